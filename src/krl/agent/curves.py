"""Training curves of residual agents: episode reward, targets reached and fall rate against env steps.

Read from each run folder's ``progress.csv`` and the segments resumptions set aside
(``progress.<steps>.csv``, :mod:`krl.agent.train`). :func:`plot_training_curves` draws one line per run;
:func:`plot_seed_groups` draws, for each group of runs (the seeds of one agent), the mean over its runs
and their spread (± one standard deviation) of the targets reached, the success rate and the fall rate,
as the thesis's Fig. 4.23 does.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from krl.util.output import figure_bytes, write_atomic

STEPS_COLUMN = "time/total_timesteps"
"""The column of ``progress.csv`` (SB3's) that holds the env steps trained when the row was logged."""

PANELS: tuple[tuple[str, str], ...] = (
    ("episode/reward", "episode reward"),
    ("episode/targets_reached", "targets reached per episode"),
    ("episode/fall_rate", "fall rate (episodes ending in a fall)"),
)
"""(progress.csv column, axis label) of each panel."""

GROUP_PANELS: tuple[tuple[str, str], ...] = (
    ("episode/targets_reached", "targets reached per episode"),
    ("episode/success_rate", "success rate (>= 2 targets, no fall)"),
    ("episode/fall_rate", "fall rate (episodes ending in a fall)"),
)
"""(progress.csv column, axis label) of each panel of :func:`plot_seed_groups` (Fig. 4.23); a log written
before ``episode/success_rate`` was logged leaves that panel without the run."""

GRID_STEPS: float = 2e5
"""Spacing of the common env-step grid the runs of a group are interpolated onto (one rollout)."""


def read_progress(run: Path) -> dict[str, list[float]]:
    """The columns of a run's training log that the panels need, as floats, in step order: the segments
    left by resumptions (``progress.<steps>.csv``) and then ``progress.csv`` (rows missing one skipped)."""
    path = run / "progress.csv"
    if not path.is_file():
        raise FileNotFoundError(f"no training log {path} (is {run} a krl agent train folder?)")
    columns: dict[str, list[float]] = {STEPS_COLUMN: []}
    columns.update({name: [] for name, _ in (*PANELS, *GROUP_PANELS)})
    for segment in [*sorted(run.glob("progress.*.csv")), path]:
        with open(segment, newline="") as handle:
            for row in csv.DictReader(handle):
                if all(row.get(name) not in (None, "") for name, _ in (*PANELS, (STEPS_COLUMN, ""))):
                    for name in columns:
                        value = row.get(name)
                        columns[name].append(float(value) if value not in (None, "") else float("nan"))
    return columns


def plot_training_curves(runs: list[Path], out: Path) -> list[Path]:
    """Write ``training-curves.png`` (three panels, one line per run) into ``out``; returns its path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(PANELS), figsize=(12, 3.4))
    for run in runs:
        progress = read_progress(run)
        steps = [s / 1e6 for s in progress[STEPS_COLUMN]]
        for ax, (name, _) in zip(axes, PANELS, strict=True):
            ax.plot(steps, progress[name], label=run.name, linewidth=1.2)
    for ax, (_, label) in zip(axes, PANELS, strict=True):
        ax.set_xlabel("env steps [1e6]")
        ax.set_title(label, fontsize=10)
        ax.grid(alpha=0.3)
    axes[-1].set_ylim(-0.02, 1.02)
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    path = out / "training-curves.png"
    write_atomic(path, figure_bytes(fig))
    plt.close(fig)
    return [path]


def group_curve(runs: list[Path], column: str) -> dict[str, np.ndarray]:
    """Mean and standard deviation over ``runs`` of one ``progress.csv`` column, on a common grid of env
    steps (every :data:`GRID_STEPS`, up to the shortest run; linear interpolation between logged rows).

    Returns ``{"steps", "mean", "std", "runs"}``: arrays of shape (G,), and the number of runs that log the
    column (runs without it are left out; no run: empty arrays).
    """
    curves = []
    for run in runs:
        progress = read_progress(run)
        steps, values = np.asarray(progress[STEPS_COLUMN]), np.asarray(progress[column])
        logged = np.isfinite(values)
        if logged.any():
            curves.append((steps[logged], values[logged]))
    if not curves:
        empty = np.zeros(0)
        return {"steps": empty, "mean": empty, "std": empty, "runs": 0}
    start = max(steps[0] for steps, _ in curves)
    end = min(steps[-1] for steps, _ in curves)
    grid = np.arange(np.ceil(start / GRID_STEPS) * GRID_STEPS, end + 1, GRID_STEPS)
    stacked = np.array([np.interp(grid, steps, values) for steps, values in curves])
    return {"steps": grid, "mean": stacked.mean(axis=0), "std": stacked.std(axis=0), "runs": len(curves)}


def plot_seed_groups(groups: dict[str, list[Path]], out: Path) -> list[Path]:
    """Write ``seed-groups.png``: per panel of :data:`GROUP_PANELS`, each group's mean over its runs with a
    band of ± one standard deviation (Fig. 4.23); returns its path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(GROUP_PANELS), figsize=(12, 3.4))
    for label, runs in groups.items():
        for ax, (column, _) in zip(axes, GROUP_PANELS, strict=True):
            curve = group_curve(runs, column)
            if curve["runs"]:
                x = curve["steps"] / 1e6
                line = ax.plot(x, curve["mean"], linewidth=1.2, label=f"{label} ({curve['runs']} runs)")
                ax.fill_between(
                    x,
                    curve["mean"] - curve["std"],
                    curve["mean"] + curve["std"],
                    color=line[0].get_color(),
                    alpha=0.2,
                )
    for ax, (_, title) in zip(axes, GROUP_PANELS, strict=True):
        ax.set_xlabel("env steps [1e6]")
        ax.set_title(title, fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    for ax in axes[1:]:
        ax.set_ylim(-0.02, 1.02)
    fig.tight_layout()
    path = out / "seed-groups.png"
    write_atomic(path, figure_bytes(fig))
    plt.close(fig)
    return [path]
