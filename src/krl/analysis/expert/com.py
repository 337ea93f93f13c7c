"""The expert's CoM figures: ``com-variance`` (thesis Fig. 4.8), ``ride-height`` (Fig. A.2) and
``step-height`` (Fig. A.3): each condition's table row and the six-panel figure (path, deviation
excerpts, standard deviations).
"""

from __future__ import annotations

import numpy as np

from krl.analysis.common import FIG_SIZE
from krl.analysis.expert.metrics import DETREND_MIN_SECONDS, SKIP_SECONDS
from krl.analysis.expert.plan import THESIS_FIGURE, Settings
from krl.analysis.expert.runs import SWEEP_STANCE
from krl.analysis.panels import style
from krl.task import TARGET_TIME_LIMIT
from krl.util.output import FIG_DPI

COM_COLUMNS: tuple[str, ...] = (
    "label",
    "stance_duration",
    "ride_height",
    "step_height",
    "com_std_x",
    "com_std_y",
    "com_std_z",
    "com_std",
    "roll_std_deg",
    "pitch_std_deg",
    "com_height_mean",
    "mean_speed",
    "targets_reached",
    "fell",
    "timed_out",
    "sim_seconds",
    "gait_cycle",
    "window_steps",
    "samples",
)

COM_METRIC_TEXT = (
    "CoM deviation = Rz(yaw)^T ((I - M)^2 com) = Rz(yaw)^T (com - 2 M com + M M com), M = centred moving "
    f"average over the fewest whole gait cycles lasting >= {DETREND_MIN_SECONDS:g} s, in the trunk's "
    f"heading frame (x forward, y left, z up), from t = {SKIP_SECONDS:g} s; com_std_x/y/z = its standard "
    "deviation over time [m]; com_std = their root sum of squares [m]; roll_std_deg / pitch_std_deg = "
    "standard deviation of trunk roll / pitch over the same time [deg]; com_height_mean [m]; "
    "mean_speed = CoM path length / time [m/s]"
)


def com_table(which: str, conditions: list, results: dict, settings: Settings) -> tuple[dict, list]:
    """The JSON table of CoM figure ``which`` and its CSV rows (one per condition) from the runs' results."""
    rows = []
    for (label, cfg), job in conditions:
        result = results[job]
        row = {
            "label": label,
            "stance_duration": cfg["stance"],
            "ride_height": cfg["ride"],
            "step_height": cfg["step"],
            **{key: result[key] for key in COM_COLUMNS if key in result},
        }
        row["error"] = result["error"]
        rows.append(row)
    table = {
        "figure": which,
        "thesis_figure": THESIS_FIGURE[which],
        "seed": settings.seed,
        "quick": settings.quick,
        "waypoints": [list(p) for p in conditions[0][1].targets],
        "target_time_limit": TARGET_TIME_LIMIT,
        "metric": COM_METRIC_TEXT,
        "conditions": rows,
    }
    return table, rows


def plot_com(which: str, conditions: list, results: dict, settings: Settings):
    """The matplotlib figure of CoM figure ``which``."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=FIG_SIZE, dpi=FIG_DPI, layout="constrained")
    axes = fig.subplots(2, 3)
    colors = [f"C{i}" for i in range(len(conditions))]
    labels = [label for (label, _), _ in conditions]
    waypoints = np.array(conditions[0][1].targets)
    ax = axes[0, 0]
    handles = []
    for color, label, (_, job) in zip(colors, labels, conditions, strict=True):
        path = results[job]["path_xy"]
        handles += ax.plot(path[:, 0], path[:, 1], color=color, lw=0.8, label=label)
        if results[job]["fell"]:
            ax.plot(*path[-1], "x", color=color, ms=8)
    marks = ax.plot(0.0, 0.0, "ko", ms=4, label="start")
    marks += ax.plot(waypoints[:, 0], waypoints[:, 1], "k*", ms=7, label="waypoints")
    if any(results[job]["fell"] for _, job in conditions):
        marks += ax.plot([], [], "kx", ms=8, label="fell")
    ax.set(xlabel="x [m]", ylabel="y [m]", title="CoM path (top view)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(handles=marks, fontsize=6, loc="best")
    fig.legend(handles=handles, loc="outside lower center", ncol=len(handles), fontsize=8)
    panels = (
        (axes[0, 1], "dev_y", 1e3, "lateral CoM deviation y' [mm]"),
        (axes[0, 2], "height", 1.0, "CoM height z [m]"),
        (axes[1, 0], "dev_x", 1e3, "forward CoM deviation x' [mm]"),
    )
    for ax, key, scale, ylabel in panels:
        for color, label, (_, job) in zip(colors, labels, conditions, strict=True):
            excerpt = results[job]["excerpt"]
            ax.plot(excerpt["t"], scale * excerpt[key], color=color, lw=0.8, label=label)
        ax.set(xlabel="time [s]", ylabel=ylabel, title=ylabel.split(" [")[0] + " (excerpt)")
    width = 0.8 / len(conditions)
    ax = axes[1, 1]
    for i, (color, label, (_, job)) in enumerate(zip(colors, labels, conditions, strict=True)):
        values = [1e3 * results[job][k] for k in ("com_std_x", "com_std_y", "com_std_z")]
        bars = ax.bar(
            np.arange(3) + (i - (len(conditions) - 1) / 2) * width, values, width, color=color, label=label
        )
        ax.bar_label(bars, fmt="%.1f", fontsize=5)
    ax.set_xticks(np.arange(3), ["x' forward", "y' lateral", "z up"])
    ax.set(ylabel="std of CoM deviation [mm]", title="CoM standard deviation (whole run)")
    ax = axes[1, 2]
    for i, (color, label, (_, job)) in enumerate(zip(colors, labels, conditions, strict=True)):
        values = [results[job]["roll_std_deg"], results[job]["pitch_std_deg"]]
        bars = ax.bar(
            np.arange(2) + (i - (len(conditions) - 1) / 2) * width, values, width, color=color, label=label
        )
        ax.bar_label(bars, fmt="%.2f", fontsize=5)
    ax.set_xticks(np.arange(2), ["roll", "pitch"])
    ax.set(ylabel="std of trunk angle [deg]", title="trunk tilt standard deviation (whole run)")
    for ax in axes.flat:
        style(ax, grid=False)
    stance = {
        "com-variance": "varying τ_stance",
        "ride-height": f"τ_stance = {SWEEP_STANCE:g} s, varying ride height",
        "step-height": f"τ_stance = {SWEEP_STANCE:g} s, varying step height",
    }[which]
    fig.suptitle(
        f"Thesis {THESIS_FIGURE[which]}: MPC expert CoM, {stance} "
        f"(seed {settings.seed}, {len(waypoints)} waypoints{', quick' if settings.quick else ''})",
        fontsize=9,
    )
    return fig
