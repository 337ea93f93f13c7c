"""The kernel's analysis figures (thesis Section 4.2.6.3-4.2.7): ``krl kernel figures WHICH --out DIR``.

``WHICH`` is one of (``docs/kernel_figures.md`` has every definition and the results):

- ``trajectories`` (Fig. 4.9): the MPC expert walks to random waypoints (so its commands change); its
  labels for the FR foot (swing targets for a swinging leg, realised positions for a standing one: the
  kernel's training labels) against kernel-base's prediction from the same inputs; L1 per axis.
- ``command-sweep`` (Fig. 4.10): kernel-base's FR foot over one trot cycle while one command (frontal
  0..1 m/s, lateral -0.5..0.5 m/s, yaw -1..1 rad/s) varies and the others are zero.
- ``symmetry`` (Fig. 4.11): FR against RL over a cycle at vx = 0 and 0.3 m/s, kernel and expert.
- ``walk-gait`` (Fig. 4.12): kernel-base (and kernel-ind, given a file) fed the walk gait's phases,
  against the MPC expert walking with that gait.
- ``heights`` (Fig. 4.13): kernel-ext's FR z over a cycle for several step and ride heights.
- ``velocity`` (Fig. 4.15, kernel half): realised against commanded velocity with the kernel as the
  controller, beside the expert's numbers read from ``docs/figures/expert/velocity.json``.
- ``all``: the six.

Each figure gives ``NAME.png``, ``NAME.json`` and ``NAME.csv`` in the output folder, each written
atomically (temporary file + ``os.replace``) with the writers of :mod:`krl.output`.
"""

from __future__ import annotations

import json
import math
import os
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from krl.analysis.expert_plots import (
    DEFAULT_DURATION,
    QUICK_DURATION,
    draw_fit_and_axes,
    fit_line,
)
from krl.control.expert import NOMINAL_RIDE_HEIGHT, NOMINAL_STEP_HEIGHT
from krl.output import FIG_DPI, csv_bytes, figure_bytes, json_value, write_atomic
from krl.parallel import run_jobs
from krl.robots.a1.constants import FOOT_RADIUS, LEG_NAMES, NUM_LEGS
from krl.runner import HOLD_RAMP, HOLD_SETTLE, TARGET_DISTANCE, TARGET_TIME_LIMIT
from krl.timing import CONTROL_DT

__all__ = [
    "CHOICES",
    "FIGURES",
    "FigureError",
    "cycle_inputs",
    "fold_cycle",
    "height_metrics",
    "l1_per_axis",
    "make_kernel_figures",
    "predict_feet",
    "stance_lift_metrics",
    "sweep_metrics",
    "symmetry_metrics",
    "velocity_sweep",
]


class FigureError(ValueError):
    """A bad ``krl kernel figures`` argument or a missing/unsuitable kernel file (one-line message)."""


FIGURES: tuple[str, ...] = ("trajectories", "command-sweep", "symmetry", "walk-gait", "heights", "velocity")
"""The figures, in the order ``all`` makes them."""

CHOICES: tuple[str, ...] = (*FIGURES, "all")

THESIS_FIGURE: dict[str, str] = {
    "trajectories": "Fig. 4.9",
    "command-sweep": "Fig. 4.10",
    "symmetry": "Fig. 4.11",
    "walk-gait": "Fig. 4.12",
    "heights": "Fig. 4.13",
    "velocity": "Fig. 4.15 (kernel)",
}

FR, RL = LEG_NAMES.index("FR"), LEG_NAMES.index("RL")
AXES: tuple[str, ...] = ("x", "y", "z")

CYCLE_POINTS: int = 80
"""Samples per gait cycle of the kernel-only sweeps (and bins of the folded expert cycles)."""

TRAJECTORY_TARGETS: int = 3
"""Waypoints the expert walks to in ``trajectories``."""
QUICK_TRAJECTORY_DISTANCE: tuple[float, float] = (1.0, 1.2)
QUICK_TRAJECTORY_TIME_LIMIT: float = 3.0
ZOOM_SECONDS: float = 1.5
"""Length of the zoomed excerpt of ``trajectories`` (centred where the first waypoint is reached)."""
CSV_DECIMATION: int = 2
"""``trajectories.csv`` and ``walk-gait.csv`` keep every this many control steps (100 Hz)."""

VX_SWEEP: tuple[float, float] = (0.0, 1.0)
VY_SWEEP: tuple[float, float] = (-0.5, 0.5)
WZ_SWEEP: tuple[float, float] = (-1.0, 1.0)
SWEEP_VALUES: int = 11
"""Command values per sweep of Fig. 4.10 (steps 0.1 m/s, 0.1 m/s, 0.2 rad/s)."""

SYMMETRY_SPEEDS: tuple[float, ...] = (0.0, 0.3)
"""Frontal velocities of Fig. 4.11 [m/s]."""
HOLD_DURATION: float = 8.0
"""Length of the expert's fixed-command runs of ``symmetry`` and ``walk-gait`` [s]."""

WALK_COMMAND: tuple[float, float, float] = (0.3, 0.0, 0.0)
"""Command of ``walk-gait`` (the thesis does not say; a forward walk inside the training range)."""
WALK_STANCE: float = 0.2
"""τ_stance of the walk gait fed to the kernels (Table 4.1 walk with the kernel's τ_stance)."""
EXCERPT_CYCLES: int = 4
"""Walk cycles drawn in ``walk-gait``."""
LIFT_THRESHOLD: float = 0.02
"""A stance sample counts as a "phantom lift" when the prediction is this much above the label [m]."""

HEIGHTS_COMMAND: tuple[float, float, float] = (0.3, 0.0, 0.0)
"""Command of ``heights`` (the thesis does not say; a forward walk inside the training range)."""
STEP_HEIGHTS: tuple[float, ...] = tuple(float(v) for v in np.round(np.linspace(0.05, 0.18, 6), 3))
RIDE_HEIGHTS: tuple[float, ...] = tuple(float(v) for v in np.round(np.linspace(0.18, 0.28, 6), 3))

VELOCITY_STEP: float = 0.1
"""Spacing of the velocity sweep's commands (as the expert's figure) [m/s or rad/s]."""

FIG_SIZE: tuple[float, float] = (9.0, 6.0)

_NEEDS: dict[str, str] = {"heights": "ext"}
"""The kernel each figure needs (``base`` unless listed)."""


# --- metrics ------------------------------------------------------------------------------------------


def l1_per_axis(prediction: np.ndarray, label: np.ndarray) -> dict[str, float]:
    """Mean absolute error per axis and overall [m]. Shapes: (..., 3) each."""
    prediction, label = np.asarray(prediction, dtype=float), np.asarray(label, dtype=float)
    if prediction.shape != label.shape or prediction.shape[-1] != 3:
        raise ValueError(f"need two (..., 3) arrays of one shape, got {prediction.shape} and {label.shape}")
    error = np.abs(prediction - label).reshape(-1, 3)
    return {
        "x": float(error[:, 0].mean()),
        "y": float(error[:, 1].mean()),
        "z": float(error[:, 2].mean()),
        "mean": float(error.mean()),
    }


def symmetry_metrics(fr: np.ndarray, rl: np.ndarray) -> dict[str, float]:
    """How far the FR and RL trajectories over one cycle are from the trot's diagonal symmetry.

    Each trajectory is first *normalised* by removing its mean over the cycle (its nominal offset):
    ``p̃ = p − mean_t p``. True symmetry (the thesis's definition) means the lateral trajectories are
    each other's inverse, ``ỹ_FR = −ỹ_RL``, while x and z coincide, ``x̃_FR = x̃_RL``, ``z̃_FR = z̃_RL``.

    Args:
        fr, rl: positions over one cycle at the same instants [m]. Shape: (K, 3) each.

    Returns:
        ``y_asym``: RMS over the cycle of ``ỹ_FR + ỹ_RL`` [m] (0 when symmetric); ``y_asym_rel``: that
        divided by the RMS amplitude ``sqrt((rms(ỹ_FR)² + rms(ỹ_RL)²) / 2)`` (0 inverse, √2 for unrelated
        equal-amplitude motions, 2 identical); ``y_corr``: correlation of ``ỹ_FR`` and ``ỹ_RL``
        (−1 when symmetric); ``y_rms_fr``, ``y_rms_rl`` [m]; ``y_offset_sum``: ``mean y_FR + mean y_RL``
        [m] (0 when the feet are placed mirror-symmetrically); ``x_mismatch``, ``z_mismatch``: RMS of
        ``x̃_FR − x̃_RL`` and ``z̃_FR − z̃_RL`` [m].
    """
    fr, rl = np.asarray(fr, dtype=float), np.asarray(rl, dtype=float)
    if fr.shape != rl.shape or fr.ndim != 2 or fr.shape[1] != 3 or len(fr) < 2:
        raise ValueError(f"need two (K >= 2, 3) arrays of one shape, got {fr.shape} and {rl.shape}")
    a, b = fr - fr.mean(axis=0), rl - rl.mean(axis=0)

    def rms(v: np.ndarray) -> float:
        return float(np.sqrt(np.mean(v**2)))

    amplitude = math.sqrt((rms(a[:, 1]) ** 2 + rms(b[:, 1]) ** 2) / 2)
    denominator = rms(a[:, 1]) * rms(b[:, 1])
    return {
        "y_asym": rms(a[:, 1] + b[:, 1]),
        "y_asym_rel": rms(a[:, 1] + b[:, 1]) / amplitude if amplitude > 0 else float("nan"),
        "y_corr": float(np.mean(a[:, 1] * b[:, 1]) / denominator) if denominator > 0 else float("nan"),
        "y_rms_fr": rms(a[:, 1]),
        "y_rms_rl": rms(b[:, 1]),
        "y_offset_sum": float(fr[:, 1].mean() + rl[:, 1].mean()),
        "x_mismatch": rms(a[:, 0] - b[:, 0]),
        "z_mismatch": rms(a[:, 2] - b[:, 2]),
    }


def fold_cycle(
    phase: np.ndarray, values: np.ndarray, bins: int = CYCLE_POINTS
) -> tuple[np.ndarray, np.ndarray]:
    """Average ``values`` over many cycles in ``bins`` equal bins of a leg phase in (0, 1].

    Args:
        phase: phase of each sample [cycles]. Shape: (N,).
        values: the samples. Shape: (N, ...).

    Returns:
        ``(centres, means)``: bin centres ``(j − 0.5) / bins`` and the mean of the samples in each bin
        (NaN for an empty bin). Shapes: (bins,), (bins, ...).
    """
    phase = np.asarray(phase, dtype=float)
    values = np.asarray(values, dtype=float)
    if phase.ndim != 1 or len(values) != len(phase):
        raise ValueError(f"phase must be (N,) and values (N, ...), got {phase.shape} and {values.shape}")
    index = np.clip(np.ceil(phase * bins).astype(int) - 1, 0, bins - 1)
    flat = values.reshape(len(values), -1)
    sums = np.zeros((bins, flat.shape[1]))
    np.add.at(sums, index, flat)
    counts = np.bincount(index, minlength=bins).astype(float)
    with np.errstate(invalid="ignore", divide="ignore"):
        means = sums / counts[:, None]
    centres = (np.arange(bins) + 0.5) / bins
    return centres, means.reshape((bins, *values.shape[1:]))


def sweep_metrics(feet: np.ndarray) -> dict[str, float]:
    """Shape of one foot's trajectory over a cycle: peak-to-peak and mean per axis, z extremes [m].

    Args:
        feet: positions over one cycle [m]. Shape: (K, 3).
    """
    feet = np.asarray(feet, dtype=float)
    out: dict[str, float] = {}
    for i, axis in enumerate(AXES):
        out[f"{axis}_ptp"] = float(np.ptp(feet[:, i]))
        out[f"{axis}_mean"] = float(feet[:, i].mean())
    out["z_min"], out["z_max"] = float(feet[:, 2].min()), float(feet[:, 2].max())
    return out


def stance_lift_metrics(
    z_prediction: np.ndarray, z_label: np.ndarray, stance: np.ndarray, threshold: float = LIFT_THRESHOLD
) -> dict[str, float]:
    """Does a predicted foot lift when it should stand, and stand when it should swing?

    Args:
        z_prediction, z_label: one foot's z over time [m]. Shape: (N,).
        stance: the gait's stance flag of that foot. Shape: (N,), bool.
        threshold: height difference that counts [m].

    Returns:
        ``phantom_lift_fraction``: fraction of stance samples with ``z_pred > z_label + threshold``;
        ``missed_swing_fraction``: fraction of the swing samples in which the label is above its own
        stance level by more than ``threshold`` (the foot is really up) where the prediction is not
        (``z_pred < stance level + threshold``); ``stance_z_l1``, ``swing_z_l1``: mean |error| of z over
        stance and swing samples [m]. The stance level is the median label z over stance samples.
    """
    zp, zl = np.asarray(z_prediction, dtype=float), np.asarray(z_label, dtype=float)
    stance = np.asarray(stance, dtype=bool)
    if not (zp.shape == zl.shape == stance.shape) or zp.ndim != 1:
        raise ValueError(f"need three (N,) arrays, got {zp.shape}, {zl.shape}, {stance.shape}")
    nan = float("nan")
    out = {"phantom_lift_fraction": nan, "missed_swing_fraction": nan, "stance_z_l1": nan, "swing_z_l1": nan}
    if stance.any():
        out["phantom_lift_fraction"] = float(np.mean(zp[stance] > zl[stance] + threshold))
        out["stance_z_l1"] = float(np.abs(zp[stance] - zl[stance]).mean())
        level = float(np.median(zl[stance]))
        up = ~stance & (zl > level + threshold)
        if up.any():
            out["missed_swing_fraction"] = float(np.mean(zp[up] < level + threshold))
    if (~stance).any():
        out["swing_z_l1"] = float(np.abs(zp[~stance] - zl[~stance]).mean())
    return out


def height_metrics(z: np.ndarray, stance: np.ndarray, step_height: float, ride_height: float) -> dict:
    """FR z over a cycle against the expert's set points (:mod:`krl.control.swing`).

    The expert lands a foot at ``−ride_height + FOOT_RADIUS`` (base frame) and lifts it to an apex
    ``step_height`` above that. Returns ``stance_z`` (median z over stance samples), ``apex_z`` (max z),
    ``clearance`` (= apex_z − stance_z), and the expected ``stance_z_expected``, ``apex_z_expected``,
    ``clearance_expected`` (= step_height) [m].
    """
    z, stance = np.asarray(z, dtype=float), np.asarray(stance, dtype=bool)
    stance_z = float(np.median(z[stance])) if stance.any() else float("nan")
    apex = float(z.max())
    ground = -ride_height + FOOT_RADIUS
    return {
        "stance_z": stance_z,
        "apex_z": apex,
        "clearance": apex - stance_z,
        "stance_z_expected": ground,
        "apex_z_expected": ground + step_height,
        "clearance_expected": float(step_height),
    }


# --- kernel inputs --------------------------------------------------------------------------------------


def _columns(
    commands: np.ndarray,
    normalised: np.ndarray,
    step_height: float = NOMINAL_STEP_HEIGHT,
    ride_height: float = NOMINAL_RIDE_HEIGHT,
) -> dict[str, np.ndarray]:
    commands = np.asarray(commands, dtype=float).reshape(-1, 3)
    n = len(commands)
    normalised = np.asarray(normalised, dtype=float).reshape(n, NUM_LEGS)
    return {
        "v_cmd": commands[:, :2],
        "yaw_cmd": commands[:, 2],
        "normalised_phase": normalised,
        "sine_phase": np.sin(normalised * np.pi),
        "step_height": np.full(n, float(step_height)),
        "ride_height": np.full(n, float(ride_height)),
    }


def predict_feet(kernel, columns: dict[str, np.ndarray]) -> np.ndarray:
    """The kernel's four foot positions for dataset-like ``columns`` (base frame [m]). Shape: (N, 4, 3).

    Works for kernel-base, -ind (one row per leg, reassembled) and -ext; the features are built by the
    function that built the training features (:func:`krl.kernel.features.features_from_columns`).
    """
    from krl.kernel.features import features_from_columns

    n = len(columns["yaw_cmd"])
    return kernel.predict(features_from_columns(kernel.variant, columns)).reshape(n, NUM_LEGS, 3)


def cycle_inputs(
    gait: str, stance_duration: float, points: int = CYCLE_POINTS, leg: int = FR
) -> dict[str, np.ndarray]:
    """One gait cycle sampled by the phase of ``leg``: ``φ_leg = j / points``, j = 1..points.

    Returns ``phase`` (that leg's phase, (K,)), ``time`` (time since the gait started at which the leg
    has that phase [s], (K,)), ``phases`` and ``normalised`` (all legs' φ and |φ| (Eq. 4.6), (K, 4)) and
    ``stance`` (the leg's stance flag, (K,)).
    """
    from krl.control.gait import gait_params, leg_phases, normalised_phase

    params = gait_params(gait, stance_duration=stance_duration)
    phase = np.arange(1, points + 1) / points
    t = np.mod(phase - params.initial_phases[leg], 1.0) * params.step_duration
    phases = leg_phases(t, params)
    return {
        "phase": phase,
        "time": t,
        "phases": phases,
        "normalised": normalised_phase(phases, params.swing_ratio),
        "stance": phase > params.swing_ratio,
        "swing_ratio": params.swing_ratio,
        "step_duration": params.step_duration,
    }


# --- the expert's labels ------------------------------------------------------------------------------------


def _expert_params(kernel, **overrides):
    from krl.kernel.registry import training_settings

    return replace(training_settings(kernel).expert, **overrides)


def _command_limits(kernel) -> dict[str, tuple[float, float]]:
    from krl.kernel.registry import training_settings

    command = training_settings(kernel).command
    return {"vx": command.vx_range, "vy": command.vy_range, "wz": command.yaw_rate_range}


def record_expert(
    params, seed: int, targets=None, command=None, duration=HOLD_DURATION, time_limit=TARGET_TIME_LIMIT
):
    """Run the MPC expert (to ``targets`` or holding ``command``) and record every control step.

    Returns arrays ``time`` (gait time [s]), ``command`` (N, 3), ``phases`` and ``normalised`` (N, 4),
    ``stance`` (N, 4), ``labels`` (N, 4, 3: swing targets for swinging legs, positions after the step
    for standing legs, exactly the kernel's training labels), plus ``fell``, ``timed_out``,
    ``targets_reached``, ``reached_at`` (times at which waypoints were reached [s]) and ``error``.
    """
    from krl.control.expert import MPCExpert
    from krl.runner import Runner
    from krl.sim.model import build_model
    from krl.sim.robot import A1Sim

    expert = MPCExpert(params)
    sim = A1Sim(build_model("flat", None, seed))
    rows: dict[str, list] = {k: [] for k in ("time", "command", "phases", "normalised", "stance", "labels")}
    reached: list[float] = []

    def on_step(record) -> None:
        last = expert.last
        rows["time"].append(expert.gait.time)
        rows["command"].append(np.array(record.command, dtype=float))
        rows["phases"].append(expert.gait.phases)
        rows["normalised"].append(expert.gait.normalised_phases)
        rows["stance"].append(last.stance.copy())
        rows["labels"].append(np.where(last.stance[:, None], record.after.foot_pos_base, last.foot_targets))

    runner = Runner(sim, expert, on_step=on_step, on_target=lambda _: reached.append(expert.gait.time))
    out: dict[str, Any] = {"error": None, "fell": False, "timed_out": False, "targets_reached": 0}
    try:
        if targets is not None:
            result = runner.walk_to(np.asarray(targets, dtype=float), target_time_limit=time_limit)
        else:
            result = runner.hold_command(np.asarray(command, dtype=float), duration, ramp=HOLD_RAMP)
        out.update(fell=result.fell, timed_out=result.timed_out, targets_reached=result.targets_reached)
    except RuntimeError as exc:  # MPCError, SimulationUnstableError: keep what was recorded
        out.update(error=f"{type(exc).__name__}: {exc}", fell=True)
    shapes = {
        "time": (0,),
        "command": (0, 3),
        "phases": (0, 4),
        "normalised": (0, 4),
        "stance": (0, 4),
        "labels": (0, 4, 3),
    }
    for key, values in rows.items():
        out[key] = np.array(values) if values else np.zeros(shapes[key])
    out["stance"] = out["stance"].astype(bool)
    out["reached_at"] = reached
    return out


# --- figure builders --------------------------------------------------------------------------------------
# Each returns (table, csv columns, csv rows, matplotlib figure).


@dataclass(frozen=True)
class _Run:
    seed: int
    quick: bool
    workers: int
    progress: bool


def _say(run: _Run, text: str) -> None:
    if run.progress:
        print(text, file=sys.stderr, flush=True)


def _style(ax, fontsize: int = 7) -> None:
    ax.tick_params(labelsize=fontsize)
    ax.title.set_fontsize(fontsize + 1)
    ax.xaxis.label.set_fontsize(fontsize)
    ax.yaxis.label.set_fontsize(fontsize)
    ax.grid(alpha=0.3)


def _shade(ax, t: np.ndarray, mask: np.ndarray, color: str = "0.85", label: str | None = None) -> None:
    """Shade the spans of ``t`` where ``mask`` holds."""
    mask = np.asarray(mask, dtype=bool)
    if not mask.any():
        return
    edges = np.flatnonzero(np.diff(np.concatenate(([0], mask.astype(int), [0]))))
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 0.0
    for k, (start, stop) in enumerate(zip(edges[::2], edges[1::2], strict=True)):
        ax.axvspan(
            t[start] - dt / 2,
            t[stop - 1] + dt / 2,
            color=color,
            lw=0,
            zorder=0,
            label=label if k == 0 else None,
        )


def _trajectories(kernel, run: _Run):
    from krl.runner import random_targets

    distance = QUICK_TRAJECTORY_DISTANCE if run.quick else TARGET_DISTANCE
    count = 1 if run.quick else TRAJECTORY_TARGETS
    waypoints = random_targets(np.random.default_rng(run.seed), count, (0.0, 0.0), distance)
    limit = QUICK_TRAJECTORY_TIME_LIMIT if run.quick else TARGET_TIME_LIMIT
    params = _expert_params(kernel)
    _say(run, f"trajectories: expert walking to {count} waypoint(s) ...")
    rec = record_expert(params, run.seed, targets=waypoints, time_limit=limit)
    columns = _columns(rec["command"], rec["normalised"], params.step_height, params.ride_height)
    prediction = predict_feet(kernel, columns)
    labels = rec["labels"]
    t = rec["time"]
    fr = l1_per_axis(prediction[:, FR], labels[:, FR])
    all_legs = l1_per_axis(prediction, labels)
    per_leg = {leg: l1_per_axis(prediction[:, i], labels[:, i])["mean"] for i, leg in enumerate(LEG_NAMES)}
    swing = ~rec["stance"][:, FR]
    fr_swing = l1_per_axis(prediction[swing, FR], labels[swing, FR]) if swing.any() else None
    fr_stance = l1_per_axis(prediction[~swing, FR], labels[~swing, FR]) if (~swing).any() else None
    table = {
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
        "l1_fr": fr,
        "l1_fr_swing": fr_swing,
        "l1_fr_stance": fr_stance,
        "l1_all_legs": all_legs,
        "l1_per_leg": per_leg,
        "command_range": {
            name: [float(rec["command"][:, i].min()), float(rec["command"][:, i].max())]
            for i, name in enumerate(("vx", "vy", "wz"))
        }
        if len(t)
        else None,
        "kernel_val_l1": kernel.metadata.get("val_l1"),
    }
    csv_columns = (
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
    rows = []
    for k in range(0, len(t), CSV_DECIMATION):
        row = {
            "time": t[k],
            "vx_cmd": rec["command"][k, 0],
            "vy_cmd": rec["command"][k, 1],
            "wz_cmd": rec["command"][k, 2],
            "fr_stance": bool(rec["stance"][k, FR]),
        }
        for i, axis in enumerate(AXES):
            row[f"label_{axis}"] = labels[k, FR, i]
            row[f"kernel_{axis}"] = prediction[k, FR, i]
        rows.append(row)

    from matplotlib.figure import Figure

    fig = Figure(figsize=FIG_SIZE, dpi=FIG_DPI, layout="constrained")
    axes = fig.subplots(4, 2, sharex="col")
    centre = rec["reached_at"][0] if rec["reached_at"] else (t[-1] / 2 if len(t) else 0.0)
    start = max(0.0, min(centre - ZOOM_SECONDS / 2, (t[-1] if len(t) else 0.0) - ZOOM_SECONDS))
    zoom = (t >= start) & (t <= start + ZOOM_SECONDS)
    for col, pick in enumerate((np.ones(len(t), bool), zoom)):
        tt = t[pick]
        for row, axis in enumerate(AXES):
            ax = axes[row, col]
            if col == 1:
                _shade(ax, tt, ~rec["stance"][pick, FR], label="FR swing")
            ax.plot(tt, labels[pick, FR, row], color="k", lw=0.9 if col else 0.5, label="MPC expert label")
            ax.plot(
                tt,
                prediction[pick, FR, row],
                color="C1",
                lw=0.9 if col else 0.5,
                ls="--",
                label="kernel-base prediction",
            )
            ax.set(ylabel=f"FR {axis} [m]")
            _style(ax)
        ax = axes[3, col]
        ax.plot(tt, rec["command"][pick, 0], color="C0", lw=0.9, label="v_x [m/s]")
        ax.plot(tt, rec["command"][pick, 1], color="C2", lw=0.9, label="v_y [m/s]")
        ax.plot(tt, rec["command"][pick, 2], color="C3", lw=0.9, label="ω_z [rad/s]")
        for reached_at in rec["reached_at"]:
            if col == 0 or start <= reached_at <= start + ZOOM_SECONDS:
                for a in axes[:, col]:
                    a.axvline(reached_at, color="0.5", lw=0.6, ls=":")
        ax.set(xlabel="time [s]", ylabel="command")
        _style(ax)
    axes[0, 0].set_title("whole walk (dotted: waypoint reached)")
    axes[0, 1].set_title(f"{ZOOM_SECONDS:g} s excerpt (shaded: FR swing)")
    axes[0, 1].legend(fontsize=6, loc="upper right")
    axes[3, 0].legend(fontsize=6, loc="lower right", ncol=3)
    fig.suptitle(
        f"Thesis {THESIS_FIGURE['trajectories']}: FR foot, MPC expert labels vs kernel-base, "
        f"τ_stance {params.stance_duration:g} s, {count} waypoint(s), seed {run.seed}"
        f"{', quick' if run.quick else ''}\nL1 FR x/y/z = {1e3 * fr['x']:.2f} / {1e3 * fr['y']:.2f} / "
        f"{1e3 * fr['z']:.2f} mm; all legs {1e3 * all_legs['mean']:.2f} mm",
        fontsize=9,
    )
    return table, csv_columns, rows, fig


def _command_grid(name: str, quick: bool) -> np.ndarray:
    low, high = {"vx": VX_SWEEP, "vy": VY_SWEEP, "wz": WZ_SWEEP}[name]
    return np.round(np.linspace(low, high, 3 if quick else SWEEP_VALUES), 6) + 0.0


def _z_spread(curves: list) -> float:
    """max over the cycle of (max − min of z over the curves) [m]; NaN for fewer than two curves."""
    if len(curves) < 2:
        return float("nan")
    z = np.stack([c[2][:, 2] for c in curves])
    return float(np.ptp(z, axis=0).max())


def _command_sweep(kernel, run: _Run):
    import matplotlib as mpl
    from matplotlib.figure import Figure

    stance_duration = _expert_params(kernel).stance_duration
    cycle = cycle_inputs("trot", stance_duration)
    limits = _command_limits(kernel)
    titles = {
        "vx": ("(a) frontal velocity", "v_x", "m/s"),
        "vy": ("(b) lateral velocity", "v_y", "m/s"),
        "wz": ("(c) yaw rate", "ω_z", "rad/s"),
    }
    rows, curves, summary = [], {}, {}
    for index, name in enumerate(("vx", "vy", "wz")):
        curves[name] = []
        for value in _command_grid(name, run.quick):
            command = np.zeros(3)
            command[index] = value
            feet = predict_feet(kernel, _columns(np.tile(command, (CYCLE_POINTS, 1)), cycle["normalised"]))
            fr = feet[:, FR]
            low, high = limits[name]
            inside = bool(low - 1e-9 <= value <= high + 1e-9)
            rows.append(
                {"command": name, "value": float(value), "in_training_range": inside, **sweep_metrics(fr)}
            )
            curves[name].append((float(value), inside, fr))
        inside_rows = [r for r in rows if r["command"] == name and r["in_training_range"]]
        outside_rows = [r for r in rows if r["command"] == name and not r["in_training_range"]]
        entry: dict[str, Any] = {
            "x_ptp_fit_inside": fit_line(
                [r["value"] for r in inside_rows], [r["x_ptp"] for r in inside_rows]
            ),
            "y_ptp_fit_inside": fit_line(
                [r["value"] for r in inside_rows], [r["y_ptp"] for r in inside_rows]
            ),
            "z_ptp_range_inside": [
                min((r["z_ptp"] for r in inside_rows), default=float("nan")),
                max((r["z_ptp"] for r in inside_rows), default=float("nan")),
            ],
            "z_ptp_range_outside": [
                min((r["z_ptp"] for r in outside_rows), default=float("nan")),
                max((r["z_ptp"] for r in outside_rows), default=float("nan")),
            ],
            "z_spread_inside": _z_spread([c for c in curves[name] if c[1]]),
            "z_spread_inside_nonzero": _z_spread([c for c in curves[name] if c[1] and abs(c[0]) > 1e-9]),
            "z_spread_all": _z_spread(curves[name]),
        }
        summary[name] = entry
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
    csv_columns = (
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

    fig = Figure(figsize=FIG_SIZE, dpi=FIG_DPI, layout="constrained")
    axes = fig.subplots(3, 3, sharex=True)
    phase = cycle["phase"]
    for col, name in enumerate(("vx", "vy", "wz")):
        title, symbol, unit = titles[name]
        grid = [c[0] for c in curves[name]]
        norm = mpl.colors.Normalize(min(grid), max(grid))
        cmap = mpl.colormaps["viridis"]
        for row, axis in enumerate(AXES):
            ax = axes[row, col]
            _shade(ax, phase, ~cycle["stance"])
            for value, inside, fr in curves[name]:
                ax.plot(phase, fr[:, row], color=cmap(norm(value)), lw=1.0, ls="-" if inside else "--")
            if col == 0:
                ax.set_ylabel(f"FR {axis} [m]")
            _style(ax)
        axes[0, col].set_title(f"{title} {min(grid):g}…{max(grid):g} {unit}")
        axes[2, col].set_xlabel("FR phase φ_FR [cycles] (shaded: swing)")
        bar = fig.colorbar(
            mpl.cm.ScalarMappable(norm=norm, cmap=cmap),
            ax=axes[:, col],
            location="bottom",
            shrink=0.9,
            aspect=30,
            pad=0.01,
        )
        low, high = limits[name]
        for edge in (low, high):
            if min(grid) <= edge <= max(grid):
                bar.ax.axvline(edge, color="0.35", lw=3.0)
        bar.set_label(f"commanded {symbol} [{unit}]", fontsize=7)
        bar.ax.tick_params(labelsize=7)
    fig.suptitle(
        f"Thesis {THESIS_FIGURE['command-sweep']}: kernel-base FR foot over one trot cycle "
        f"(τ_step {cycle['step_duration']:.3f} s), one command varied, the others zero\n"
        "grey bars on the colour scales: training limits (command generator); dashed curves: outside them",
        fontsize=9,
    )
    return table, csv_columns, rows, fig


def _symmetry(kernel, run: _Run):
    from matplotlib.figure import Figure

    params = _expert_params(kernel)
    cycle = cycle_inputs(params.gait, params.stance_duration)
    duration = QUICK_DURATION if run.quick else HOLD_DURATION
    steady = HOLD_RAMP + HOLD_SETTLE
    results, rows = {}, []
    for speed in SYMMETRY_SPEEDS:
        command = np.array([speed, 0.0, 0.0])
        feet = predict_feet(kernel, _columns(np.tile(command, (CYCLE_POINTS, 1)), cycle["normalised"]))
        _say(run, f"symmetry: expert holding vx = {speed:g} m/s for {duration:g} s ...")
        rec = record_expert(params, run.seed, command=command, duration=duration)
        keep = rec["time"] > steady
        centres, folded = fold_cycle(rec["phases"][keep, FR], rec["labels"][keep])
        valid = np.isfinite(folded).all(axis=(1, 2))
        kernel_m = symmetry_metrics(feet[:, FR], feet[:, RL])
        expert_m = symmetry_metrics(folded[valid, FR], folded[valid, RL]) if valid.sum() >= 2 else None
        results[speed] = {
            "kernel": feet,
            "expert_phase": centres[valid],
            "expert": folded[valid],
            "fell": rec["fell"],
        }
        rows.append({"source": "kernel-base", "vx": speed, **kernel_m})
        rows.append(
            {
                "source": "MPC expert",
                "vx": speed,
                "fell": rec["fell"],
                "cycles": int(keep.sum() * CONTROL_DT / cycle["step_duration"]),
                **(expert_m or {}),
            }
        )
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
    csv_columns = (
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

    fig = Figure(figsize=FIG_SIZE, dpi=FIG_DPI, layout="constrained")
    axes = fig.subplots(len(SYMMETRY_SPEEDS), 3, sharex=True)
    for r, speed in enumerate(SYMMETRY_SPEEDS):
        res = results[speed]
        kfr, krl = res["kernel"][:, FR], res["kernel"][:, RL]
        kfr, krl = kfr - kfr.mean(0), krl - krl.mean(0)
        efr = res["expert"][:, FR] - res["expert"][:, FR].mean(0) if len(res["expert"]) else None
        erl = res["expert"][:, RL] - res["expert"][:, RL].mean(0) if len(res["expert"]) else None
        km = next(x for x in rows if x["source"] == "kernel-base" and x["vx"] == speed)
        em = next(x for x in rows if x["source"] == "MPC expert" and x["vx"] == speed)
        for c, axis in enumerate(AXES):
            ax = axes[r, c]
            _shade(ax, cycle["phase"], ~cycle["stance"])
            sign, rl_name = (-1.0, "−RL") if axis == "y" else (1.0, "RL")
            ax.plot(cycle["phase"], 1e3 * kfr[:, c], color="C0", lw=1.3, label="kernel FR")
            ax.plot(cycle["phase"], 1e3 * sign * krl[:, c], color="C3", lw=1.3, label=f"kernel {rl_name}")
            if efr is not None:
                ax.plot(
                    res["expert_phase"],
                    1e3 * efr[:, c],
                    color="C0",
                    lw=0.8,
                    ls=":",
                    label="expert FR",
                )
                ax.plot(
                    res["expert_phase"],
                    1e3 * sign * erl[:, c],
                    color="C3",
                    lw=0.8,
                    ls=":",
                    label=f"expert {rl_name}",
                )
            if axis == "y":
                key, what = "y_asym", "FR and −RL; y_asym"
            else:
                key, what = f"{axis}_mismatch", f"FR and RL; {axis}_mismatch"
            expert_text = f"{1e3 * em[key]:.1f}" if key in em else "n/a"
            ax.set_title(
                f"v_x = {speed:g} m/s, {what}\nkernel {1e3 * km[key]:.1f} mm, expert {expert_text} mm"
            )
            ax.set(ylabel=f"{axis} − cycle mean [mm]")
            _style(ax, 6)
            ax.legend(fontsize=5, loc="best")
        for ax in axes[-1]:
            ax.set_xlabel("FR phase φ_FR [cycles] (shaded: swing)")
    fig.suptitle(
        f"Thesis {THESIS_FIGURE['symmetry']}: normalised FR and RL trajectories (cycle mean removed), "
        "kernel-base (solid) and MPC expert labels (dotted)\nsymmetric trot: y_FR = −y_RL, x and z aligned",
        fontsize=9,
    )
    return table, csv_columns, rows, fig


def _walk_gait(kernel, ind_kernel, run: _Run):
    from matplotlib.figure import Figure

    from krl.control.gait import gait_params

    params = _expert_params(kernel, gait="walk", stance_duration=WALK_STANCE)
    walk = gait_params("walk", stance_duration=WALK_STANCE)
    duration = QUICK_DURATION if run.quick else HOLD_DURATION
    steady = HOLD_RAMP + HOLD_SETTLE
    _say(run, f"walk-gait: expert (walk gait) holding {WALK_COMMAND} for {duration:g} s ...")
    rec = record_expert(params, run.seed, command=np.array(WALK_COMMAND), duration=duration)
    keep = rec["time"] > steady
    columns = _columns(rec["command"], rec["normalised"], params.step_height, params.ride_height)
    models = {"kernel-base": predict_feet(kernel, columns)}
    if ind_kernel is not None:
        models["kernel-ind"] = predict_feet(ind_kernel, columns)
    labels = rec["labels"]
    stance = rec["stance"][:, FR]
    results = {}
    for name, prediction in models.items():
        results[name] = {
            "l1_fr": l1_per_axis(prediction[keep, FR], labels[keep, FR]),
            "l1_all_legs": l1_per_axis(prediction[keep], labels[keep]),
            **stance_lift_metrics(prediction[keep, FR, 2], labels[keep, FR, 2], stance[keep]),
        }
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
    t = rec["time"]
    csv_columns = (
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

    fig = Figure(figsize=FIG_SIZE, dpi=FIG_DPI, layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    start = (t[-1] if len(t) else 0.0) - EXCERPT_CYCLES * walk.step_duration
    pick = t >= start
    colors = {"kernel-base": "C1", "kernel-ind": "C2"}
    for i, (ax, axis) in enumerate(zip(axes, AXES, strict=True)):
        _shade(ax, t[pick], ~stance[pick], label="FR swing (walk gait)")
        ax.plot(t[pick], labels[pick, FR, i], color="k", lw=1.2, label="MPC expert label (walk gait)")
        for name, prediction in models.items():
            l1 = results[name]["l1_fr"][axis]
            ax.plot(
                t[pick],
                prediction[pick, FR, i],
                color=colors[name],
                lw=1.1,
                ls="--",
                label=f"{name} (L1 {1e3 * l1:.1f} mm)",
            )
        ax.set(ylabel=f"FR {axis} [m]")
        ax.set_title(f"({'abc'[i]}) {axis}", loc="left")
        _style(ax)
        ax.legend(fontsize=6, loc="upper left", ncol=len(models) + 2)
    axes[-1].set_xlabel("time [s]")
    note = "" if ind_kernel is not None else " (no kernel-ind file given)"
    fig.suptitle(
        f"Thesis {THESIS_FIGURE['walk-gait']}: FR foot with the walk gait's phases "
        f"(r_swing {walk.swing_ratio:g}, τ_stance {WALK_STANCE:g} s), command v_x = {WALK_COMMAND[0]:g} m/s"
        f"\nkernels vs the MPC expert walking with that gait{note}; last {EXCERPT_CYCLES} cycles",
        fontsize=9,
    )
    return table, csv_columns, rows, fig


def _heights(ext_kernel, run: _Run):
    import matplotlib as mpl
    from matplotlib.figure import Figure

    stance_duration = _expert_params(ext_kernel).stance_duration
    cycle = cycle_inputs("trot", stance_duration)
    command = np.tile(np.array(HEIGHTS_COMMAND), (CYCLE_POINTS, 1))
    sweeps = {
        "step_height": [(h, NOMINAL_RIDE_HEIGHT) for h in STEP_HEIGHTS],
        "ride_height": [(NOMINAL_STEP_HEIGHT, h) for h in RIDE_HEIGHTS],
    }
    if run.quick:
        sweeps = {key: values[:: len(values) - 1] for key, values in sweeps.items()}
    rows, curves = [], {}
    for name, settings in sweeps.items():
        curves[name] = []
        for step, ride in settings:
            z = predict_feet(ext_kernel, _columns(command, cycle["normalised"], step, ride))[:, FR, 2]
            rows.append(
                {
                    "sweep": name,
                    "step_height": step,
                    "ride_height": ride,
                    **height_metrics(z, cycle["stance"], step, ride),
                }
            )
            curves[name].append((step, ride, z))
    step_rows = [r for r in rows if r["sweep"] == "step_height"]
    ride_rows = [r for r in rows if r["sweep"] == "ride_height"]
    fits = {
        "clearance_vs_step_height": fit_line(
            [r["step_height"] for r in step_rows], [r["clearance"] for r in step_rows]
        ),
        "apex_vs_step_height": fit_line(
            [r["step_height"] for r in step_rows], [r["apex_z"] for r in step_rows]
        ),
        "stance_z_vs_ride_height": fit_line(
            [r["ride_height"] for r in ride_rows], [r["stance_z"] for r in ride_rows]
        ),
        "apex_vs_ride_height": fit_line(
            [r["ride_height"] for r in ride_rows], [r["apex_z"] for r in ride_rows]
        ),
    }
    table = {
        "figure": "heights",
        "thesis_figure": THESIS_FIGURE["heights"],
        "quick": run.quick,
        "command": list(HEIGHTS_COMMAND),
        "stance_duration": stance_duration,
        "training_ranges": {"step_height": [0.05, 0.18], "ride_height": [0.18, 0.28]},
        "metric": (
            f"kernel-ext FR z (base frame) over one trot cycle at φ_FR = j/{CYCLE_POINTS}, command "
            f"{HEIGHTS_COMMAND}; stance_z = median z over the stance part, apex_z = max z, clearance = "
            "apex_z − stance_z [m]; expected (the expert's set points): stance_z = −ride + foot radius "
            f"({FOOT_RADIUS:g} m), apex = stance + step height; fits: least squares over the sweep (ideal "
            "slopes: clearance vs step 1, stance_z vs ride −1)"
        ),
        "fits": fits,
        "conditions": rows,
    }
    csv_columns = (
        "sweep",
        "step_height",
        "ride_height",
        "stance_z",
        "apex_z",
        "clearance",
        "stance_z_expected",
        "apex_z_expected",
        "clearance_expected",
    )

    fig = Figure(figsize=FIG_SIZE, dpi=FIG_DPI, layout="constrained")
    axes = fig.subplots(2, 2)
    cmap = mpl.colormaps["viridis"]
    phase = cycle["phase"]
    for col, name in enumerate(("step_height", "ride_height")):
        values = [c[0] if name == "step_height" else c[1] for c in curves[name]]
        norm = mpl.colors.Normalize(min(values), max(values))
        ax = axes[0, col]
        _shade(ax, phase, ~cycle["stance"])
        for (step, ride, z), value in zip(curves[name], values, strict=True):
            color = cmap(norm(value))
            ax.plot(phase, z, color=color, lw=1.3, label=f"{value:.3f} m")
            ground = -ride + FOOT_RADIUS
            target = ground + step if name == "step_height" else ground
            ax.axhline(target, color=color, lw=0.7, ls=":")
        for edge in (min(values), max(values)):
            step, ride, z = curves[name][values.index(edge)]
            ax.plot(phase, z, color="0.5", lw=3.0, alpha=0.35, zorder=0)
        what = "step height (ride 0.25 m)" if name == "step_height" else "ride height (step 0.08 m)"
        ax.set(
            xlabel="FR phase φ_FR [cycles] (shaded: swing)",
            ylabel="FR z [m]",
            title=f"({'ab'[col]}) varying {what}; dotted: expert's "
            f"{'apex' if name == 'step_height' else 'landing height'}",
        )
        _style(ax)
        ax.legend(fontsize=6, loc="upper right", title=name.replace("_", " "), title_fontsize=6)
    ax = axes[1, 0]
    x = [r["step_height"] for r in step_rows]
    ax.plot(x, [r["clearance"] for r in step_rows], "o-", color="C1", label="kernel-ext clearance")
    ax.plot(x, x, "k--", lw=0.8, label="expert set point (= step height)")
    fit = fits["clearance_vs_step_height"]
    ax.set(
        xlabel="step height input [m]",
        ylabel="apex − stance z [m]",
        title=f"(c) swing clearance (fit slope {fit['slope']:.2f}, offset {fit['offset']:+.3f} m)",
    )
    _style(ax)
    ax.legend(fontsize=6)
    ax = axes[1, 1]
    x = [r["ride_height"] for r in ride_rows]
    ax.plot(x, [r["stance_z"] for r in ride_rows], "o-", color="C0", label="kernel-ext stance z")
    ax.plot(x, [r["stance_z_expected"] for r in ride_rows], "k--", lw=0.8, label="−ride + foot radius")
    fit = fits["stance_z_vs_ride_height"]
    ax.set(
        xlabel="ride height input [m]",
        ylabel="stance z [m]",
        title=f"(d) stance height (fit slope {fit['slope']:.2f}, offset {fit['offset']:+.3f} m)",
    )
    _style(ax)
    ax.legend(fontsize=6)
    fig.suptitle(
        f"Thesis {THESIS_FIGURE['heights']}: kernel-ext FR z over one trot cycle, command v_x = "
        f"{HEIGHTS_COMMAND[0]:g} m/s; grey: the training range's end values",
        fontsize=9,
    )
    return table, csv_columns, rows, fig


def velocity_sweep(quick: bool = False) -> list[tuple[str, float, tuple[float, float, float]]]:
    """(axis, commanded value, command) per point: the expert velocity figure's sweep.

    Each of vx, vy, wz over the command generator's limits (``CommandParams``) in steps of 0.1 (vx, wz:
    -0.5..0.5, 11 points; vy: -0.3..0.3, 7 points), the other two zero; ``quick``: low, 0, high.
    """
    from krl.control.commands import CommandParams

    params = CommandParams()
    out = []
    for index, (axis, (low, high)) in enumerate(
        zip(("vx", "vy", "wz"), (params.vx_range, params.vy_range, params.yaw_rate_range), strict=True)
    ):
        count = 3 if quick else 1 + round((high - low) / VELOCITY_STEP)
        for value in np.linspace(low, high, count):
            value = round(float(value), 6) + 0.0  # no -0.0
            command = [0.0, 0.0, 0.0]
            command[index] = value
            out.append((axis, value, (command[0], command[1], command[2])))
    return out


def _kernel_hold(job: tuple[str, tuple[float, float, float], float, int]) -> dict[str, Any]:
    """One velocity-sweep point with the kernel as the controller (runs in a worker process)."""
    from krl.kernel.controller import KernelController
    from krl.kernel.model import load_kernel
    from krl.runner import Runner
    from krl.sim.model import build_model
    from krl.sim.robot import A1Sim

    path, command, duration, seed = job
    start = time.perf_counter()
    controller = KernelController(load_kernel(path))
    runner = Runner(A1Sim(build_model("flat", None, seed)), controller)
    error = None
    try:
        result = runner.hold_command(np.array(command), duration, ramp=HOLD_RAMP)
        realised, fell = np.array(result.realised).reshape(-1, 3), result.fell
    except RuntimeError as exc:
        error, realised, fell = f"{type(exc).__name__}: {exc}", np.zeros((0, 3)), True
    mean = realised.mean(axis=0) if len(realised) else np.full(3, np.nan)
    std = realised.std(axis=0) if len(realised) else np.full(3, np.nan)
    return {
        "fell": bool(fell),
        "error": error,
        "samples": len(realised),
        "mean": mean.tolist(),
        "std": std.tolist(),
        "wall_seconds": time.perf_counter() - start,
    }


def _expert_velocity_json(path: str | os.PathLike | None) -> tuple[dict | None, str | None]:
    if path is not None:
        path = Path(path)
        if not path.is_file():
            raise FigureError(f"expert velocity table not found: {path}")
        candidates = [path]
    else:
        relative = Path("docs/figures/expert/velocity.json")
        candidates = [relative, Path(__file__).resolve().parents[3] / relative]
    for candidate in candidates:
        if candidate.is_file():
            try:
                return json.loads(candidate.read_text()), str(candidate)
            except (OSError, json.JSONDecodeError) as error:
                raise FigureError(f"expert velocity table {candidate} is unreadable: {error}") from None
    return None, None


def _velocity(kernel_path: Path, expert_json, run: _Run):
    from matplotlib.figure import Figure

    duration = QUICK_DURATION if run.quick else DEFAULT_DURATION
    points = velocity_sweep(run.quick)
    # the zero command appears in all three sweeps: run each distinct command once
    jobs = list(dict.fromkeys((str(kernel_path), command, duration, run.seed) for _, _, command in points))
    _say(run, f"velocity: {len(jobs)} kernel holds of {duration:g} s, {run.workers} worker(s) ...")
    outcomes = run_jobs(_kernel_hold, jobs, run.workers, progress="velocity holds" if run.progress else None)
    by_command = {job[1]: outcome for job, outcome in zip(jobs, outcomes, strict=True)}
    expert, expert_source = expert_json
    expert_rows = {(r["axis"], round(r["commanded"], 6)): r for r in (expert or {}).get("conditions", [])}
    rows = []
    for axis, value, command in points:
        outcome = by_command[command]
        row: dict[str, Any] = {"axis": axis, "commanded": value}
        for i, name in enumerate(("vx", "vy", "wz")):
            row[f"{name}_mean"], row[f"{name}_std"] = outcome["mean"][i], outcome["std"][i]
        row.update(fell=outcome["fell"], samples=outcome["samples"], error=outcome["error"])
        match = expert_rows.get((axis, round(value, 6)))
        row["expert_mean"] = match[f"{axis}_mean"] if match else None
        row["expert_std"] = match[f"{axis}_std"] if match else None
        row["expert_fell"] = match["fell"] if match else None
        rows.append(row)
        status = " FELL" if outcome["fell"] else ""
        _say(
            run,
            f"  {axis} = {value:+.2f}: realised {outcome['mean'][('vx', 'vy', 'wz').index(axis)]:+.3f}"
            f"{status} ({outcome['wall_seconds']:.1f} s)",
        )
    fits = {}
    for axis in ("vx", "vy", "wz"):
        ok = [r for r in rows if r["axis"] == axis and not r["fell"]]
        fits[axis] = fit_line([r["commanded"] for r in ok], [r[f"{axis}_mean"] for r in ok])
        fits[axis]["falls"] = sum(1 for r in rows if r["axis"] == axis and r["fell"])
        others = [o for o in ("vx", "vy", "wz") if o != axis]
        fits[axis]["max_abs_cross"] = max(
            (abs(r[f"{o}_mean"]) for r in ok for o in others if math.isfinite(r[f"{o}_mean"])),
            default=float("nan"),
        )
        fits[axis]["max_std"] = max((r[f"{axis}_std"] for r in ok), default=float("nan"))
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
            "as the expert's velocity figure (krl.analysis.expert_plots): each command (others zero) "
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
    csv_columns = (
        "axis",
        "commanded",
        "vx_mean",
        "vx_std",
        "vy_mean",
        "vy_std",
        "wz_mean",
        "wz_std",
        "fell",
        "samples",
        "expert_mean",
        "expert_std",
    )

    fig = Figure(figsize=(FIG_SIZE[0], FIG_SIZE[1] * 0.75), dpi=FIG_DPI, layout="constrained")
    axes = fig.subplots(1, 3)
    names = {
        "vx": ("forward velocity v_x", "m/s"),
        "vy": ("lateral velocity v_y", "m/s"),
        "wz": ("yaw rate ω_z", "rad/s"),
    }
    for ax, axis in zip(axes, ("vx", "vy", "wz"), strict=True):
        sel = [r for r in rows if r["axis"] == axis]
        x = np.array([r["commanded"] for r in sel])
        lim = max(abs(x).max(), 1e-3) * 1.15
        ax.plot([-lim, lim], [-lim, lim], "k--", lw=0.8, label="identity")
        ex = [
            (r["commanded"], r["expert_mean"], r["expert_std"]) for r in sel if r["expert_mean"] is not None
        ]
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
        fit = fits[axis]
        label = f"kernel fit: slope {fit['slope']:.2f}, offset {fit['offset']:+.3f}"
        draw_fit_and_axes(ax, fit, lim, *names[axis], label)
        _style(ax)
        ax.legend(fontsize=6, loc="upper left")
    fig.suptitle(
        f"Thesis {THESIS_FIGURE['velocity']}: realised vs commanded velocity, kernel-base controller vs MPC "
        f"expert ({duration:g} s holds, measured from {HOLD_RAMP + HOLD_SETTLE:g} s"
        f"{', quick' if run.quick else ''})",
        fontsize=9,
    )
    return table, csv_columns, rows, fig


# --- driver -------------------------------------------------------------------------------------------------


def _load_checked(model: str | os.PathLike, variant: str, option: str):
    from krl.kernel.model import load_kernel
    from krl.kernel.registry import resolve_model

    path = resolve_model(str(model))
    if not path.is_file():
        raise FigureError(f"{option}: kernel file not found: {path}")
    kernel = load_kernel(path)
    if kernel.variant != variant:
        raise FigureError(
            f"{option}: {path} is a kernel-{kernel.variant}, this figure needs a kernel-{variant}"
        )
    return kernel, path


def make_kernel_figures(
    which: str,
    out_dir: str | os.PathLike,
    model: str | os.PathLike = "base",
    ext_model: str | os.PathLike = "ext",
    ind_model: str | os.PathLike | None = None,
    expert_json: str | os.PathLike | None = None,
    seed: int = 0,
    quick: bool = False,
    workers: int | None = None,
    progress: bool = True,
) -> dict[str, Any]:
    """Make the figure(s) and write ``NAME.png``, ``NAME.json``, ``NAME.csv`` per figure into ``out_dir``.

    Args:
        which: a name of :data:`FIGURES` or ``all``.
        out_dir: output folder (created).
        model, ext_model: kernel-base and kernel-ext: a shipped kernel's name (``base``, ``ext``) or a
            file; ``ext_model`` is only loaded for ``heights``.
        ind_model: an optional kernel-ind file for ``walk-gait`` (its panel is left out without one).
        expert_json: the expert's velocity table (default: ``docs/figures/expert/velocity.json`` under
            the working directory or the repository); without one ``velocity`` shows the kernel only.
        seed: waypoints of ``trajectories`` and the simulator's seed.
        quick: tiny runs (tests).
        workers: processes for the velocity sweep (default: number of CPUs; 1 = in-process).

    Returns:
        ``{"figures": {name: {"png", "json", "csv", "table"}}, "workers", "wall_seconds"}``.

    Raises:
        FigureError (a ValueError): unknown ``which``, bad argument, missing or wrong-variant kernel file,
        missing explicit ``expert_json``; all checked before anything runs or is written.
    """
    if which not in CHOICES:
        raise FigureError(f"unknown figure {which!r}; choose from {', '.join(CHOICES)}")
    if workers is None:
        workers = os.cpu_count() or 1
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise FigureError(f"--workers must be a whole number >= 1, got {workers!r}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise FigureError(f"--seed must be a whole number >= 0, got {seed!r}")
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise FigureError(f"--out {str(out)!r} exists and is not a folder")
    names = FIGURES if which == "all" else (which,)
    kernels: dict[str, Any] = {}
    paths: dict[str, Path] = {}
    if any(_NEEDS.get(name, "base") == "base" for name in names):
        kernels["base"], paths["base"] = _load_checked(model, "base", "--model")
    if "heights" in names:
        kernels["ext"], paths["ext"] = _load_checked(ext_model, "ext", "--ext-model")
    if ind_model is not None and "walk-gait" in names:
        kernels["ind"], paths["ind"] = _load_checked(ind_model, "ind", "--ind-model")
    expert = _expert_velocity_json(expert_json) if "velocity" in names else (None, None)

    run = _Run(seed=seed, quick=quick, workers=workers, progress=progress)
    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    figures: dict[str, Any] = {}
    for name in names:
        if name == "trajectories":
            built = _trajectories(kernels["base"], run)
        elif name == "command-sweep":
            built = _command_sweep(kernels["base"], run)
        elif name == "symmetry":
            built = _symmetry(kernels["base"], run)
        elif name == "walk-gait":
            built = _walk_gait(kernels["base"], kernels.get("ind"), run)
        elif name == "heights":
            built = _heights(kernels["ext"], run)
        else:
            built = _velocity(paths["base"], expert, run)
        table, columns, rows, fig = built
        table["kernels"] = {key: str(path) for key, path in paths.items()}
        table = json_value(table)
        files = {kind: out / f"{name}.{kind}" for kind in ("png", "json", "csv")}
        write_atomic(files["png"], figure_bytes(fig))
        write_atomic(files["json"], (json.dumps(table, indent=2, ensure_ascii=False) + "\n").encode())
        write_atomic(files["csv"], csv_bytes(columns, [{c: row.get(c) for c in columns} for row in rows]))
        figures[name] = {**{kind: str(path) for kind, path in files.items()}, "table": table}
        _say(run, f"{name}: wrote {files['png']}")
    return {"figures": figures, "workers": workers, "wall_seconds": round(time.perf_counter() - start, 2)}
