"""``walk-gait`` (thesis Fig. 4.12): kernel-base (and kernel-ind, given a file) fed the walk gait's phases,
against the MPC expert walking with that gait.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from krl.analysis.common import FIG_SIZE, QUICK_DURATION
from krl.analysis.kernel.context import CSV_DECIMATION, FR, THESIS_FIGURE, FigureRun
from krl.analysis.kernel.metrics import AXES, LIFT_THRESHOLD, l1_per_axis, stance_lift_metrics
from krl.analysis.kernel.recording import (
    HOLD_DURATION,
    expert_params,
    kernel_columns,
    predict_feet,
    record_expert,
)
from krl.analysis.panels import shade, style
from krl.task.runner import HOLD_RAMP, HOLD_SETTLE
from krl.util.output import FIG_DPI

WALK_COMMAND: tuple[float, float, float] = (0.3, 0.0, 0.0)
"""Command of ``walk-gait`` (the thesis does not say; a forward walk inside the training range)."""
WALK_STANCE: float = 0.2
"""τ_stance of the walk gait fed to the kernels (Table 4.1 walk with the kernel's τ_stance)."""
EXCERPT_CYCLES: int = 4
"""Walk cycles drawn in ``walk-gait``."""


def walk_gait_figure(kernel, ind_kernel, run: FigureRun):
    """Fig. 4.12 for kernel-base ``kernel`` and, unless None, kernel-ind ``ind_kernel``.

    Returns ``(table, csv columns, csv rows, matplotlib figure)``.
    """
    from krl.control.gait import gait_params

    params = expert_params(kernel, gait="walk", stance_duration=WALK_STANCE)
    walk = gait_params("walk", stance_duration=WALK_STANCE)
    duration = QUICK_DURATION if run.quick else HOLD_DURATION
    steady = HOLD_RAMP + HOLD_SETTLE
    run.say(f"walk-gait: expert (walk gait) holding {WALK_COMMAND} for {duration:g} s ...")
    rec = record_expert(params, run.seed, command=np.array(WALK_COMMAND), duration=duration)
    columns = kernel_columns(rec["command"], rec["normalised"], params.step_height, params.ride_height)
    models = {"kernel-base": predict_feet(kernel, columns)}
    if ind_kernel is not None:
        models["kernel-ind"] = predict_feet(ind_kernel, columns)
    results = _results(models, rec, rec["time"] > steady)
    table = {
        "figure": "walk-gait",
        "thesis_figure": THESIS_FIGURE["walk-gait"],
        "seed": run.seed,
        "quick": run.quick,
        "gait": {
            "name": "walk",
            "initial_phases": list(walk.initial_phases),
            "swing_ratio": walk.swing_ratio,
            "stance_duration": walk.stance_duration,
            "step_duration": walk.step_duration,
        },
        "command": list(WALK_COMMAND),
        "hold_seconds": duration,
        "measured_from": steady,
        "expert_fell": rec["fell"],
        "expert_error": rec["error"],
        "kernel_ind": ind_kernel is not None,
        "metric": (
            "the MPC expert walks with the walk gait (Table 4.1, τ_stance 0.2 s) holding the command; its "
            "inputs (command, walk-gait |φ| of the four legs) are fed to each kernel; labels as in training "
            f"(swing targets / realised stance positions); from t = {steady:g} s: L1 per axis [m] (FR, all "
            f"legs); phantom_lift_fraction = fraction of FR stance samples with predicted z > label + "
            f"{LIFT_THRESHOLD:g} m; missed_swing_fraction = fraction of the FR swing samples where the label "
            f"is > {LIFT_THRESHOLD:g} m above its stance level but the prediction is not; stance_z_l1, "
            "swing_z_l1 = mean |z error| over FR stance / swing samples [m]"
        ),
        "results": results,
    }
    csv_columns, rows = _csv(rec, models)
    return table, csv_columns, rows, _draw(rec, models, results, walk)


def _results(models: dict[str, np.ndarray], rec: dict, keep: np.ndarray) -> dict[str, dict]:
    """Per model (name: predicted feet (N, 4, 3)), over the steps ``keep``: L1 per axis of the FR foot and
    of all legs against the labels of ``rec``, and the FR stance/lift metrics."""
    labels = rec["labels"]
    stance = rec["stance"][:, FR]
    return {
        name: {
            "l1_fr": l1_per_axis(prediction[keep, FR], labels[keep, FR]),
            "l1_all_legs": l1_per_axis(prediction[keep], labels[keep]),
            **stance_lift_metrics(prediction[keep, FR, 2], labels[keep, FR, 2], stance[keep]),
        }
        for name, prediction in models.items()
    }


def _csv(rec: dict, models: dict[str, np.ndarray]) -> tuple[tuple[str, ...], list[dict]]:
    """The CSV columns and rows: every :data:`CSV_DECIMATION`-th control step's FR stance flag, FR label and
    each model's FR prediction (columns ``base_x``, ``ind_x``, ...)."""
    t, labels, stance = rec["time"], rec["labels"], rec["stance"][:, FR]
    columns = (
        "time",
        "fr_stance",
        "label_x",
        "label_y",
        "label_z",
        *(f"{m.split('-')[1]}_{a}" for m in models for a in AXES),
    )
    rows = []
    for k in range(0, len(t), CSV_DECIMATION):
        row: dict[str, Any] = {"time": t[k], "fr_stance": bool(stance[k])}
        for i, axis in enumerate(AXES):
            row[f"label_{axis}"] = labels[k, FR, i]
            for name, prediction in models.items():
                row[f"{name.split('-')[1]}_{axis}"] = prediction[k, FR, i]
        rows.append(row)
    return columns, rows


def _draw(rec: dict, models: dict[str, np.ndarray], results: dict, walk):
    """The figure: FR x, y, z over the last :data:`EXCERPT_CYCLES` cycles of the ``walk`` gait, the expert's
    label against each model's prediction, the FR swing shaded."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=FIG_SIZE, dpi=FIG_DPI, layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    t, stance = rec["time"], rec["stance"][:, FR]
    start = (t[-1] if len(t) else 0.0) - EXCERPT_CYCLES * walk.step_duration
    pick = t >= start
    colors = {"kernel-base": "C1", "kernel-ind": "C2"}
    for i, (ax, axis) in enumerate(zip(axes, AXES, strict=True)):
        shade(ax, t[pick], ~stance[pick], label="FR swing (walk gait)")
        ax.plot(t[pick], rec["labels"][pick, FR, i], color="k", lw=1.2, label="MPC expert label (walk gait)")
        for name, prediction in models.items():
            l1 = results[name]["l1_fr"][axis]
            label = f"{name} (L1 {1e3 * l1:.1f} mm)"
            ax.plot(t[pick], prediction[pick, FR, i], color=colors[name], lw=1.1, ls="--", label=label)
        ax.set(ylabel=f"FR {axis} [m]")
        ax.set_title(f"({'abc'[i]}) {axis}", loc="left")
        style(ax)
        ax.legend(fontsize=6, loc="upper left", ncol=len(models) + 2)
    axes[-1].set_xlabel("time [s]")
    note = "" if "kernel-ind" in models else " (no kernel-ind file given)"
    fig.suptitle(
        f"Thesis {THESIS_FIGURE['walk-gait']}: FR foot with the walk gait's phases "
        f"(r_swing {walk.swing_ratio:g}, τ_stance {WALK_STANCE:g} s), command v_x = {WALK_COMMAND[0]:g} m/s"
        f"\nkernels vs the MPC expert walking with that gait{note}; last {EXCERPT_CYCLES} cycles",
        fontsize=9,
    )
    return fig
