"""The expert dataset's reader: the manifest, each part file checked against it, and :class:`Dataset`.

:mod:`krl.data.storage` writes what this reads; :mod:`krl.data.schema` defines the columns both agree on.
pyarrow is imported only inside the functions that read Parquet, so importing this module stays cheap.
"""

from __future__ import annotations

import json
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from krl.data.schema import (
    FIELD_NAMES,
    FIELDS,
    FORMAT_NAME,
    MANIFEST_NAME,
    METADATA_KEY,
    SCHEMA_VERSION,
    SCHEMA_VERSION_KEY,
    DatasetError,
    FieldSpec,
    content_hash,
    dataset_hash,
    field_spec,
)
from krl.util.hashing import file_sha256


def _column_to_numpy(column, spec: FieldSpec) -> np.ndarray:
    """A Parquet column (``pyarrow.ChunkedArray``) as a numpy array of shape (N, *spec.shape)."""
    array = column.combine_chunks()
    if spec.width:
        array = array.flatten()
    values = array.to_numpy(zero_copy_only=False).astype(spec.dtype, copy=False)
    return values.reshape(-1, *spec.shape)


# --- manifest --------------------------------------------------------------------------------------


def read_manifest(directory: Path) -> dict[str, Any]:
    """Read and check a dataset's manifest (DatasetError naming the file on any problem)."""
    path = Path(directory) / MANIFEST_NAME
    if not path.is_file():
        raise DatasetError(f"{path}: manifest missing (not a krl dataset directory?)")
    try:
        manifest = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise DatasetError(f"{path}: unreadable or corrupt manifest ({error})") from None
    if not isinstance(manifest, dict) or manifest.get("format") != FORMAT_NAME:
        raise DatasetError(f"{path}: not a {FORMAT_NAME} manifest")
    version = manifest.get("schema_version")
    if version != SCHEMA_VERSION:
        raise DatasetError(
            f"{path}: schema version {version!r}, this krl reads version {SCHEMA_VERSION} only"
        )
    parts = manifest.get("parts")
    metadata = manifest.get("metadata")
    if not isinstance(parts, list) or not isinstance(metadata, dict) or "settings" not in metadata:
        raise DatasetError(f"{path}: manifest lacks 'parts' or 'metadata.settings'")
    required = ("file", "episode", "rows", "targets", "sha256", "content_hash")
    for part in parts:
        if not isinstance(part, dict) or any(key not in part for key in required):
            raise DatasetError(f"{path}: malformed part entry {part!r}")
    ordered = sorted(parts, key=lambda p: p["episode"])
    try:
        derived = dataset_hash(metadata["settings"], (str(p["content_hash"]) for p in ordered))
    except (TypeError, ValueError) as error:
        raise DatasetError(f"{path}: settings that are not plain JSON ({error})") from None
    if manifest.get("content_hash") != derived:
        raise DatasetError(
            f"{path}: content_hash {str(manifest.get('content_hash'))[:12]} is not the hash of its parts "
            f"and settings ({derived[:12]}); the manifest was edited"
        )
    return manifest


def non_finite_rows(columns: Mapping[str, np.ndarray]) -> dict[str, int]:
    """Float columns holding NaN or ±inf: ``{name: number of rows with one or more such values}``."""
    bad = {}
    for name, values in columns.items():
        if np.issubdtype(values.dtype, np.floating):
            rows = int((~np.isfinite(values)).reshape(len(values), -1).any(axis=1).sum())
            if rows:
                bad[name] = rows
    return bad


def read_part(path: Path, entry: Mapping[str, Any], columns: Sequence[str] | None = None):
    """Read one part file listed in a manifest and check it: its sha256 (the file's bytes), schema version
    and row count, that its rows hash to its ``content_hash`` (so the dataset's hash is the hash of the
    rows, not only what the manifest says), and that no float column holds NaN or ±inf.

    Every column is read, whatever ``columns`` asks for, since the content hash covers them all.
    Returns ``(columns dict, part metadata dict)``; DatasetError naming the file on any problem.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    if not path.is_file():
        raise DatasetError(f"{path}: part file missing")
    sha = file_sha256(path)
    if sha != entry["sha256"]:
        raise DatasetError(f"{path}: sha256 mismatch (file corrupt, truncated or modified)")
    names = FIELD_NAMES if columns is None else tuple(columns)
    try:
        table = pq.read_table(path)
    except (OSError, pa.ArrowException, ValueError) as error:
        message = str(error).splitlines()[0] if str(error) else type(error).__name__
        raise DatasetError(f"{path}: unreadable part file ({message})") from None
    meta = table.schema.metadata or {}
    version = meta.get(SCHEMA_VERSION_KEY, b"?").decode(errors="replace")
    if version != str(SCHEMA_VERSION):
        raise DatasetError(f"{path}: schema version {version}, this krl reads version {SCHEMA_VERSION}")
    if table.num_rows != entry["rows"]:
        raise DatasetError(f"{path}: {table.num_rows} rows, the manifest says {entry['rows']}")
    try:
        part_meta = json.loads(meta.get(METADATA_KEY, b"{}"))
    except json.JSONDecodeError:
        raise DatasetError(f"{path}: corrupt key-value metadata") from None
    try:
        every = {f.name: _column_to_numpy(table.column(f.name), f) for f in FIELDS}
    except (KeyError, pa.ArrowException, ValueError) as error:
        raise DatasetError(f"{path}: columns of another layout ({error})") from None
    bad = non_finite_rows(every)
    if bad:
        listed = ", ".join(f"column {name}: {rows} of {table.num_rows} rows" for name, rows in bad.items())
        raise DatasetError(f"{path}: NaN or infinite values ({listed})")
    if content_hash(every) != entry["content_hash"]:
        raise DatasetError(
            f"{path}: its rows do not match its content_hash in the manifest (the file was modified "
            "and its sha256 updated)"
        )
    return {name: every[name] for name in names}, part_meta


# --- the dataset -----------------------------------------------------------------------------------


class Dataset:
    """A loaded expert dataset: numpy arrays by field name plus the metadata.

    ``ds["q"]`` has shape (N, 12); scalar columns have shape (N,). Rows are in episode order, and within
    an episode in time order.
    """

    def __init__(self, path: Path, manifest: Mapping[str, Any], columns: dict[str, np.ndarray]) -> None:
        self.path = Path(path)
        """The dataset directory."""
        self.manifest: dict[str, Any] = dict(manifest)
        """The manifest as read (parts with their counts and hashes, metadata, totals)."""
        self.metadata: dict[str, Any] = dict(manifest["metadata"])
        """Dataset-level metadata: schema and krl version, creation time, ``settings`` (mode, seed,
        expert/terrain/command parameters, target distances, ...) and the column table."""
        self._columns = columns

    # mapping-like access
    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self._columns[name]
        except KeyError:
            if name in FIELD_NAMES:
                raise KeyError(f"field {name!r} was not loaded (columns=...)") from None
            raise KeyError(f"unknown dataset field {name!r}; fields: {', '.join(FIELD_NAMES)}") from None

    def __contains__(self, name: object) -> bool:
        return name in self._columns

    def __iter__(self) -> Iterator[str]:
        return iter(self._columns)

    def __len__(self) -> int:
        return self.num_rows

    def keys(self) -> list[str]:
        """Loaded field names, in file order."""
        return list(self._columns)

    @property
    def settings(self) -> dict[str, Any]:
        """The collection settings (mode, seed, expert, terrain, command, distances, ...)."""
        return dict(self.metadata["settings"])

    @property
    def parts(self) -> list[dict[str, Any]]:
        """Manifest entries of the part files, in episode order."""
        return list(self.manifest["parts"])

    @property
    def num_rows(self) -> int:
        return int(sum(p["rows"] for p in self.manifest["parts"]))

    @property
    def num_episodes(self) -> int:
        return len(self.manifest["parts"])

    @property
    def num_targets(self) -> int:
        """Targets attempted (reached, fallen on or timed out)."""
        return int(sum(p["targets"] for p in self.manifest["parts"]))

    @property
    def targets_reached(self) -> int:
        return int(sum(p.get("targets_reached", 0) for p in self.manifest["parts"]))

    @property
    def falls(self) -> int:
        return int(sum(p.get("falls", 0) for p in self.manifest["parts"]))

    @property
    def timeouts(self) -> int:
        return int(sum(p.get("timeouts", 0) for p in self.manifest["parts"]))

    @property
    def sim_seconds(self) -> float:
        """Simulated time covered by the rows [s]."""
        from krl.util.timing import CONTROL_DT

        return self.num_rows * CONTROL_DT

    @property
    def content_hash(self) -> str:
        """Stable sha256 of the settings and the row data (see :func:`dataset_hash`); equal for equal data
        however it was written (resumed or not), different for any change of a value."""
        return dataset_hash(self.metadata["settings"], (p["content_hash"] for p in self.manifest["parts"]))

    def __repr__(self) -> str:
        return (
            f"Dataset({str(self.path)!r}, rows={self.num_rows}, targets={self.num_targets}, "
            f"episodes={self.num_episodes}, mode={self.metadata['settings'].get('mode')!r})"
        )


def load_dataset(path: str | Path, columns: Sequence[str] | None = None) -> Dataset:
    """Load a dataset directory (or its ``manifest.json``) written by :mod:`krl.data.collect`.

    Every listed part's sha256, schema version, row count and content hash is checked, and every float
    column must be finite; a missing, corrupt, truncated or modified part or manifest, or a NaN or
    infinite value, raises :class:`DatasetError` naming the file (and the column). Part files not in the
    manifest (an episode interrupted between writing its part and the manifest) are ignored.

    Args:
        path: the dataset directory or its manifest file.
        columns: keep only these fields (default: all); every part is still read whole to check it.
    """
    path = Path(path)
    directory = path.parent if path.name == MANIFEST_NAME and path.is_file() else path
    if columns is not None:
        for name in columns:
            field_spec(name)
        columns = [name for name in FIELD_NAMES if name in set(columns)]
    manifest = read_manifest(directory)
    names = FIELD_NAMES if columns is None else tuple(columns)
    chunks: dict[str, list[np.ndarray]] = {name: [] for name in names}
    for entry in sorted(manifest["parts"], key=lambda p: p["episode"]):
        part_columns, _ = read_part(directory / entry["file"], entry, names)
        for name in names:
            chunks[name].append(part_columns[name])
    data = {}
    for name in names:
        spec = field_spec(name)
        data[name] = (
            np.concatenate(chunks[name]) if chunks[name] else np.zeros((0, *spec.shape), dtype=spec.dtype)
        )
    manifest["parts"] = sorted(manifest["parts"], key=lambda p: p["episode"])
    return Dataset(directory, manifest, data)


__all__ = ["Dataset", "load_dataset", "non_finite_rows", "read_manifest", "read_part"]
