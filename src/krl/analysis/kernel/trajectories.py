"""``trajectories`` (thesis Fig. 4.9): the MPC expert walks to random waypoints (so its commands change);
its labels for the FR foot (swing targets for a swinging leg, realised positions for a standing one: the
kernel's training labels) against kernel-base's prediction from the same inputs; L1 per axis.
"""

from __future__ import annotations

import numpy as np

from krl.analysis.common import FIG_SIZE
from krl.analysis.kernel.context import CSV_DECIMATION, FR, THESIS_FIGURE, FigureRun
from krl.analysis.kernel.metrics import AXES, l1_per_axis
from krl.analysis.kernel.recording import expert_params, kernel_columns, predict_feet, record_expert
from krl.analysis.panels import shade, style
from krl.robots.a1.constants import LEG_NAMES
from krl.task import TARGET_DISTANCE, TARGET_TIME_LIMIT
from krl.util.output import FIG_DPI

TRAJECTORY_TARGETS: int = 3
"""Waypoints the expert walks to in ``trajectories``."""
QUICK_TRAJECTORY_DISTANCE: tuple[float, float] = (1.0, 1.2)
QUICK_TRAJECTORY_TIME_LIMIT: float = 3.0
ZOOM_SECONDS: float = 1.5
"""Length of the zoomed excerpt of ``trajectories`` (centred where the first waypoint is reached)."""

_CSV_COLUMNS: tuple[str, ...] = (
    "time",
    "vx_cmd",
    "vy_cmd",
    "wz_cmd",
    "fr_stance",
    "label_x",
    "label_y",
    "label_z",
    "kernel_x",
    "kernel_y",
    "kernel_z",
)


def trajectories_figure(kernel, run: FigureRun):
    """Fig. 4.9 for kernel-base ``kernel``: the expert's FR labels against the kernel's prediction.

    Returns ``(table, csv columns, csv rows, matplotlib figure)``.
    """
    from krl.task import random_targets

    distance = QUICK_TRAJECTORY_DISTANCE if run.quick else TARGET_DISTANCE
    count = 1 if run.quick else TRAJECTORY_TARGETS
    waypoints = random_targets(np.random.default_rng(run.seed), count, (0.0, 0.0), distance)
    limit = QUICK_TRAJECTORY_TIME_LIMIT if run.quick else TARGET_TIME_LIMIT
    params = expert_params(kernel)
    run.say(f"trajectories: expert walking to {count} waypoint(s) ...")
    rec = record_expert(params, run.seed, targets=waypoints, time_limit=limit)
    columns = kernel_columns(rec["command"], rec["normalised"], params.step_height, params.ride_height)
    prediction = predict_feet(kernel, columns)
    l1 = _l1_metrics(prediction, rec["labels"], ~rec["stance"][:, FR])
    table = _table(kernel, run, params, waypoints, rec, l1)
    title = (
        f"Thesis {THESIS_FIGURE['trajectories']}: FR foot, MPC expert labels vs kernel-base, "
        f"τ_stance {params.stance_duration:g} s, {count} waypoint(s), seed {run.seed}"
        f"{', quick' if run.quick else ''}\nL1 FR x/y/z = {1e3 * l1['l1_fr']['x']:.2f} / "
        f"{1e3 * l1['l1_fr']['y']:.2f} / {1e3 * l1['l1_fr']['z']:.2f} mm; "
        f"all legs {1e3 * l1['l1_all_legs']['mean']:.2f} mm"
    )
    return table, _CSV_COLUMNS, _csv_rows(rec, prediction), _draw(rec, prediction, title)


def _l1_metrics(prediction: np.ndarray, labels: np.ndarray, swing: np.ndarray) -> dict:
    """The L1 errors of ``prediction`` against ``labels`` (both (N, 4, 3)): ``l1_fr`` (per axis), split by
    the FR foot's ``swing`` (N,) into ``l1_fr_swing`` and ``l1_fr_stance`` (None without samples),
    ``l1_all_legs`` (per axis) and ``l1_per_leg`` (the mean per leg name)."""
    return {
        "l1_fr": l1_per_axis(prediction[:, FR], labels[:, FR]),
        "l1_fr_swing": l1_per_axis(prediction[swing, FR], labels[swing, FR]) if swing.any() else None,
        "l1_fr_stance": l1_per_axis(prediction[~swing, FR], labels[~swing, FR]) if (~swing).any() else None,
        "l1_all_legs": l1_per_axis(prediction, labels),
        "l1_per_leg": {
            leg: l1_per_axis(prediction[:, i], labels[:, i])["mean"] for i, leg in enumerate(LEG_NAMES)
        },
    }


def _table(kernel, run: FigureRun, params, waypoints: np.ndarray, rec: dict, l1: dict) -> dict:
    """The JSON table: the run's settings and outcome, and the :func:`_l1_metrics` ``l1``."""
    t = rec["time"]
    return {
        "figure": "trajectories",
        "thesis_figure": THESIS_FIGURE["trajectories"],
        "seed": run.seed,
        "quick": run.quick,
        "expert": {
            "gait": params.gait,
            "stance_duration": params.stance_duration,
            "step_height": params.step_height,
            "ride_height": params.ride_height,
        },
        "waypoints": waypoints.tolist(),
        "targets_reached": rec["targets_reached"],
        "reached_at": rec["reached_at"],
        "fell": rec["fell"],
        "timed_out": rec["timed_out"],
        "error": rec["error"],
        "steps": len(t),
        "sim_seconds": float(t[-1]) if len(t) else 0.0,
        "metric": (
            "labels = the expert's swing targets for legs in swing and the realised foot positions after the "
            "control step for legs in stance (krl.kernel.features.labels_from_columns); prediction = "
            "kernel.predict on the same inputs (commands and normalised phases the expert's action used); "
            "L1 = mean |prediction − label| [m] over every control step of the run, per axis and overall"
        ),
        **l1,
        "command_range": {
            name: [float(rec["command"][:, i].min()), float(rec["command"][:, i].max())]
            for i, name in enumerate(("vx", "vy", "wz"))
        }
        if len(t)
        else None,
        "kernel_val_l1": kernel.metadata.get("val_l1"),
    }


def _csv_rows(rec: dict, prediction: np.ndarray) -> list[dict]:
    """The CSV rows: every :data:`CSV_DECIMATION`-th control step's commands, FR stance flag, FR label and
    FR prediction."""
    rows = []
    for k in range(0, len(rec["time"]), CSV_DECIMATION):
        row = {
            "time": rec["time"][k],
            "vx_cmd": rec["command"][k, 0],
            "vy_cmd": rec["command"][k, 1],
            "wz_cmd": rec["command"][k, 2],
            "fr_stance": bool(rec["stance"][k, FR]),
        }
        for i, axis in enumerate(AXES):
            row[f"label_{axis}"] = rec["labels"][k, FR, i]
            row[f"kernel_{axis}"] = prediction[k, FR, i]
        rows.append(row)
    return rows


def _draw(rec: dict, prediction: np.ndarray, title: str):
    """The figure: the whole walk on the left, a :data:`ZOOM_SECONDS` excerpt around the first waypoint
    reached (or the middle) on the right; FR x, y, z and the commands, the waypoints reached dotted."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=FIG_SIZE, dpi=FIG_DPI, layout="constrained")
    axes = fig.subplots(4, 2, sharex="col")
    t = rec["time"]
    centre = rec["reached_at"][0] if rec["reached_at"] else (t[-1] / 2 if len(t) else 0.0)
    start = max(0.0, min(centre - ZOOM_SECONDS / 2, (t[-1] if len(t) else 0.0) - ZOOM_SECONDS))
    zoom = (t >= start) & (t <= start + ZOOM_SECONDS)
    in_zoom = [r for r in rec["reached_at"] if start <= r <= start + ZOOM_SECONDS]
    _draw_column(axes[:, 0], rec, prediction, np.ones(len(t), bool), rec["reached_at"], zoomed=False)
    _draw_column(axes[:, 1], rec, prediction, zoom, in_zoom, zoomed=True)
    axes[0, 0].set_title("whole walk (dotted: waypoint reached)")
    axes[0, 1].set_title(f"{ZOOM_SECONDS:g} s excerpt (shaded: FR swing)")
    axes[0, 1].legend(fontsize=6, loc="upper right")
    axes[3, 0].legend(fontsize=6, loc="lower right", ncol=3)
    fig.suptitle(title, fontsize=9)
    return fig


def _draw_column(column, rec: dict, prediction: np.ndarray, pick: np.ndarray, marks: list, zoomed: bool):
    """One ``column`` of axes over the steps ``pick``: the FR label against the prediction per axis (the FR
    swing shaded and the lines thicker when ``zoomed``), the commands below, a dotted line at each time of
    ``marks``."""
    tt = rec["time"][pick]
    lw = 0.9 if zoomed else 0.5
    for row, axis in enumerate(AXES):
        ax = column[row]
        if zoomed:
            shade(ax, tt, ~rec["stance"][pick, FR], label="FR swing")
        ax.plot(tt, rec["labels"][pick, FR, row], color="k", lw=lw, label="MPC expert label")
        ax.plot(tt, prediction[pick, FR, row], color="C1", lw=lw, ls="--", label="kernel-base prediction")
        ax.set(ylabel=f"FR {axis} [m]")
        style(ax)
    ax = column[3]
    ax.plot(tt, rec["command"][pick, 0], color="C0", lw=0.9, label="v_x [m/s]")
    ax.plot(tt, rec["command"][pick, 1], color="C2", lw=0.9, label="v_y [m/s]")
    ax.plot(tt, rec["command"][pick, 2], color="C3", lw=0.9, label="ω_z [rad/s]")
    for reached_at in marks:
        for a in column:
            a.axvline(reached_at, color="0.5", lw=0.6, ls=":")
    ax.set(xlabel="time [s]", ylabel="command")
    style(ax)
