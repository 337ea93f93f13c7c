"""The kernel's inputs and the expert's labels for the kernel figures: dataset-like input columns, the
kernel's prediction from them, one gait cycle sampled by a leg's phase, and the MPC expert re-recorded with
the settings a kernel was trained on (its labels exactly as in training).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from krl.analysis.kernel.context import FR
from krl.analysis.kernel.metrics import CYCLE_POINTS
from krl.control.expert import NOMINAL_RIDE_HEIGHT, NOMINAL_STEP_HEIGHT
from krl.robots.a1.constants import NUM_LEGS
from krl.task import TARGET_TIME_LIMIT
from krl.task.runner import HOLD_RAMP

HOLD_DURATION: float = 8.0
"""Length of the expert's fixed-command runs of ``symmetry`` and ``walk-gait`` [s]."""


def kernel_columns(
    commands: np.ndarray,
    normalised: np.ndarray,
    step_height: float = NOMINAL_STEP_HEIGHT,
    ride_height: float = NOMINAL_RIDE_HEIGHT,
) -> dict[str, np.ndarray]:
    """Dataset-like kernel input columns (:mod:`krl.data.schema`'s names) for N control steps.

    Args:
        commands: (vx [m/s], vy [m/s], wz [rad/s]) per step. Shape: (N, 3).
        normalised: the four legs' normalised phases |φ| (Eq. 4.6). Shape: (N, 4).
        step_height, ride_height: the expert's heights, constant over the steps [m].
    """
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


def expert_params(kernel, **overrides):
    """The ``ExpertParams`` the kernel's training data was collected with, ``overrides`` replaced."""
    from krl.kernel.settings import training_settings

    return replace(training_settings(kernel).expert, **overrides)


def command_limits(kernel) -> dict[str, tuple[float, float]]:
    """The command generator's limits during the kernel's collection: (low, high) per vx, vy, wz."""
    from krl.kernel.settings import training_settings

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
    from krl.sim.model import build_model
    from krl.sim.robot import A1Sim
    from krl.task.runner import Runner

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
