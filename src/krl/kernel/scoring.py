"""Scoring a kernel on expert data: its mean absolute error [m] overall, per axis and where it is
(``krl kernel eval``), on a dataset or on fresh expert data collected with the kernel's training settings.
"""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import Any

import numpy as np

from krl.data.collect import CollectConfig, collect_dataset
from krl.data.reader import load_dataset
from krl.kernel.features import features_from_columns, labels_from_columns, split_by_target
from krl.kernel.model import Kernel
from krl.kernel.settings import training_settings

TIME_BINS: tuple[float, ...] = (0.0, 0.5, 1.0, 2.0, np.inf)
"""Edges [s] of the breakdown's bins of time since the walk to the current target started."""
CLEARANCE_BINS: tuple[float, ...] = (-np.inf, 0.04, 0.06, 0.08, 0.10, np.inf)
"""Edges [m] of the breakdown's bins of ride height minus step height (how far below the hips the
swing apex stays)."""


def score(kernel: Kernel, dataset, validation_only: bool = False, breakdown: bool = False) -> dict[str, Any]:
    """Mean absolute error [m] of ``kernel`` on the rows of ``dataset``, overall and per axis.

    ``validation_only``: only the targets that the kernel's training run held out (the dataset must be
    the one it was trained on). ``breakdown``: also the error by leg phase, by time since the target
    started and by swing clearance; each bin reports its share of rows and its mean error.
    """
    columns = {name: np.asarray(dataset[name]) for name in dataset.keys()}
    if validation_only:
        settings = training_settings(kernel)
        if settings.dataset_hash != dataset.content_hash:
            raise ValueError(
                f"--validation: the kernel was trained on dataset {str(settings.dataset_hash)[:12]}, "
                f"not on this one ({dataset.content_hash[:12]})"
            )
        fraction, split_seed = settings.validation_split
        rows = split_by_target(columns["target_index"], fraction, split_seed)
        columns = {name: column[rows] for name, column in columns.items()}
    features = features_from_columns(kernel.variant, columns)
    labels = labels_from_columns(kernel.variant, columns)
    n = len(columns["target_index"])
    error = np.abs(kernel.predict(features) - labels).reshape(n, -1, 3)
    result: dict[str, Any] = {
        "val_l1": float(error.mean()),
        "val_l1_xyz": [float(e) for e in error.mean(axis=(0, 1))],
        "rows": n,
        "targets": len(np.unique(columns["target_index"])),
    }
    if breakdown:
        result["breakdown"] = error_breakdown(error, columns)
    return result


def error_breakdown(error: np.ndarray, columns: dict[str, np.ndarray]) -> dict[str, Any]:
    """Where the error is. ``error``: |prediction − label| [m], shape (N, 4, 3), rows in dataset order."""
    stance = np.asarray(columns["stance"], dtype=bool)
    target = columns["target_index"]
    first = np.r_[True, target[1:] != target[:-1]]
    started = np.maximum.accumulate(np.where(first, np.arange(len(target)), 0))
    since_target = columns["time"] - columns["time"][started]
    clearance = columns["ride_height"] - columns["step_height"]

    def bins(values: np.ndarray, edges: tuple[float, ...], unit: str) -> list[dict[str, Any]]:
        out = []
        for low, high in itertools.pairwise(edges):
            rows = (values >= low) & (values < high)
            if rows.any():
                label = f"[{low:g}, {high:g}) {unit}"
                out.append({"bin": label, "rows": float(rows.mean()), "l1": float(error[rows].mean())})
        return out

    return {
        "stance_l1": float(error[stance].mean()) if stance.any() else None,
        "swing_l1": float(error[~stance].mean()) if (~stance).any() else None,
        "by_time_since_target": bins(since_target, TIME_BINS, "s"),
        "by_swing_clearance": bins(clearance, CLEARANCE_BINS, "m"),
    }


def fresh_validation_data(kernel: Kernel, targets: int, seed: int, directory: Path):
    """Collect ``targets`` targets of expert data into ``directory`` (one episode, seeded by ``seed``) with
    the kernel's training settings (expert, collection mode, ext heights); returns the loaded dataset."""
    settings = training_settings(kernel)
    config = CollectConfig(
        targets=targets,
        mode=settings.mode,
        seed=seed,
        expert=settings.expert,
        targets_per_episode=targets,
        ext_heights=settings.ext_heights,
    )
    collect_dataset(directory, config)
    return load_dataset(directory)


__all__ = ["CLEARANCE_BINS", "TIME_BINS", "error_breakdown", "fresh_validation_data", "score"]
