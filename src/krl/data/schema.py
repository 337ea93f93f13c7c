"""The expert dataset's schema (version :data:`SCHEMA_VERSION`): the column table and its Arrow encoding.

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
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
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


def dataset_hash(settings: Mapping[str, Any], part_hashes: Iterable[str]) -> str:
    """The dataset's content hash: sha256 over the canonical settings and the parts' content hashes in
    episode order. Creation time and krl version are not part of it."""
    digest = hashlib.sha256()
    digest.update(f"krl-expert-dataset/v{SCHEMA_VERSION}|".encode())
    digest.update(canonical_json(settings).encode())
    for value in part_hashes:
        digest.update(b"|" + value.encode())
    return digest.hexdigest()


__all__ = [
    "FIELDS",
    "FIELD_NAMES",
    "MANIFEST_NAME",
    "SCHEMA_VERSION",
    "DatasetError",
    "FieldSpec",
    "arrow_schema",
    "canonical_json",
    "columns_description",
    "columns_to_table",
    "content_hash",
    "dataset_hash",
    "field_spec",
]
