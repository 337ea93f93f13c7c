"""``velocity`` (thesis Fig. 4.15, kernel half): realised against commanded velocity with the kernel as the
controller, beside the expert's numbers read from ``docs/figures/expert/velocity.json``.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from krl.analysis.common import (
    DEFAULT_DURATION,
    FIG_SIZE,
    QUICK_DURATION,
    VELOCITY_AXES,
    VELOCITY_COLUMNS,
    fit_rows,
    hold_velocity,
    max_cross,
    velocity_row,
    velocity_sweep,
)
from krl.analysis.kernel.context import THESIS_FIGURE, FigureError, FigureRun
from krl.analysis.panels import VELOCITY_NAMES, draw_fit_and_axes, style
from krl.task.runner import HOLD_RAMP, HOLD_SETTLE
from krl.util.output import FIG_DPI
from krl.util.parallel import run_jobs


def _kernel_hold(job: tuple[str, tuple[float, float, float], float, int]) -> dict[str, Any]:
    """One velocity-sweep point with the kernel as the controller (runs in a worker process): ``job`` is
    (kernel file, command, duration [s], seed); the :func:`~krl.analysis.common.hold_velocity` outcome
    with ``wall_seconds`` [s]."""
    from krl.kernel.controller import KernelController
    from krl.kernel.model import load_kernel
    from krl.sim.model import build_model
    from krl.sim.robot import A1Sim

    path, command, duration, seed = job
    start = time.perf_counter()
    controller = KernelController(load_kernel(path))
    outcome = hold_velocity(A1Sim(build_model("flat", None, seed)), controller, command, duration)
    return {**outcome, "wall_seconds": time.perf_counter() - start}


def expert_velocity_table(path: str | os.PathLike | None) -> tuple[dict | None, str | None]:
    """The expert's velocity table and where it was read: ``path``, or by default
    ``docs/figures/expert/velocity.json`` under the working directory, then under the repository;
    ``(None, None)`` when the default is in neither.

    Raises:
        FigureError: an explicit ``path`` that is missing, or a table that cannot be read.
    """
    if path is not None:
        path = Path(path)
        if not path.is_file():
            raise FigureError(f"expert velocity table not found: {path}")
        candidates = [path]
    else:
        relative = Path("docs/figures/expert/velocity.json")
        candidates = [relative, Path(__file__).resolve().parents[4] / relative]
    for candidate in candidates:
        if candidate.is_file():
            try:
                return json.loads(candidate.read_text()), str(candidate)
            except (OSError, json.JSONDecodeError) as error:
                raise FigureError(f"expert velocity table {candidate} is unreadable: {error}") from None
    return None, None


def velocity_figure(kernel_path: Path, expert_json: tuple[dict | None, str | None], run: FigureRun):
    """Fig. 4.15's kernel half: the kernel in ``kernel_path`` holds each command of the sweep (in
    ``run.workers`` processes), drawn beside ``expert_json`` (:func:`expert_velocity_table`).

    Returns ``(table, csv columns, csv rows, matplotlib figure)``.
    """
    duration = QUICK_DURATION if run.quick else DEFAULT_DURATION
    points = velocity_sweep(run.quick)
    by_command = _hold_all(kernel_path, points, duration, run)
    expert, expert_source = expert_json
    rows = _rows(points, by_command, expert, run)
    fits = {axis: _fit(rows, axis) for axis in VELOCITY_AXES}
    table = {
        "figure": "velocity",
        "thesis_figure": THESIS_FIGURE["velocity"],
        "seed": run.seed,
        "quick": run.quick,
        "controller": "KernelController(kernel-base)",
        "kernel": str(kernel_path),
        "duration": duration,
        "ramp": HOLD_RAMP,
        "measured_from": HOLD_RAMP + HOLD_SETTLE,
        "metric": (
            "as the expert's velocity figure (krl.analysis.expert.velocity): each command (others zero) "
            f"held from a standing start, rising from zero over {HOLD_RAMP:g} s; "
            "realised (vx, vy) of the trunk in its "
            f"heading frame [m/s] and yaw rate [rad/s] at every control step from "
            f"t = {HOLD_RAMP + HOLD_SETTLE:g} s; mean / std over time; fits: least squares realised_mean = "
            "slope * commanded + offset over the points that did not fall; falls = points that fell; "
            "max_std = largest std over time"
        ),
        "fits": fits,
        "expert_source": expert_source,
        "expert_fits": (expert or {}).get("fits"),
        "expert_duration": (expert or {}).get("duration"),
        "conditions": rows,
    }
    csv_columns = (*VELOCITY_COLUMNS, "expert_mean", "expert_std")
    return table, csv_columns, rows, _draw(rows, fits, duration, run.quick)


def _hold_all(kernel_path: Path, points: list, duration: float, run: FigureRun) -> dict:
    """Each distinct command of the sweep ``points`` held by the kernel for ``duration`` [s] (in
    ``run.workers`` processes): the :func:`_kernel_hold` outcome per command."""
    # the zero command appears in all three sweeps: run each distinct command once
    jobs = list(dict.fromkeys((str(kernel_path), command, duration, run.seed) for _, _, command in points))
    run.say(f"velocity: {len(jobs)} kernel holds of {duration:g} s, {run.workers} worker(s) ...")
    outcomes = run_jobs(_kernel_hold, jobs, run.workers, progress="velocity holds" if run.progress else None)
    return {job[1]: outcome for job, outcome in zip(jobs, outcomes, strict=True)}


def _rows(points: list, by_command: dict, expert: dict | None, run: FigureRun) -> list[dict]:
    """A :func:`~krl.analysis.common.velocity_row` per sweep point, with the ``expert`` table's mean, std
    and fall at the same point (None where it has none)."""
    expert_rows = {(r["axis"], round(r["commanded"], 6)): r for r in (expert or {}).get("conditions", [])}
    rows = []
    for axis, value, command in points:
        outcome = by_command[command]
        row = velocity_row(axis, value, outcome)
        match = expert_rows.get((axis, round(value, 6)))
        row["expert_mean"] = match[f"{axis}_mean"] if match else None
        row["expert_std"] = match[f"{axis}_std"] if match else None
        row["expert_fell"] = match["fell"] if match else None
        rows.append(row)
        status = " FELL" if outcome["fell"] else ""
        run.say(
            f"  {axis} = {value:+.2f}: realised {outcome['mean'][VELOCITY_AXES.index(axis)]:+.3f}"
            f"{status} ({outcome['wall_seconds']:.1f} s)",
        )
    return rows


def _fit(rows: list[dict], axis: str) -> dict[str, float]:
    """The line fit of ``axis``'s realised mean against the command over its points that did not fall, with
    ``falls``, ``max_abs_cross`` and ``max_std``."""
    ok = [r for r in rows if r["axis"] == axis and not r["fell"]]
    fit = fit_rows(ok, "commanded", f"{axis}_mean")
    fit["falls"] = sum(1 for r in rows if r["axis"] == axis and r["fell"])
    fit["max_abs_cross"] = max_cross(ok, axis)
    fit["max_std"] = max((r[f"{axis}_std"] for r in ok), default=float("nan"))
    return fit


def _draw(rows: list[dict], fits: dict, duration: float, quick: bool):
    """The figure: a realised-against-commanded panel per command component."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(FIG_SIZE[0], FIG_SIZE[1] * 0.75), dpi=FIG_DPI, layout="constrained")
    axes = fig.subplots(1, 3)
    for ax, axis in zip(axes, VELOCITY_AXES, strict=True):
        _draw_panel(ax, axis, [r for r in rows if r["axis"] == axis], fits[axis])
    fig.suptitle(
        f"Thesis {THESIS_FIGURE['velocity']}: realised vs commanded velocity, kernel-base controller vs MPC "
        f"expert ({duration:g} s holds, measured from {HOLD_RAMP + HOLD_SETTLE:g} s"
        f"{', quick' if quick else ''})",
        fontsize=9,
    )
    return fig


def _draw_panel(ax, axis: str, sel: list[dict], fit: dict[str, float]) -> None:
    """The panel of ``axis`` from its rows ``sel``: the identity, the expert's and the kernel's mean ± std
    (side by side), the kernel's falls as crosses and its fitted line."""
    x = np.array([r["commanded"] for r in sel])
    lim = max(abs(x).max(), 1e-3) * 1.15
    ax.plot([-lim, lim], [-lim, lim], "k--", lw=0.8, label="identity")
    ex = [(r["commanded"], r["expert_mean"], r["expert_std"]) for r in sel if r["expert_mean"] is not None]
    if ex:
        e = np.array(ex, dtype=float)
        ax.errorbar(
            e[:, 0] - 0.01 * lim,
            e[:, 1],
            yerr=e[:, 2],
            fmt="s",
            ms=3.5,
            capsize=2,
            color="C0",
            label="MPC expert (velocity.json)",
        )
    ok = np.array([not r["fell"] for r in sel])
    mean = np.array([r[f"{axis}_mean"] for r in sel], dtype=float)
    std = np.array([r[f"{axis}_std"] for r in sel], dtype=float)
    if ok.any():
        ax.errorbar(
            x[ok] + 0.01 * lim,
            mean[ok],
            yerr=std[ok],
            fmt="o",
            ms=4,
            capsize=2,
            color="C1",
            label="kernel-base: mean ± std",
        )
    if (~ok).any():
        y = np.where(np.isfinite(mean[~ok]), mean[~ok], 0.0)
        ax.plot(x[~ok], y, "rx", ms=9, mew=2, label="kernel-base fell")
    label = f"kernel fit: slope {fit['slope']:.2f}, offset {fit['offset']:+.3f}"
    draw_fit_and_axes(ax, fit, lim, *VELOCITY_NAMES[axis], label)
    style(ax)
    ax.legend(fontsize=6, loc="upper left")
