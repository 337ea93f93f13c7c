"""What the expert's and the kernel's figures share: the velocity sweep (thesis Fig. 4.15, both halves),
the straight-line fit, and writing a figure's three files.

Drawing helpers shared by both live in :mod:`krl.analysis.panels`.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from krl.task.runner import HOLD_RAMP
from krl.util.output import csv_bytes, figure_bytes, json_value, write_atomic

FIG_SIZE: tuple[float, float] = (9.0, 6.0)
"""Size of a full-width figure [inches] (900 px wide at :data:`krl.util.output.FIG_DPI`)."""

DEFAULT_DURATION: float = 8.0
"""Length of each fixed-command run of the velocity sweep [s] (1 s ramp + 1 s settling + 6 s measured)."""
QUICK_DURATION: float = 3.0
"""The same with ``quick`` (tests) [s]."""

VELOCITY_STEP: float = 0.1
"""Spacing of the velocity sweep's commands [m/s or rad/s]."""
VELOCITY_AXES: tuple[str, ...] = ("vx", "vy", "wz")
"""The command components, in command order (forward, lateral velocity [m/s]; yaw rate [rad/s])."""


def fit_line(x: Sequence[float], y: Sequence[float]) -> dict[str, float]:
    """Least-squares line ``y ≈ slope x + offset`` over the finite pairs, with its RMS and largest residual.

    NaNs throughout when fewer than two distinct finite x values remain.
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    keep = np.isfinite(x) & np.isfinite(y)
    x, y = x[keep], y[keep]
    if len(np.unique(x)) < 2:
        nan = float("nan")
        return {"slope": nan, "offset": nan, "rmse": nan, "max_abs_residual": nan, "points": len(x)}
    slope, offset = np.polyfit(x, y, 1)
    residual = y - (slope * x + offset)
    return {
        "slope": float(slope),
        "offset": float(offset),
        "rmse": float(np.sqrt(np.mean(residual**2))),
        "max_abs_residual": float(np.abs(residual).max()),
        "points": len(x),
    }


def fit_rows(rows: Sequence[dict[str, Any]], x: str, y: str) -> dict[str, float]:
    """:func:`fit_line` of the ``y`` values of ``rows`` against their ``x`` values (two keys of each row)."""
    return fit_line([r[x] for r in rows], [r[y] for r in rows])


def velocity_sweep(quick: bool = False) -> list[tuple[str, float, tuple[float, float, float]]]:
    """(axis, commanded value, command) per point of the velocity figures' sweep.

    Each of vx, vy, wz over the command generator's limits (``CommandParams``) in steps of
    :data:`VELOCITY_STEP` (vx, wz: -0.5..0.5, 11 points; vy: -0.3..0.3, 7 points), the other two zero;
    ``quick``: low, 0, high.
    """
    from krl.control.commands import CommandParams

    params = CommandParams()
    out = []
    for index, (axis, (low, high)) in enumerate(
        zip(VELOCITY_AXES, (params.vx_range, params.vy_range, params.yaw_rate_range), strict=True)
    ):
        count = 3 if quick else 1 + round((high - low) / VELOCITY_STEP)
        for value in np.linspace(low, high, count):
            value = round(float(value), 6) + 0.0  # no -0.0
            command = [0.0, 0.0, 0.0]
            command[index] = value
            out.append((axis, value, (command[0], command[1], command[2])))
    return out


def hold_velocity(sim, controller, command: Sequence[float], duration: float) -> dict[str, Any]:
    """Hold ``command`` from a standing start (rising over ``HOLD_RAMP``) and measure the realised velocity.

    Args:
        sim: a fresh :class:`krl.sim.robot.A1Sim`.
        controller: what walks it (the expert or the kernel controller).
        command: (vx [m/s], vy [m/s], wz [rad/s]).
        duration: length of the run [s].

    Returns:
        ``fell``, ``error`` (an ``MPCError``/``SimulationUnstableError`` as text, or None), ``samples``
        (control steps measured), ``mean`` and ``std``: the realised (vx, vy, wz) over those steps
        (:meth:`krl.task.runner.Runner.hold_command`), NaN without samples.
    """
    from krl.task.runner import Runner

    runner = Runner(sim, controller)
    error = None
    try:
        result = runner.hold_command(np.array(command), duration, ramp=HOLD_RAMP)
        realised, fell = np.array(result.realised).reshape(-1, 3), result.fell
    except RuntimeError as exc:  # MPCError, SimulationUnstableError
        error, realised, fell = f"{type(exc).__name__}: {exc}", np.zeros((0, 3)), True
    mean = realised.mean(axis=0) if len(realised) else np.full(3, np.nan)
    std = realised.std(axis=0) if len(realised) else np.full(3, np.nan)
    return {
        "fell": bool(fell),
        "error": error,
        "samples": len(realised),
        "mean": mean.tolist(),
        "std": std.tolist(),
    }


VELOCITY_COLUMNS: tuple[str, ...] = (
    "axis",
    "commanded",
    "vx_mean",
    "vx_std",
    "vy_mean",
    "vy_std",
    "wz_mean",
    "wz_std",
    "fell",
    "samples",
)
"""The CSV columns of a velocity table (:func:`velocity_row`'s keys but ``error``)."""


def velocity_row(axis: str, value: float, outcome: dict[str, Any]) -> dict[str, Any]:
    """One velocity-table row from a :func:`hold_velocity` outcome: ``axis``, ``commanded``,
    ``{vx,vy,wz}_{mean,std}``, ``fell``, ``samples``, ``error``."""
    row: dict[str, Any] = {"axis": axis, "commanded": value}
    for i, name in enumerate(VELOCITY_AXES):
        row[f"{name}_mean"], row[f"{name}_std"] = outcome["mean"][i], outcome["std"][i]
    row.update(fell=outcome["fell"], samples=outcome["samples"], error=outcome["error"])
    return row


def max_cross(rows: Sequence[dict[str, Any]], axis: str) -> float:
    """Largest |mean| of the two components not commanded on ``axis``'s rows (NaN without finite ones)."""
    others = [o for o in VELOCITY_AXES if o != axis]
    return max(
        (abs(r[f"{o}_mean"]) for r in rows for o in others if math.isfinite(r[f"{o}_mean"])),
        default=float("nan"),
    )


def write_figure(
    out_dir: Path, name: str, fig, table: dict[str, Any], columns: Sequence[str], rows: Sequence[dict]
) -> dict[str, Any]:
    """Write ``NAME.png``, ``NAME.json`` (the table, floats rounded by :func:`krl.util.output.json_value`) and
    ``NAME.csv`` (``columns`` of ``rows``; a missing key is an empty cell), each atomically.

    Returns ``{"png", "json", "csv"}`` (the paths as text) and ``"table"`` (the rounded table).
    """
    table = json_value(table)
    paths = {kind: Path(out_dir) / f"{name}.{kind}" for kind in ("png", "json", "csv")}
    write_atomic(paths["png"], figure_bytes(fig))
    write_atomic(paths["json"], (json.dumps(table, indent=2, ensure_ascii=False) + "\n").encode())
    write_atomic(paths["csv"], csv_bytes(columns, [{c: row.get(c) for c in columns} for row in rows]))
    return {**{kind: str(path) for kind, path in paths.items()}, "table": table}


def check_run_options(workers: int | None, seed: int, out: Path, error: type[ValueError]) -> int:
    """Check the options every figure command has; raise ``error`` (one line) on a bad one.

    Returns the worker count: ``workers``, or the number of CPUs when None.
    """
    if workers is None:
        workers = os.cpu_count() or 1
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise error(f"--workers must be a whole number >= 1, got {workers!r}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise error(f"--seed must be a whole number >= 0, got {seed!r}")
    if out.exists() and not out.is_dir():
        raise error(f"--out {str(out)!r} exists and is not a folder")
    return workers
