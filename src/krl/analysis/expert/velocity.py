"""The expert's ``velocity`` figure (the MPC half of thesis Fig. 4.15): realised against commanded velocity,
each component swept over the command generator's limits with the other two held at zero.
"""

from __future__ import annotations

import numpy as np

from krl.analysis.common import FIG_SIZE, VELOCITY_AXES, fit_line, max_cross, velocity_row
from krl.analysis.expert.plan import THESIS_FIGURE, Settings
from krl.analysis.expert.runs import SWEEP_STANCE
from krl.analysis.panels import VELOCITY_NAMES, draw_fit_and_axes, style
from krl.task.runner import HOLD_RAMP, HOLD_SETTLE
from krl.util.output import FIG_DPI


def velocity_table(conditions: list, results: dict, settings: Settings) -> tuple[dict, list]:
    """The JSON table (with a line fit per component) and the CSV rows, one per commanded point."""
    rows = [velocity_row(axis, value, results[job]) for (axis, value), job in conditions]
    fits = {}
    for axis in VELOCITY_AXES:
        points = [r for r in rows if r["axis"] == axis and not r["fell"]]
        fits[axis] = fit_line([r["commanded"] for r in points], [r[f"{axis}_mean"] for r in points])
        fits[axis]["max_abs_cross"] = max_cross(points, axis)
    table = {
        "figure": "velocity",
        "thesis_figure": THESIS_FIGURE["velocity"],
        "seed": settings.seed,
        "quick": settings.quick,
        "stance_duration": SWEEP_STANCE,
        "duration": settings.duration,
        "ramp": HOLD_RAMP,
        "measured_from": HOLD_RAMP + HOLD_SETTLE,
        "metric": (
            "each point: the command (others zero) held from a standing start, rising from zero over "
            f"{HOLD_RAMP:g} s; realised (vx, vy) of the trunk origin in its heading frame [m/s] and yaw "
            f"rate wz [rad/s] at every control step from t = {HOLD_RAMP + HOLD_SETTLE:g} s; *_mean / *_std "
            "= mean / standard deviation over time; fits: least squares realised_mean = slope * commanded "
            "+ offset over the points that did not fall; max_abs_cross = largest |mean| of the two "
            "uncommanded components"
        ),
        "fits": fits,
        "conditions": rows,
    }
    return table, rows


def plot_velocity(conditions: list, results: dict, settings: Settings, fits: dict):
    """The matplotlib figure: one realised-vs-commanded panel per component."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(FIG_SIZE[0], FIG_SIZE[1] * 0.6), dpi=FIG_DPI, layout="constrained")
    axes = fig.subplots(1, 3)
    for index, (ax, axis) in enumerate(zip(axes, VELOCITY_AXES, strict=True)):
        points = [(value, results[job]) for (a, value), job in conditions if a == axis]
        x = np.array([p[0] for p in points])
        mean = np.array([p[1]["mean"][index] for p in points])
        std = np.array([p[1]["std"][index] for p in points])
        fell = np.array([p[1]["fell"] for p in points], dtype=bool)
        lim = max(abs(x).max(), 1e-3) * 1.15
        ax.plot([-lim, lim], [-lim, lim], "k--", lw=0.8, label="identity (realised = commanded)")
        ax.errorbar(
            x[~fell],
            mean[~fell],
            yerr=std[~fell],
            fmt="o",
            ms=4,
            capsize=3,
            color="C0",
            label="MPC expert: mean ± std over time",
        )
        if fell.any():
            ax.plot(x[fell], mean[fell], "rx", ms=8, label="fell")
        fit = fits[axis]
        label = f"fit: slope {fit['slope']:.3f}, offset {fit['offset']:+.3f}"
        draw_fit_and_axes(ax, fit, lim, *VELOCITY_NAMES[axis], label)
        ax.legend(fontsize=6, loc="upper left")
        style(ax)
    fig.suptitle(
        f"Thesis {THESIS_FIGURE['velocity']}: realised vs commanded velocity, MPC expert "
        f"(τ_stance = {SWEEP_STANCE:g} s, {settings.duration:g} s holds, measured from "
        f"{HOLD_RAMP + HOLD_SETTLE:g} s{', quick' if settings.quick else ''})",
        fontsize=9,
    )
    return fig
