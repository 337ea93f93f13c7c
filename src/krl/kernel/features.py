"""Kernel inputs and labels from expert datasets (thesis Section 4.2.6.3, Tables 4.4 and A.1).

Every variant maps one control step's inputs to the four feet's positions in the base frame:

* ``base``: velocity command (vx, vy), yaw-rate command and the normalised phases |φ| (Eq. 4.6): 7.
* ``ind``: one leg at a time: the commands, that leg's |φ| and a one-hot leg code (4): 8 -> 3 outputs;
  each dataset row gives four samples.
* ``ext``: ``base`` plus the step and ride heights: 9.
* ``dyn1``: ``base`` plus base linear and angular velocity (3 + 3), joint angles and velocities
  (12 + 12), centre of mass relative to the base (3) and projected gravity (3): 43.
* ``dyn2``: ``dyn1`` with the sine phase form sin(|φ|π) instead of |φ|, stacked over the last 5
  control steps (oldest first; the first rows after a reset repeat the earliest available step): 215.
  The thesis trains it on data collected with a reset after each target (``krl collect --mode dyn2``).

Labels (4.2.6.3, "Training Labels"): the expert's swing targets ``foot_ref`` for legs in swing and the
realised positions after the step ``foot_pos_next`` for legs in stance. Shapes: (N, 12) leg-major.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from krl.robots.a1.constants import NUM_LEGS

VARIANTS: tuple[str, ...] = ("base", "ind", "ext", "dyn1", "dyn2")
"""Kernel variants (thesis Table 4.4)."""

HISTORY: int = 5
"""Stacked control steps of kernel-dyn2."""

_DYNAMIC_FIELDS: tuple[tuple[str, int], ...] = (
    ("base_lin_vel", 3),
    ("base_ang_vel", 3),
    ("q", 12),
    ("dq", 12),
    ("com", 3),
    ("projected_gravity", 3),
)


def check_variant(variant: str) -> str:
    """Return ``variant`` or raise ValueError listing the known ones."""
    if variant not in VARIANTS:
        raise ValueError(f"unknown kernel variant {variant!r}; known: {', '.join(VARIANTS)}")
    return variant


def input_names(variant: str) -> list[str]:
    """Names of the input features of ``variant``, in order (one per column)."""
    check_variant(variant)
    commands = ["vx_cmd", "vy_cmd", "yaw_cmd"]
    if variant == "ind":
        return [*commands, "phase", "leg_FR", "leg_FL", "leg_RR", "leg_RL"]
    phase_kind = "sine_phase" if variant == "dyn2" else "phase"
    names = [*commands, *(f"{phase_kind}_{leg}" for leg in range(NUM_LEGS))]
    if variant == "ext":
        names += ["step_height", "ride_height"]
    if variant in ("dyn1", "dyn2"):
        names += [f"{field}_{i}" for field, width in _DYNAMIC_FIELDS for i in range(width)]
    if variant == "dyn2":
        names = [f"{name}@t-{lag}" for lag in range(HISTORY - 1, -1, -1) for name in names]
    return names


def output_size(variant: str) -> int:
    """Number of outputs: 3 for ``ind`` (one foot), 12 otherwise."""
    return 3 if check_variant(variant) == "ind" else 3 * NUM_LEGS


def features_from_columns(variant: str, columns: Mapping[str, np.ndarray]) -> np.ndarray:
    """Inputs of ``variant`` from dataset columns (see :mod:`krl.data.schema`). Shape: (N, n_in) or
    (4 N, 8) for ``ind`` (rows leg-major within each step: step 0 FR, FL, RR, RL, step 1 ...)."""
    check_variant(variant)
    commands = np.column_stack((columns["v_cmd"], columns["yaw_cmd"]))
    n = len(commands)
    if variant == "ind":
        phases = np.asarray(columns["normalised_phase"]).reshape(n * NUM_LEGS, 1)
        one_hot = np.tile(np.eye(NUM_LEGS), (n, 1))
        return np.hstack((np.repeat(commands, NUM_LEGS, axis=0), phases, one_hot)).astype(np.float32)
    phases = columns["sine_phase"] if variant == "dyn2" else columns["normalised_phase"]
    parts = [commands, phases]
    if variant == "ext":
        parts += [np.asarray(columns["step_height"])[:, None], np.asarray(columns["ride_height"])[:, None]]
    if variant in ("dyn1", "dyn2"):
        parts += [np.asarray(columns[field]).reshape(n, width) for field, width in _DYNAMIC_FIELDS]
    features = np.hstack(parts).astype(np.float32)
    if variant == "dyn2":
        boundaries = np.asarray(columns["new_segment"], dtype=bool).copy()
        if "episode" in columns:
            episode = np.asarray(columns["episode"])
            boundaries[1:] |= episode[1:] != episode[:-1]
        features = stack_history(features, boundaries)
    return features


def stack_history(features: np.ndarray, new_segment: np.ndarray, history: int = HISTORY) -> np.ndarray:
    """Concatenate each row with its ``history - 1`` predecessors (oldest first) within a segment.

    A segment starts at a row with ``new_segment`` True (and at row 0); before a segment's first row
    the first row is repeated. Shapes: (N, d), (N,) -> (N, history * d).
    """
    n = len(features)
    start = np.maximum.accumulate(np.where(new_segment | (np.arange(n) == 0), np.arange(n), 0))
    lags = [np.maximum(np.arange(n) - lag, start) for lag in range(history - 1, -1, -1)]
    return np.hstack([features[index] for index in lags])


def labels_from_columns(variant: str, columns: Mapping[str, np.ndarray]) -> np.ndarray:
    """Labels: swing targets for swing legs, realised positions for stance legs [m], base frame.

    Shape: (N, 12), or (4 N, 3) for ``ind``.
    """
    check_variant(variant)
    stance = np.repeat(np.asarray(columns["stance"], dtype=bool), 3, axis=1)
    labels = np.where(stance, columns["foot_pos_next"], columns["foot_ref"]).astype(np.float32)
    if variant == "ind":
        return labels.reshape(-1, 3)
    return labels


def split_by_target(target_index: np.ndarray, validation_fraction: float, seed: int) -> np.ndarray:
    """Boolean mask of validation rows: whole targets (walks to one waypoint) drawn at random.

    Rows of one target stay together so that validation measures generalisation to new walks, not
    interpolation between neighbouring control steps. Shape: (N,) -> (N,), bool.
    """
    if not 0 < validation_fraction < 1:
        raise ValueError(f"validation fraction must be in (0, 1), got {validation_fraction}")
    targets = np.unique(target_index)
    if len(targets) < 2:
        raise ValueError(f"need at least 2 targets to split, the data has {len(targets)}")
    rng = np.random.default_rng(seed)
    count = max(1, round(validation_fraction * len(targets)))
    chosen = rng.choice(targets, size=count, replace=False)
    return np.isin(target_index, chosen)
