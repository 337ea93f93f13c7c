"""Writing result files: atomically (temporary file in the same folder, then ``os.replace``), tables as
CSV, figures as palette PNGs. Shared by every command that writes figures, tables or per-run results, so
an interrupted command never leaves a truncated file under a final name.
"""

from __future__ import annotations

import contextlib
import csv
import io
import math
import os
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

FIG_DPI: int = 100
"""Resolution of the PNG figures [dots per inch]."""


def write_atomic(path: Path, data: bytes | str, durable: bool = False) -> None:
    """Write ``data`` (text as UTF-8) to ``path`` through a temporary file in the same folder
    (``.NAME.XXXXXXXX.tmp``) and ``os.replace``; the folder is created if missing.

    With ``durable`` the file is fsynced before the rename and the folder after it, so the new file
    also survives a crash of the machine, not only of the process (the datasets' parts and manifests).

    Raises:
        OSError: the file cannot be written (a full disk, a read-only folder), of the same kind, its
            message naming ``path`` (:func:`cannot_write`), not the temporary file.
    """
    path = Path(path)
    try:
        _replace_through_temporary(path, data, durable)
    except OSError as error:
        raise cannot_write(path, error) from None


def cannot_write(path: Path, error: OSError) -> OSError:
    """``error`` of writing ``path`` as an error of the same kind and number whose one-line message names
    ``path`` (``cannot write runs/eval/expert/commands.txt: No space left on device``) and the folder that
    could not be made, if that failed (not the temporary file, a name the user never gave)."""
    reason = error.strerror or str(error)
    if error.filename is not None and Path(error.filename).parent != path.parent:
        reason = f"{error.filename}: {reason}"
    failure = type(error)(f"cannot write {path}: {reason}")
    failure.errno = error.errno
    return failure


def _replace_through_temporary(path: Path, data: bytes | str, durable: bool) -> None:
    """:func:`write_atomic`'s work: the folder made, a temporary file written, then renamed to ``path``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(data, str):
        data = data.encode()
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
            if durable:
                handle.flush()
                os.fsync(handle.fileno())
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    if durable:
        with contextlib.suppress(OSError):  # not every filesystem can fsync a folder
            folder = os.open(path.parent, os.O_RDONLY)
            try:
                os.fsync(folder)
            finally:
                os.close(folder)


def json_value(value: Any) -> Any:
    """Floats rounded for the tables; NaN becomes null."""
    if isinstance(value, float):
        return None if not math.isfinite(value) else round(value, 6)
    if isinstance(value, dict):
        return {key: json_value(v) for key, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_value(v) for v in value]
    return value


def csv_bytes(columns: Sequence[str], rows: Sequence[dict[str, Any]]) -> bytes:
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=list(columns), lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow(
            {key: ("" if json_value(row[key]) is None else json_value(row[key])) for key in columns}
        )
    return buffer.getvalue().encode()


def npz_bytes(arrays: dict[str, Any]) -> bytes:
    """Arrays as the bytes of an uncompressed ``.npz`` archive (``numpy.savez``), for :func:`write_atomic`."""
    import numpy as np

    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    return buffer.getvalue()


def figure_bytes(fig) -> bytes:
    """The figure as a PNG with a 256-colour palette (a third of the size of full colour, same look)."""
    from PIL import Image

    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=FIG_DPI)
    buffer.seek(0)
    with Image.open(buffer) as image:
        palette = image.convert("RGB").quantize(
            colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE
        )
    out = io.BytesIO()
    palette.save(out, format="PNG", optimize=True)
    return out.getvalue()


def distinct_colours(count: int) -> list[tuple[float, float, float]]:
    """``count`` RGB colours, one per line or bar group of a figure, that do not repeat up to 20:
    Matplotlib's ``tab10`` up to 10 (its default cycle, which starts over after 10), ``tab20`` up to 20,
    cycled beyond."""
    import matplotlib

    palette = matplotlib.colormaps["tab10" if count <= 10 else "tab20"].colors
    return [palette[index % len(palette)] for index in range(count)]
