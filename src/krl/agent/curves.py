"""Training curves of residual agents: episode reward, targets reached and fall rate against env steps.

Read from each run folder's ``progress.csv`` and the segments resumptions set aside
(``progress.<steps>.csv``, :mod:`krl.agent.train`). :func:`plot_training_curves` draws one line per run;
:func:`plot_seed_groups` draws, for each group of runs (the seeds of one agent), the mean over its runs
and their spread (± one standard deviation) of the targets reached, the success rate and the fall rate,
as the thesis's Fig. 4.23 does; :func:`reach_rows` reads those curves as numbers: the env steps each group
needs to reach a reference group's final success rate.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

import numpy as np

from krl.agent.config import AgentConfig, EnvConfig
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
    steps (every :data:`GRID_STEPS`, up to the shortest run; the shortest run's last step alone where that
    is no grid point; linear interpolation between logged rows).

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
    if not grid.size:  # runs shorter than a grid step (a smoke run): compared where all have logged
        grid = np.array([end], dtype=float)
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


REACH_COLUMN = "episode/success_rate"
"""The measure :func:`reach_rows` compares: the training episodes' success rate (>= 2 targets, no fall)."""


def steps_to_reach(curve: dict[str, np.ndarray], level: float) -> float | None:
    """The first env step of ``curve`` (:func:`group_curve`) at which its mean is at or above ``level``;
    None if it never is."""
    reached = np.flatnonzero(curve["mean"] >= level - 1e-12)
    return float(curve["steps"][reached[0]]) if reached.size else None


def trailing_mean(curve: dict[str, np.ndarray], window_steps: float, label: str) -> dict[str, np.ndarray]:
    """``curve`` (:func:`group_curve`) with its mean averaged over the trailing ``window_steps`` env steps:
    at each grid point the mean of the last k = ``window_steps / GRID_STEPS`` grid points up to it; the
    points before the first full window are dropped (arrays of shape (G - k + 1,)). ``label`` names the
    curve in errors.

    Raises:
        ValueError: ``window_steps`` is no positive multiple of :data:`GRID_STEPS`, or spans more grid
            points than the curve has.
    """
    points = round(window_steps / GRID_STEPS) if np.isfinite(window_steps) else 0
    if points < 1 or abs(points * GRID_STEPS - window_steps) > 1e-6 * GRID_STEPS:
        raise ValueError(
            f"--window {window_steps:.10g}: not a positive multiple of the {GRID_STEPS:.10g}-step grid"
        )
    if points > curve["mean"].size:
        raise ValueError(
            f"--window {window_steps:.10g}: longer than --group {label}'s curve "
            f"({curve['mean'].size} grid points of {GRID_STEPS:.10g} env steps)"
        )
    mean = np.convolve(curve["mean"], np.full(points, 1.0 / points), mode="valid")
    return {"steps": curve["steps"][points - 1 :], "mean": mean, "runs": curve["runs"]}


def reach_rows(
    groups: dict[str, list[Path]], reference: str, window_steps: float | None = None
) -> list[dict[str, Any]]:
    """Sample efficiency (the issue-45 question, Fig. 4.23's curves read as numbers): for each group, the
    env steps at which its mean training success rate (:data:`REACH_COLUMN`, on :func:`group_curve`'s grid)
    first reaches the ``reference`` group's final mean, the level the reference ends at. With
    ``window_steps``, every curve (the reference's too, so its level is its mean over its last
    ``window_steps``) is first a :func:`trailing_mean`: single rollouts' rates swing by ±0.1, a window's
    mean does not.

    Rows: ``label``, ``runs``, ``final_steps`` and ``final_success`` (the group's own last grid point),
    ``level``, ``steps_to_level`` (None: never reached), ``window_steps`` (None: single rollouts) and
    ``same_env``: whether the group's runs trained
    in the reference's environment (the ``env`` section of their ``config.json``; false where one is
    unreadable). A rate measures each
    group on its own training ground with the stochastic actions of training, so only a group with
    ``same_env`` compares with the level (a symmetric arm against its recipe without symmetry, say).

    Raises:
        ValueError: ``reference`` is no group, a group logs no success rate, or the window is invalid
            (:func:`trailing_mean`).
    """
    if reference not in groups:
        raise ValueError(f"--reach {reference!r} is no --group label (labels: {', '.join(groups)})")
    curves = {label: group_curve(runs, REACH_COLUMN) for label, runs in groups.items()}
    for label, curve in curves.items():
        if not curve["runs"]:
            raise ValueError(f"--group {label}: no run logs {REACH_COLUMN} (trained before it was logged)")
    if window_steps is not None:
        curves = {label: trailing_mean(curve, window_steps, label) for label, curve in curves.items()}
    level = float(curves[reference]["mean"][-1])
    envs = {label: {_env_section(run) for run in runs} for label, runs in groups.items()}
    return [
        {
            "label": label,
            "runs": curve["runs"],
            "final_steps": float(curve["steps"][-1]),
            "final_success": float(curve["mean"][-1]),
            "level": level,
            "steps_to_level": steps_to_reach(curve, level),
            "window_steps": window_steps,
            "same_env": envs[label] == envs[reference] and len(envs[label]) == 1 and None not in envs[label],
        }
        for label, curve in curves.items()
    ]


def _env_section(run: Path) -> EnvConfig | None:
    """The environment a run folder's ``config.json`` trained in, fields it predates at their defaults
    (None: no readable config)."""
    try:
        return AgentConfig.load(run / "config.json").env
    except (OSError, ValueError):
        return None


def write_reach(rows: list[dict[str, Any]], reference: str, out: Path) -> list[Path]:
    """Write :func:`reach_rows`'s table as ``reach.md`` and ``reach.json`` into ``out`` (read over a window:
    ``reach-window-<steps>.md`` and ``.json``, so both readings of the same groups can share a folder);
    returns the paths."""

    def millions(steps: float | None) -> str:
        return "not reached" if steps is None else f"{steps / 1e6:.1f}"

    level, window = rows[0]["level"], rows[0]["window_steps"]
    averaged = (
        "single rollouts"
        if window is None
        else f"each point the mean over the last {window / 1e6:g}e6 env steps"
    )
    lines = [
        f"# Env steps to {reference}'s final training success ({level:.2f})",
        "",
        "| agent | runs | final success | at env steps [1e6] | reaches the level at [1e6] | its ground |",
        "| --- | --- | --- | --- | --- | --- |",
        *(
            f"| {row['label']} | {row['runs']} | {row['final_success']:.2f} | {millions(row['final_steps'])} "
            f"| {millions(row['steps_to_level'])} | {'same' if row['same_env'] else 'other'} |"
            for row in rows
        ),
        "",
        f"The mean over each agent's runs of `{REACH_COLUMN}` in `progress.csv` (training episodes, "
        f"stochastic actions), on a grid of {GRID_STEPS:.0e} env steps, {averaged}. Only an agent trained on "
        f"{reference}'s ground (its ground: same) compares with the level.",
    ]
    stem = "reach" if window is None else f"reach-window-{round(window)}"
    markdown, record = out / f"{stem}.md", out / f"{stem}.json"
    write_atomic(markdown, "\n".join(lines) + "\n")
    write_atomic(record, json.dumps({"reference": reference, "rows": rows}, indent=1) + "\n")
    return [markdown, record]
