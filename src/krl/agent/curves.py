"""Training curves of residual agents: episode reward, targets reached and fall rate against env steps.

Read from each run folder's ``progress.csv`` and the segments resumptions set aside
(``progress.<steps>.csv``, :mod:`krl.agent.train`); one line per run, so the
runs of several seeds (Fig. 4.23) or settings share one figure.
"""

from __future__ import annotations

import csv
from pathlib import Path

from krl.util.output import figure_bytes, write_atomic

STEPS_COLUMN = "time/total_timesteps"
"""The column of ``progress.csv`` (SB3's) that holds the env steps trained when the row was logged."""

PANELS: tuple[tuple[str, str], ...] = (
    ("episode/reward", "episode reward"),
    ("episode/targets_reached", "targets reached per episode"),
    ("episode/fall_rate", "fall rate (episodes ending in a fall)"),
)
"""(progress.csv column, axis label) of each panel."""


def read_progress(run: Path) -> dict[str, list[float]]:
    """The columns of a run's training log that the panels need, as floats, in step order: the segments
    left by resumptions (``progress.<steps>.csv``) and then ``progress.csv`` (rows missing one skipped)."""
    path = run / "progress.csv"
    if not path.is_file():
        raise FileNotFoundError(f"no training log {path} (is {run} a krl agent train folder?)")
    columns: dict[str, list[float]] = {STEPS_COLUMN: []}
    columns.update({name: [] for name, _ in PANELS})
    for segment in [*sorted(run.glob("progress.*.csv")), path]:
        with open(segment, newline="") as handle:
            for row in csv.DictReader(handle):
                if all(row.get(name) not in (None, "") for name in columns):
                    for name in columns:
                        columns[name].append(float(row[name]))
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
