"""The residual agent's observation: named features, concatenated in the configured order.

Every feature is computed for a batch of N robots at once from the step's :class:`ObservationInputs`.
The default set is the thesis's final one (4.2.8.3); the optional ones are those of Fig. 4.20.

:func:`observation_table` writes the table of every feature (name, size, unit, what) from
:data:`FEATURES`, the one registry; :class:`krl.agent.env.A1ResidualEnv`'s docstring shows it.
:func:`layout` gives the slices of a configured observation.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from krl.sim.state import StateBatch


@dataclass(frozen=True)
class ObservationInputs:
    """What the features are computed from, for N robots."""

    state: StateBatch
    """The robots' current states."""
    command: np.ndarray
    """Velocity commands of the coming step. Shape: (N, 3)."""
    residual: np.ndarray
    """Filtered residual of the previous step [m]. Shape: (N, 4, 3)."""
    normalised_phase: np.ndarray
    """Normalised phases of the coming step. Shape: (N, 4)."""
    kernel_targets: np.ndarray
    """Kernel foot targets of the coming step [m]. Shape: (N, 4, 3)."""
    gait_inputs: np.ndarray
    """The driven command (or steering offset), step and ride heights [m] and clock rate of the coming step
    (:attr:`krl.agent.residual.ResidualController.gait_inputs`). Shape: (N, 6)."""


@dataclass(frozen=True)
class Feature:
    """One observation feature."""

    size: int
    """Numbers the feature adds to the observation."""
    unit: str
    """Unit of its numbers ("1": dimensionless)."""
    description: str
    """What it is, in one line (frame and order of its numbers)."""
    compute: Callable[[ObservationInputs], np.ndarray]
    """``inputs -> (N, size)``."""


def _flat(array: np.ndarray) -> np.ndarray:
    return array.reshape(len(array), -1)


FEATURES: dict[str, Feature] = {
    "base_lin_vel": Feature(3, "m/s", "trunk linear velocity, base frame", lambda i: i.state.lin_vel_base),
    "base_ang_vel": Feature(3, "rad/s", "trunk angular velocity, base frame", lambda i: i.state.ang_vel_base),
    "command": Feature(
        3,
        "m/s, m/s, rad/s",
        "commanded (v_x, v_y) and yaw rate of the step (heading frame)",
        lambda i: i.command,
    ),
    "joint_pos": Feature(
        12, "rad", "joint angles, FR FL RR RL × (abduction, hip, knee)", lambda i: i.state.joint_pos
    ),
    "joint_vel": Feature(12, "rad/s", "joint velocities", lambda i: i.state.joint_vel),
    "gravity": Feature(
        3,
        "1",
        'gravity direction in the base frame (the thesis\'s "CoM"), (0, 0, -1) level',
        lambda i: i.state.projected_gravity,
    ),
    "roll_pitch": Feature(2, "rad", "trunk roll and pitch", lambda i: i.state.rpy[:, :2]),
    "residual": Feature(
        12,
        "m",
        "the previous step's filtered residual δA^lpf_{t-1}, base frame, leg-major",
        lambda i: _flat(i.residual),
    ),
    "foot_contact": Feature(
        4,
        "1",
        "1 where the foot touched something in the last physics step",
        lambda i: i.state.foot_contact.astype(float),
    ),
    "phase": Feature(
        4, "1", "the gait's normalised phases (Eq. 4.6) of the coming step", lambda i: i.normalised_phase
    ),
    "kernel_targets": Feature(
        12,
        "m",
        "the kernel's foot targets A^ref_t of the coming step, base frame",
        lambda i: _flat(i.kernel_targets),
    ),
    "contact_force": Feature(
        4, "N", "normal contact force on each foot in the last physics step", lambda i: i.state.foot_force
    ),
    "kernel_command": Feature(
        3,
        "m/s, m/s, rad/s",
        "the driven command columns of the coming step: the kernel's command (drive_command) or the offset "
        "to the task's (drive_steer); 0 when neither",
        lambda i: i.gait_inputs[:, :3],
    ),
    "heights": Feature(
        2,
        "m",
        "kernel-ext's step and ride heights of the coming step (driven or nominal)",
        lambda i: i.gait_inputs[:, 3:5],
    ),
    "clock_rate": Feature(
        1, "1", "the gait clock's rate of the coming step (driven, else 1)", lambda i: i.gait_inputs[:, 5:6]
    ),
}
"""Every observation feature, by name."""


def layout(features: Sequence[str]) -> list[dict[str, object]]:
    """``[{"name", "start", "stop", "size", "unit"}, ...]`` of an observation of ``features``, in order."""
    rows, start = [], 0
    for name in features:
        feature = FEATURES[name]
        rows.append(
            {
                "name": name,
                "start": start,
                "stop": start + feature.size,
                "size": feature.size,
                "unit": feature.unit,
            }
        )
        start += feature.size
    return rows


def observation_table() -> str:
    """Every feature of :data:`FEATURES` as a Markdown table: name, size, unit, what."""
    lines = ["| name | size | unit | what |", "| --- | --- | --- | --- |"]
    lines += [f"| ``{n}`` | {f.size} | {f.unit} | {f.description} |" for n, f in FEATURES.items()]
    return "\n".join(lines)


def observation_size(features: Sequence[str]) -> int:
    """Length of an observation of ``features``."""
    return sum(FEATURES[name].size for name in features)


def observe(features: Sequence[str], inputs: ObservationInputs) -> np.ndarray:
    """The observations of N robots. Shape: (N, observation_size(features)), float32."""
    return np.concatenate([FEATURES[name].compute(inputs) for name in features], axis=1).astype(np.float32)
