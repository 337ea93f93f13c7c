"""``command-sweep`` (thesis Fig. 4.10): kernel-base's FR foot over one trot cycle while one command
(frontal 0..1 m/s, lateral -0.5..0.5 m/s, yaw -1..1 rad/s) varies and the others are zero.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from krl.analysis.common import FIG_SIZE, fit_rows
from krl.analysis.kernel.context import FR, THESIS_FIGURE, FigureRun
from krl.analysis.kernel.metrics import AXES, CYCLE_POINTS, sweep_metrics
from krl.analysis.kernel.recording import (
    command_limits,
    cycle_inputs,
    expert_params,
    kernel_columns,
    predict_feet,
)
from krl.analysis.panels import shade, style
from krl.util.output import FIG_DPI

VX_SWEEP: tuple[float, float] = (0.0, 1.0)
VY_SWEEP: tuple[float, float] = (-0.5, 0.5)
WZ_SWEEP: tuple[float, float] = (-1.0, 1.0)
SWEEP_VALUES: int = 11
"""Command values per sweep of Fig. 4.10 (steps 0.1 m/s, 0.1 m/s, 0.2 rad/s)."""

_TITLES: dict[str, tuple[str, str, str]] = {
    "vx": ("(a) frontal velocity", "v_x", "m/s"),
    "vy": ("(b) lateral velocity", "v_y", "m/s"),
    "wz": ("(c) yaw rate", "ω_z", "rad/s"),
}
"""(panel title, symbol, unit) of each command's column."""
_CSV_COLUMNS: tuple[str, ...] = (
    "command",
    "value",
    "in_training_range",
    "x_ptp",
    "x_mean",
    "y_ptp",
    "y_mean",
    "z_ptp",
    "z_mean",
    "z_min",
    "z_max",
)


def _command_grid(name: str, quick: bool) -> np.ndarray:
    low, high = {"vx": VX_SWEEP, "vy": VY_SWEEP, "wz": WZ_SWEEP}[name]
    return np.round(np.linspace(low, high, 3 if quick else SWEEP_VALUES), 6) + 0.0


def _z_spread(curves: list) -> float:
    """max over the cycle of (max − min of z over the curves) [m]; NaN for fewer than two curves."""
    if len(curves) < 2:
        return float("nan")
    z = np.stack([c[2][:, 2] for c in curves])
    return float(np.ptp(z, axis=0).max())


def command_sweep_figure(kernel, run: FigureRun):
    """Fig. 4.10 for kernel-base ``kernel`` (no simulation: the kernel alone).

    Returns ``(table, csv columns, csv rows, matplotlib figure)``.
    """
    stance_duration = expert_params(kernel).stance_duration
    cycle = cycle_inputs("trot", stance_duration)
    limits = command_limits(kernel)
    rows, curves = _sweep(kernel, cycle, limits, run.quick)
    summary = {name: _summary([r for r in rows if r["command"] == name], curves[name]) for name in curves}
    table = {
        "figure": "command-sweep",
        "thesis_figure": THESIS_FIGURE["command-sweep"],
        "quick": run.quick,
        "gait": "trot",
        "stance_duration": stance_duration,
        "step_duration": cycle["step_duration"],
        "cycle_points": CYCLE_POINTS,
        "training_range": limits,
        "metric": (
            "kernel-base FR foot (base frame) over one trot cycle sampled at φ_FR = j/K, j = 1..K "
            f"(K = {CYCLE_POINTS}), the other legs' |φ| from the gait generator at the same instant; one "
            "command varied, the others zero; *_ptp = max − min over the cycle [m], *_mean = mean over the "
            "cycle [m]; fits: least squares of x_ptp / y_ptp against the command over the values inside the "
            "command generator's limits (the training range); z_spread = max over the cycle of (max − min of "
            "z(φ; c) over the commands c) [m], over the commands inside the training range, inside it but "
            "without the zero command, and over all commands of the sweep"
        ),
        "summary": summary,
        "conditions": rows,
    }
    return table, _CSV_COLUMNS, rows, _draw(cycle, curves, limits)


def _sweep(kernel, cycle: dict, limits: dict, quick: bool) -> tuple[list, dict]:
    """Predict the FR foot over ``cycle`` for each command value of each sweep.

    Returns the CSV rows (one per command value, sweeps in ``vx, vy, wz`` order) and, per sweep, the curves
    ``(value, inside the training range, FR foot (CYCLE_POINTS, 3))``.
    """
    rows, curves = [], {}
    for index, name in enumerate(("vx", "vy", "wz")):
        curves[name] = []
        for value in _command_grid(name, quick):
            command = np.zeros(3)
            command[index] = value
            feet = predict_feet(
                kernel, kernel_columns(np.tile(command, (CYCLE_POINTS, 1)), cycle["normalised"])
            )
            fr = feet[:, FR]
            low, high = limits[name]
            inside = bool(low - 1e-9 <= value <= high + 1e-9)
            rows.append(
                {"command": name, "value": float(value), "in_training_range": inside, **sweep_metrics(fr)}
            )
            curves[name].append((float(value), inside, fr))
    return rows, curves


def _summary(rows: list, curves: list) -> dict[str, Any]:
    """One sweep's summary from its ``rows`` and ``curves`` (:func:`_sweep`): fits of the x and y extents
    inside the training range, the z extents inside and outside it, and the z spreads."""
    inside_rows = [r for r in rows if r["in_training_range"]]
    outside_rows = [r for r in rows if not r["in_training_range"]]
    return {
        "x_ptp_fit_inside": fit_rows(inside_rows, "value", "x_ptp"),
        "y_ptp_fit_inside": fit_rows(inside_rows, "value", "y_ptp"),
        "z_ptp_range_inside": [
            min((r["z_ptp"] for r in inside_rows), default=float("nan")),
            max((r["z_ptp"] for r in inside_rows), default=float("nan")),
        ],
        "z_ptp_range_outside": [
            min((r["z_ptp"] for r in outside_rows), default=float("nan")),
            max((r["z_ptp"] for r in outside_rows), default=float("nan")),
        ],
        "z_spread_inside": _z_spread([c for c in curves if c[1]]),
        "z_spread_inside_nonzero": _z_spread([c for c in curves if c[1] and abs(c[0]) > 1e-9]),
        "z_spread_all": _z_spread(curves),
    }


def _draw(cycle: dict, curves: dict, limits: dict):
    """The figure: one column per sweep (x, y, z of the FR foot over the cycle) over its colour scale."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=FIG_SIZE, dpi=FIG_DPI, layout="constrained")
    axes = fig.subplots(3, 3, sharex=True)
    for col, name in enumerate(("vx", "vy", "wz")):
        _draw_sweep(fig, axes[:, col], name, cycle, curves[name], limits[name], ylabels=col == 0)
    fig.suptitle(
        f"Thesis {THESIS_FIGURE['command-sweep']}: kernel-base FR foot over one trot cycle "
        f"(τ_step {cycle['step_duration']:.3f} s), one command varied, the others zero\n"
        "grey bars on the colour scales: training limits (command generator); dashed curves: outside them",
        fontsize=9,
    )
    return fig


def _draw_sweep(fig, column, name: str, cycle: dict, curves: list, limits: tuple, ylabels: bool) -> None:
    """One sweep's ``column`` of axes (x, y, z; labelled on the left with ``ylabels``): a curve per command
    value, solid inside the training range ``limits`` and dashed outside, coloured by the value; under it
    the colour bar, the limits marked."""
    import matplotlib as mpl

    title, symbol, unit = _TITLES[name]
    grid = [c[0] for c in curves]
    norm = mpl.colors.Normalize(min(grid), max(grid))
    cmap = mpl.colormaps["viridis"]
    phase = cycle["phase"]
    for row, ax in enumerate(column):
        shade(ax, phase, ~cycle["stance"])
        for value, inside, fr in curves:
            ax.plot(phase, fr[:, row], color=cmap(norm(value)), lw=1.0, ls="-" if inside else "--")
        if ylabels:
            ax.set_ylabel(f"FR {AXES[row]} [m]")
        style(ax)
    column[0].set_title(f"{title} {min(grid):g}…{max(grid):g} {unit}")
    column[2].set_xlabel("FR phase φ_FR [cycles] (shaded: swing)")
    bar = fig.colorbar(
        mpl.cm.ScalarMappable(norm=norm, cmap=cmap),
        ax=column,
        location="bottom",
        shrink=0.9,
        aspect=30,
        pad=0.01,
    )
    for edge in limits:
        if min(grid) <= edge <= max(grid):
            bar.ax.axvline(edge, color="0.35", lw=3.0)
    bar.set_label(f"commanded {symbol} [{unit}]", fontsize=7)
    bar.ax.tick_params(labelsize=7)
