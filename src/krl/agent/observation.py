"""The residual agent's observation: named features, concatenated in the configured order.

Every feature is computed for a batch of N robots at once from the step's :class:`ObservationInputs`.
The default set is the thesis's final one (4.2.8.3); the optional ones are those of Fig. 4.20.

:func:`observation_table` writes the table of every feature (name, size, unit, what) from
:data:`FEATURES`, the one registry; :class:`krl.envs.residual.A1ResidualEnv`'s docstring shows it.
:func:`layout` gives the slices of a configured observation.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

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
    sensed: Mapping[str, np.ndarray] = field(default_factory=dict)
    """The values of the :data:`SENSED` features the observation asks for, by name, measured in the scene
    (:mod:`krl.agent.sensing`). Shape of each: (N, size)."""


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
    privileged: bool = False
    """Only the critic may see it: no robot measures it (``ObservationConfig.critic_features``)."""


def _flat(array: np.ndarray) -> np.ndarray:
    return array.reshape(len(array), -1)


class MissingSensorError(ValueError):
    """An observation asks for a sensed feature its caller did not measure."""


def _sensed(name: str) -> Callable[[ObservationInputs], np.ndarray]:
    def compute(inputs: ObservationInputs) -> np.ndarray:
        if name not in inputs.sensed:
            raise MissingSensorError(
                f"observation feature {name!r} is measured in the scene, and this caller did not measure it"
            )
        return inputs.sensed[name]

    return compute


SCAN_SIZE = -1
"""The :attr:`Feature.size` of the height scans: the configured grid's (:func:`feature_size`)."""


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
    "height_scan": Feature(
        SCAN_SIZE,
        "m",
        "trunk height above the terrain, less the standing height, at the scan's heading-frame grid points "
        "(``observation.scan``, x-major), clipped; noisy in training where ``scan.noise`` is set",
        _sensed("height_scan"),
    ),
    "height_scan_clean": Feature(
        SCAN_SIZE, "m", "the height scan without noise (privileged)", _sensed("height_scan_clean"), True
    ),
    "ground_friction": Feature(
        1, "1", "sliding friction μ of the ground's terrain (privileged)", _sensed("ground_friction"), True
    ),
    "push_force": Feature(
        3,
        "N",
        "the push acting on the trunk now, base frame; 0 between pushes (privileged)",
        _sensed("push_force"),
        True,
    ),
    "terrain_level": Feature(
        1,
        "1",
        "the robot's terrain curriculum level / (levels - 1); 0 without a curriculum (privileged)",
        _sensed("terrain_level"),
        True,
    ),
}
"""Every observation feature, by name."""

SENSED: tuple[str, ...] = (
    "height_scan",
    "height_scan_clean",
    "ground_friction",
    "push_force",
    "terrain_level",
)
"""The features measured in the scene rather than read from the state and the controller
(:class:`ObservationInputs.sensed`)."""


def feature_size(name: str, scan=None) -> int:
    """Numbers feature ``name`` adds: its :attr:`Feature.size`, or for a height scan the points of ``scan``
    (a :class:`krl.agent.config.ScanConfig`, which a height scan needs: ValueError without it)."""
    size = FEATURES[name].size
    if size != SCAN_SIZE:
        return size
    if scan is None:
        raise ValueError(f"the size of {name!r} is its scan grid's, and none was given")
    return scan.size


def layout(features: Sequence[str], scan=None) -> list[dict[str, object]]:
    """``[{"name", "start", "stop", "size", "unit"}, ...]`` of an observation of ``features``, in order
    (``scan``: the height scans' grid, :func:`feature_size`)."""
    rows, start = [], 0
    for name in features:
        size = feature_size(name, scan)
        rows.append(
            {"name": name, "start": start, "stop": start + size, "size": size, "unit": FEATURES[name].unit}
        )
        start += size
    return rows


def observation_table() -> str:
    """Every feature of :data:`FEATURES` as a Markdown table: name, size, unit, what."""
    lines = ["| name | size | unit | what |", "| --- | --- | --- | --- |"]
    lines += [
        f"| ``{n}`` | {'grid' if f.size == SCAN_SIZE else f.size} | {f.unit} | {f.description} |"
        for n, f in FEATURES.items()
    ]
    return "\n".join(lines)


def observation_size(features: Sequence[str], scan=None) -> int:
    """Length of an observation of ``features`` (``scan``: the height scans' grid)."""
    return sum(feature_size(name, scan) for name in features)


def observe(features: Sequence[str], inputs: ObservationInputs) -> np.ndarray:
    """The observations of N robots. Shape: (N, observation_size(features)), float32."""
    return np.concatenate([FEATURES[name].compute(inputs) for name in features], axis=1).astype(np.float32)
