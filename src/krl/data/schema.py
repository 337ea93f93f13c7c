"""The expert dataset's schema (version :data:`SCHEMA_VERSION`) and its reader.

A dataset is a directory holding ``manifest.json`` and one Parquet part file per finished episode
(``part-00000.parquet``, ...). Every row is one 200 Hz control step of the expert: the Table A.1
variables *before* the action, the labels *after* it, and bookkeeping columns. :data:`FIELDS` lists every
column with its shape, dtype, unit and frame; ``docs/data.md`` explains them and the choices behind them.

Vectors are stored as Arrow ``fixed_size_list`` columns; per-foot vectors of shape (4, 3) are flattened
leg-major (FR x, y, z, FL x, y, z, RR ..., RL ...) to 12 numbers, so ``ds["foot_pos"]`` has shape (N, 12)
and ``ds["foot_pos"].reshape(-1, 4, 3)`` gives (N, leg, xyz).

pyarrow is imported only inside the functions that read or write Parquet, so importing this module (and the
``krl`` command) stays cheap.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

SCHEMA_VERSION: int = 1
"""Version of the row layout and of the manifest; bumped on any incompatible change."""

FORMAT_NAME: str = "krl-expert-dataset"
"""The manifest's ``format`` value."""

MANIFEST_NAME: str = "manifest.json"
"""File name of the manifest inside a dataset directory."""

PART_PATTERN: str = "part-{episode:05d}.parquet"
"""File name of one episode's part file."""

METADATA_KEY: bytes = b"krl.dataset"
"""Parquet key-value metadata key holding the dataset- and part-level metadata as JSON."""

SCHEMA_VERSION_KEY: bytes = b"krl.schema_version"
"""Parquet key-value metadata key holding :data:`SCHEMA_VERSION` as text."""


class DatasetError(ValueError):
    """A dataset (manifest or part file) is missing, corrupt, truncated or of another schema version.

    The message is one line naming the offending file.
    """


@dataclass(frozen=True)
class FieldSpec:
    """One column of the dataset."""

    name: str
    """Column name (the key of :class:`Dataset`)."""
    width: int
    """Numbers per row: 0 for a scalar column, n for a fixed-size list of n."""
    dtype: str
    """numpy dtype name of the values: ``float32``, ``float64``, ``int32`` or ``bool``."""
    unit: str
    """Unit of the values ("-" for dimensionless, "" for flags and indices)."""
    frame: str
    """Frame of vector values: ``base``, ``heading``, ``world`` or "" (not a spatial vector)."""
    group: str
    """``feature`` (before the action), ``label`` (after it), ``setting`` or ``bookkeeping``."""
    symbol: str
    """Thesis symbol (Table A.1 / Eq. 4.6) or "" when the thesis has none."""
    description: str
    """What the column holds."""

    @property
    def shape(self) -> tuple[int, ...]:
        """Shape of one row's value: () or (width,)."""
        return () if self.width == 0 else (self.width,)


_F32, _F64, _I32, _BOOL = "float32", "float64", "int32", "bool"

# fmt: off
FIELDS: tuple[FieldSpec, ...] = (
    # --- Table A.1, before the action --------------------------------------------------------------
    FieldSpec("base_lin_vel", 3, _F32, "m/s", "base", "feature", "v_base",
              "trunk-origin linear velocity"),
    FieldSpec("base_ang_vel", 3, _F32, "rad/s", "base", "feature", "a_base",
              "trunk angular velocity (roll, pitch, yaw rates about the base axes)"),
    FieldSpec("v_cmd", 2, _F32, "m/s", "heading", "feature", "v_cmd",
              "velocity command (vx forward, vy left) of the command generator"),
    FieldSpec("yaw_cmd", 0, _F32, "rad/s", "", "feature", "a_cmd",
              "yaw-rate command of the command generator"),
    FieldSpec("q", 12, _F32, "rad", "", "feature", "q", "joint angles, FR FL RR RL x (abd, hip, knee)"),
    FieldSpec("dq", 12, _F32, "rad/s", "", "feature", "q̇", "joint velocities"),
    FieldSpec("ddq", 12, _F32, "rad/s²", "", "feature", "q̈",
              "joint accelerations: (q̇ after - q̇ before) / CONTROL_DT over this control step"),
    FieldSpec("phase", 4, _F32, "cycles", "", "feature", "φ",
              "leg phases in (0, 1] that the expert's action used (Eq. 4.3)"),
    FieldSpec("normalised_phase", 4, _F32, "-", "", "feature", "|φ|",
              "normalised phases (Eq. 4.6): (1, 2] in swing, (0, 1] in stance"),
    FieldSpec("sine_phase", 4, _F32, "-", "", "feature", "sin(|φ|π)", "sine phase representation"),
    FieldSpec("stance", 4, _BOOL, "", "", "feature", "", "legs in stance by the gait schedule"),
    FieldSpec("foot_pos", 12, _F32, "m", "base", "feature", "p",
              "foot-sphere centres, (4, 3) flattened leg-major"),
    FieldSpec("com", 3, _F32, "m", "base", "feature", "CoM",
              "whole-robot centre of mass relative to the trunk origin"),
    FieldSpec("projected_gravity", 3, _F32, "-", "base", "feature", "",
              "unit gravity direction, (0, 0, -1) when level (the reward's 'CoM' term)"),
    # --- labels, after the action ------------------------------------------------------------------
    FieldSpec("foot_ref", 12, _F32, "m", "base", "label", "p_ref",
              "expert foot targets: swing targets (swing legs), current before-positions (stance legs)"),
    FieldSpec("foot_pos_next", 12, _F32, "m", "base", "label", "p'",
              "foot-sphere centres after the control step, in the base frame after the step"),
    # --- expert settings ---------------------------------------------------------------------------
    FieldSpec("step_height", 0, _F32, "m", "", "setting", "p_air",
              "swing apex above the default foot height"),
    FieldSpec("ride_height", 0, _F32, "m", "", "setting", "", "desired trunk-origin height"),
    FieldSpec("stance_duration", 0, _F32, "s", "", "setting", "τ_stance", "stance duration of the gait"),
    # --- bookkeeping -------------------------------------------------------------------------------
    FieldSpec("episode", 0, _I32, "", "", "bookkeeping", "", "episode index (one part file each)"),
    FieldSpec("target_index", 0, _I32, "", "", "bookkeeping", "",
              "global target index: episode * targets_per_episode + index within the episode"),
    FieldSpec("time", 0, _F64, "s", "", "bookkeeping", "",
              "time of the before-state since the episode started (runs on through resets)"),
    FieldSpec("time_since_reset", 0, _F64, "s", "", "bookkeeping", "",
              "time of the before-state since the last standing reset (the gait clock's start)"),
    FieldSpec("new_segment", 0, _BOOL, "", "", "bookkeeping", "",
              "first row after a standing reset: the previous row is not this row's past"),
    FieldSpec("base_pos", 3, _F64, "m", "world", "bookkeeping", "", "trunk origin"),
    FieldSpec("rpy", 3, _F32, "rad", "world", "bookkeeping", "", "trunk roll, pitch, yaw (Z-Y-X)"),
    FieldSpec("target_xy", 2, _F64, "m", "world", "bookkeeping", "", "the waypoint being walked to"),
    FieldSpec("fell", 0, _BOOL, "", "", "bookkeeping", "",
              "the robot fell in this control step (its after-state is fallen); a reset follows"),
)
# fmt: on
"""Every column, in file order."""

FIELD_NAMES: tuple[str, ...] = tuple(f.name for f in FIELDS)
"""Column names in file order."""

_BY_NAME: dict[str, FieldSpec] = {f.name: f for f in FIELDS}


def field_spec(name: str) -> FieldSpec:
    """The :class:`FieldSpec` of column ``name`` (KeyError naming the valid names otherwise)."""
    try:
        return _BY_NAME[name]
    except KeyError:
        raise KeyError(f"unknown dataset field {name!r}; fields: {', '.join(FIELD_NAMES)}") from None


def columns_description() -> list[dict[str, Any]]:
    """The column table as JSON-ready dicts (stored in the manifest so a dataset describes itself)."""
    return [
        {
            "name": f.name,
            "shape": list(f.shape),
            "dtype": f.dtype,
            "unit": f.unit,
            "frame": f.frame,
            "group": f.group,
            "symbol": f.symbol,
            "description": f.description,
        }
        for f in FIELDS
    ]


def arrow_schema(metadata: Mapping[str, Any] | None = None):
    """The Arrow schema of a part file (``pyarrow.Schema``), with per-field unit/frame/description metadata
    and, if given, ``metadata`` as JSON under :data:`METADATA_KEY`."""
    import pyarrow as pa

    fields = []
    for f in FIELDS:
        value_type = pa.from_numpy_dtype(np.dtype(f.dtype))
        arrow_type = value_type if f.width == 0 else pa.list_(value_type, f.width)
        field_meta = {"unit": f.unit, "frame": f.frame, "group": f.group, "symbol": f.symbol}
        field_meta["description"] = f.description
        fields.append(pa.field(f.name, arrow_type, nullable=False, metadata=field_meta))
    schema_meta = {SCHEMA_VERSION_KEY: str(SCHEMA_VERSION).encode()}
    if metadata is not None:
        schema_meta[METADATA_KEY] = canonical_json(metadata).encode()
    return pa.schema(fields, metadata=schema_meta)


def canonical_json(value: Any) -> str:
    """JSON with sorted keys and no whitespace: the form hashed and compared."""
    return json.dumps(value, sort_keys=True, separators=(",", ":"), allow_nan=False)


def columns_to_table(columns: Mapping[str, np.ndarray], metadata: Mapping[str, Any] | None = None):
    """A ``pyarrow.Table`` from numpy arrays by field name (each cast to its field's dtype)."""
    import pyarrow as pa

    schema = arrow_schema(metadata)
    arrays = []
    rows = None
    for f in FIELDS:
        values = np.ascontiguousarray(columns[f.name], dtype=f.dtype)
        if rows is None:
            rows = len(values)
        if values.shape != (rows, *f.shape):
            raise ValueError(f"column {f.name!r}: shape {values.shape}, expected {(rows, *f.shape)}")
        flat = pa.array(values.reshape(-1), type=pa.from_numpy_dtype(values.dtype))
        arrays.append(flat if f.width == 0 else pa.FixedSizeListArray.from_arrays(flat, f.width))
    return pa.Table.from_arrays(arrays, schema=schema)


def _column_to_numpy(column, spec: FieldSpec) -> np.ndarray:
    """A Parquet column (``pyarrow.ChunkedArray``) as a numpy array of shape (N, *spec.shape)."""
    array = column.combine_chunks()
    if spec.width:
        array = array.flatten()
    values = array.to_numpy(zero_copy_only=False).astype(spec.dtype, copy=False)
    return values.reshape(-1, *spec.shape)


def content_hash(columns: Mapping[str, np.ndarray]) -> str:
    """sha256 of the row data: every field's name, dtype, shape and bytes, in file order.

    Independent of the Parquet encoding (compression, pyarrow version), so the same rows always give the
    same hash.
    """
    digest = hashlib.sha256()
    for f in FIELDS:
        values = np.ascontiguousarray(columns[f.name], dtype=f.dtype)
        digest.update(f"{f.name}|{f.dtype}|{values.shape}|".encode())
        digest.update(values.tobytes())
    return digest.hexdigest()


def file_sha256(path: Path) -> str:
    """sha256 of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def dataset_hash(settings: Mapping[str, Any], part_hashes: Iterable[str]) -> str:
    """The dataset's content hash: sha256 over the canonical settings and the parts' content hashes in
    episode order. Creation time and krl version are not part of it."""
    digest = hashlib.sha256()
    digest.update(f"krl-expert-dataset/v{SCHEMA_VERSION}|".encode())
    digest.update(canonical_json(settings).encode())
    for value in part_hashes:
        digest.update(b"|" + value.encode())
    return digest.hexdigest()


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
            if name in _BY_NAME:
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
        from krl.timing import CONTROL_DT

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


__all__ = [
    "FIELDS",
    "FIELD_NAMES",
    "MANIFEST_NAME",
    "SCHEMA_VERSION",
    "Dataset",
    "DatasetError",
    "FieldSpec",
    "arrow_schema",
    "columns_description",
    "content_hash",
    "dataset_hash",
    "field_spec",
    "load_dataset",
    "non_finite_rows",
    "read_manifest",
]
