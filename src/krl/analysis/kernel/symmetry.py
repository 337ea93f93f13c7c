"""``symmetry`` (thesis Fig. 4.11): FR against RL over a cycle at vx = 0 and 0.3 m/s, kernel and expert."""

from __future__ import annotations

import numpy as np

from krl.analysis.common import FIG_SIZE, QUICK_DURATION
from krl.analysis.kernel.context import FR, RL, THESIS_FIGURE, FigureRun
from krl.analysis.kernel.metrics import AXES, CYCLE_POINTS, fold_cycle, symmetry_metrics
from krl.analysis.kernel.recording import (
    HOLD_DURATION,
    cycle_inputs,
    expert_params,
    kernel_columns,
    predict_feet,
    record_expert,
)
from krl.analysis.panels import shade, style
from krl.task.runner import HOLD_RAMP, HOLD_SETTLE
from krl.util.output import FIG_DPI
from krl.util.timing import CONTROL_DT

SYMMETRY_SPEEDS: tuple[float, ...] = (0.0, 0.3)
"""Frontal velocities of Fig. 4.11 [m/s]."""

_CSV_COLUMNS: tuple[str, ...] = (
    "source",
    "vx",
    "y_asym",
    "y_asym_rel",
    "y_corr",
    "y_rms_fr",
    "y_rms_rl",
    "y_offset_sum",
    "x_mismatch",
    "z_mismatch",
)


def symmetry_figure(kernel, run: FigureRun):
    """Fig. 4.11 for kernel-base ``kernel``, beside the expert holding each speed.

    Returns ``(table, csv columns, csv rows, matplotlib figure)``.
    """
    params = expert_params(kernel)
    cycle = cycle_inputs(params.gait, params.stance_duration)
    duration = QUICK_DURATION if run.quick else HOLD_DURATION
    steady = HOLD_RAMP + HOLD_SETTLE
    results, rows = {}, []
    for speed in SYMMETRY_SPEEDS:
        results[speed], kernel_row, expert_row = _measure(kernel, params, cycle, speed, duration, run)
        rows += [kernel_row, expert_row]
    table = {
        "figure": "symmetry",
        "thesis_figure": THESIS_FIGURE["symmetry"],
        "seed": run.seed,
        "quick": run.quick,
        "gait": params.gait,
        "stance_duration": params.stance_duration,
        "expert_hold_seconds": duration,
        "expert_measured_from": steady,
        "metric": (
            "one cycle per leg, each leg's mean over the cycle removed (normalised); kernel: kernel-base at "
            f"φ_FR = j/{CYCLE_POINTS}, command (vx, 0, 0); expert: its labels while holding (vx, 0, 0), "
            f"from t = {steady:g} s, averaged in {CYCLE_POINTS} bins of φ_FR; y_asym = RMS(ỹ_FR + ỹ_RL) [m] "
            "(0 = the RL lateral trajectory is the exact inverse of FR's, the thesis's symmetry); "
            "y_asym_rel = y_asym / sqrt((rms ỹ_FR² + rms ỹ_RL²)/2); "
            "y_corr = correlation of ỹ_FR and ỹ_RL (−1 symmetric); "
            "y_offset_sum = mean y_FR + mean y_RL [m]; x_mismatch, z_mismatch = RMS(x̃_FR − x̃_RL), "
            "RMS(z̃_FR − z̃_RL) [m] (0 = aligned)"
        ),
        "conditions": rows,
    }
    return table, _CSV_COLUMNS, rows, _draw(cycle, results, rows)


def _measure(kernel, params, cycle: dict, speed: float, duration: float, run: FigureRun):
    """The kernel's feet over ``cycle`` at vx = ``speed`` and the expert's labels while it holds that speed
    for ``duration`` [s], folded over its FR phase from the steady part on.

    Returns ``(curves, kernel row, expert row)``: the curves ``kernel`` (CYCLE_POINTS, 4, 3), ``expert_phase``
    and ``expert`` (the folded bins with samples in every leg and axis); the rows are the CSV rows with the
    symmetry metrics (the expert's without metrics when under two bins).
    """
    command = np.array([speed, 0.0, 0.0])
    feet = predict_feet(kernel, kernel_columns(np.tile(command, (CYCLE_POINTS, 1)), cycle["normalised"]))
    run.say(f"symmetry: expert holding vx = {speed:g} m/s for {duration:g} s ...")
    rec = record_expert(params, run.seed, command=command, duration=duration)
    keep = rec["time"] > HOLD_RAMP + HOLD_SETTLE
    centres, folded = fold_cycle(rec["phases"][keep, FR], rec["labels"][keep])
    valid = np.isfinite(folded).all(axis=(1, 2))
    kernel_m = symmetry_metrics(feet[:, FR], feet[:, RL])
    expert_m = symmetry_metrics(folded[valid, FR], folded[valid, RL]) if valid.sum() >= 2 else None
    curves = {"kernel": feet, "expert_phase": centres[valid], "expert": folded[valid]}
    expert_row = {
        "source": "MPC expert",
        "vx": speed,
        "fell": rec["fell"],
        "cycles": int(keep.sum() * CONTROL_DT / cycle["step_duration"]),
        **(expert_m or {}),
    }
    return curves, {"source": "kernel-base", "vx": speed, **kernel_m}, expert_row


def _draw(cycle: dict, results: dict, rows: list):
    """The figure: a row per speed, a column per axis, FR against RL (−RL for y) for kernel and expert."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=FIG_SIZE, dpi=FIG_DPI, layout="constrained")
    axes = fig.subplots(len(SYMMETRY_SPEEDS), 3, sharex=True)
    for r, speed in enumerate(SYMMETRY_SPEEDS):
        km = next(x for x in rows if x["source"] == "kernel-base" and x["vx"] == speed)
        em = next(x for x in rows if x["source"] == "MPC expert" and x["vx"] == speed)
        curves = _normalised(results[speed])
        for c, axis in enumerate(AXES):
            _draw_panel(axes[r, c], c, axis, cycle, results[speed]["expert_phase"], curves)
            _annotate(axes[r, c], axis, speed, km, em)
    for ax in axes[-1]:
        ax.set_xlabel("FR phase φ_FR [cycles] (shaded: swing)")
    fig.suptitle(
        f"Thesis {THESIS_FIGURE['symmetry']}: normalised FR and RL trajectories (cycle mean removed), "
        "kernel-base (solid) and MPC expert labels (dotted)\nsymmetric trot: y_FR = −y_RL, x and z aligned",
        fontsize=9,
    )
    return fig


def _normalised(result: dict) -> tuple:
    """``(kernel FR, kernel RL, expert FR, expert RL)`` of one speed's curves (:func:`_measure`), each less
    its mean over the cycle; the expert's are None without folded bins."""
    kfr, krl = result["kernel"][:, FR], result["kernel"][:, RL]
    kfr, krl = kfr - kfr.mean(0), krl - krl.mean(0)
    expert = result["expert"]
    efr = expert[:, FR] - expert[:, FR].mean(0) if len(expert) else None
    erl = expert[:, RL] - expert[:, RL].mean(0) if len(expert) else None
    return kfr, krl, efr, erl


def _draw_panel(ax, c: int, axis: str, cycle: dict, expert_phase: np.ndarray, curves: tuple) -> None:
    """FR against RL (−RL for y) along ``axis`` (column ``c`` of the :func:`_normalised` ``curves``) [mm],
    kernel solid and expert dotted, over the cycle with the swing shaded."""
    kfr, krl, efr, erl = curves
    shade(ax, cycle["phase"], ~cycle["stance"])
    sign, rl_name = (-1.0, "−RL") if axis == "y" else (1.0, "RL")
    ax.plot(cycle["phase"], 1e3 * kfr[:, c], color="C0", lw=1.3, label="kernel FR")
    ax.plot(cycle["phase"], 1e3 * sign * krl[:, c], color="C3", lw=1.3, label=f"kernel {rl_name}")
    if efr is not None:
        ax.plot(expert_phase, 1e3 * efr[:, c], color="C0", lw=0.8, ls=":", label="expert FR")
        ax.plot(expert_phase, 1e3 * sign * erl[:, c], color="C3", lw=0.8, ls=":", label=f"expert {rl_name}")


def _annotate(ax, axis: str, speed: float, kernel_row: dict, expert_row: dict) -> None:
    """Title the panel of ``axis`` at vx = ``speed`` with its metric (y_asym for y, the mismatch for x and
    z) for kernel and expert from their CSV rows; label, style and add the legend."""
    if axis == "y":
        key, what = "y_asym", "FR and −RL; y_asym"
    else:
        key, what = f"{axis}_mismatch", f"FR and RL; {axis}_mismatch"
    expert_text = f"{1e3 * expert_row[key]:.1f}" if key in expert_row else "n/a"
    ax.set_title(
        f"v_x = {speed:g} m/s, {what}\nkernel {1e3 * kernel_row[key]:.1f} mm, expert {expert_text} mm"
    )
    ax.set(ylabel=f"{axis} − cycle mean [mm]")
    style(ax, 6)
    ax.legend(fontsize=5, loc="best")
