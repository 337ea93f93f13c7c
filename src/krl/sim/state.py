"""What a control step reads out of the simulator: one robot's :class:`RobotState`, N robots'
:class:`StateBatch`, and :func:`state_fields`, the one readout that makes both from ``MjData``'s arrays
(the fall rule included).

This module only computes; :mod:`krl.sim.batch` owns the simulators and hands it copies of their data.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, fields

import numpy as np

FALL_TILT: float = np.pi / 3
"""The robot has fallen when its trunk's up axis is tilted more than this from vertical [rad]."""

_COS_FALL_TILT = math.cos(FALL_TILT)


@dataclass(slots=True)
class RobotState:
    """Everything a controller reads after a control step. Frames: world (W) and base/trunk (B).

    A fresh snapshot is made every step (its arrays are copies, never views of ``MjData``); treat it
    as read-only.
    """

    time: float
    """Simulation time [s]."""
    base_pos: np.ndarray
    """Trunk origin in W [m]. Shape: (3,)."""
    base_quat: np.ndarray
    """Trunk orientation, quaternion (w, x, y, z), B to W. Shape: (4,)."""
    base_rot: np.ndarray
    """Rotation matrix B to W. Shape: (3, 3)."""
    rpy: np.ndarray
    """Roll, pitch, yaw (intrinsic Z-Y-X: R = Rz(yaw) Ry(pitch) Rx(roll)) [rad]. Shape: (3,)."""
    projected_gravity: np.ndarray
    """Unit gravity direction expressed in B ((0, 0, -1) when level). Shape: (3,)."""
    lin_vel_world: np.ndarray
    """Trunk-origin linear velocity in W [m/s]. Shape: (3,)."""
    lin_vel_base: np.ndarray
    """Trunk-origin linear velocity in B [m/s]. Shape: (3,)."""
    ang_vel_world: np.ndarray
    """Trunk angular velocity in W [rad/s]. Shape: (3,)."""
    ang_vel_base: np.ndarray
    """Trunk angular velocity in B [rad/s]. Shape: (3,)."""
    joint_pos: np.ndarray
    """Joint angles [rad]. Shape: (12,)."""
    joint_vel: np.ndarray
    """Joint velocities [rad/s]. Shape: (12,)."""
    joint_torque: np.ndarray
    """Actuator torques applied during the last physics step [N·m]. Shape: (12,)."""
    foot_pos_world: np.ndarray
    """Foot-sphere centres in W [m]. Shape: (4, 3)."""
    foot_pos_base: np.ndarray
    """Foot-sphere centres in B [m]. Shape: (4, 3)."""
    foot_force: np.ndarray
    """Normal contact force on each foot during the last physics step [N]. Shape: (4,)."""
    foot_contact: np.ndarray
    """Whether each foot touched anything during the last physics step. Shape: (4,), bool."""
    com: np.ndarray
    """Whole-robot centre of mass in W [m]. Shape: (3,)."""
    trunk_contact: bool
    """Whether the trunk touched anything during the last physics step."""
    fallen: bool
    """Fall rule (docs/sim.md): trunk contact, or trunk tilted more than FALL_TILT from vertical."""


@dataclass(slots=True)
class StateBatch:
    """The fields of :class:`RobotState` for N robots, each with a leading axis of N.

    Shapes: ``time`` (N,), ``base_pos`` (N, 3), ``base_quat`` (N, 4), ``base_rot`` (N, 3, 3), ``rpy``
    (N, 3), ``projected_gravity``/``lin_vel_*``/``ang_vel_*``/``com`` (N, 3), ``joint_*`` (N, 12),
    ``foot_pos_*`` (N, 4, 3), ``foot_force``/``foot_contact`` (N, 4), ``trunk_contact``/``fallen`` (N,).
    Units and frames as in :class:`RobotState`.
    """

    time: np.ndarray
    base_pos: np.ndarray
    base_quat: np.ndarray
    base_rot: np.ndarray
    rpy: np.ndarray
    projected_gravity: np.ndarray
    lin_vel_world: np.ndarray
    lin_vel_base: np.ndarray
    ang_vel_world: np.ndarray
    ang_vel_base: np.ndarray
    joint_pos: np.ndarray
    joint_vel: np.ndarray
    joint_torque: np.ndarray
    foot_pos_world: np.ndarray
    foot_pos_base: np.ndarray
    foot_force: np.ndarray
    foot_contact: np.ndarray
    com: np.ndarray
    trunk_contact: np.ndarray
    fallen: np.ndarray

    @classmethod
    def from_states(cls, states: Sequence[RobotState]) -> StateBatch:
        """Stack single states (in order) into a batch."""
        return cls(*(np.array([getattr(s, name) for s in states]) for name in FIELD_NAMES))

    def __len__(self) -> int:
        return len(self.time)

    def rows(self, index: np.ndarray | slice) -> StateBatch:
        """The robots ``index`` selects (an index array or a slice), as a new batch of copies."""
        return StateBatch(*(np.array(getattr(self, name)[index]) for name in FIELD_NAMES))

    def row(self, index: int) -> RobotState:
        """Robot ``index`` as a single state (copies of its rows)."""
        return RobotState(
            float(self.time[index]),
            *(getattr(self, name)[index].copy() for name in _ARRAY_FIELDS),
            trunk_contact=bool(self.trunk_contact[index]),
            fallen=bool(self.fallen[index]),
        )


FIELD_NAMES: tuple[str, ...] = tuple(f.name for f in fields(RobotState))
if FIELD_NAMES != tuple(f.name for f in fields(StateBatch)):  # pragma: no cover - a guard for editors
    raise RuntimeError("StateBatch must list RobotState's fields in RobotState's order")
_ARRAY_FIELDS = FIELD_NAMES[1:-2]
"""The fields of a single state that are arrays: all but ``time`` (first), ``trunk_contact`` and ``fallen``
(last)."""
if FIELD_NAMES[:1] + FIELD_NAMES[-2:] != ("time", "trunk_contact", "fallen"):  # pragma: no cover
    raise RuntimeError("RobotState must begin with time and end with trunk_contact, fallen")


def state_fields(
    time: float | np.ndarray,
    qpos: np.ndarray,
    qvel: np.ndarray,
    rot: np.ndarray,
    foot_world: np.ndarray,
    foot_force: np.ndarray,
    trunk_force: float | np.ndarray,
    joint_torque: np.ndarray,
    com: np.ndarray,
) -> tuple:
    """The fields of :class:`RobotState`, in its order, from what ``MjData`` holds after a step: the one
    readout of :meth:`krl.sim.batch.SimBatch.step` (N robots at once) and of
    :meth:`krl.sim.batch.SimBatch.read_state` (one robot).

    Every input has the shape of one robot, ``(...)`` below, or a leading axis of N; the results are
    views of the inputs or new arrays, never copies of ``MjData`` memory (pass copies).

    Args:
        time: simulation time [s]. Shape: (...).
        qpos: the robot's ``qpos`` (free joint, then the 12 joints) [m, 1, rad]. Shape: (..., 19).
        qvel: the robot's ``qvel`` [m/s, rad/s]. Shape: (..., 18).
        rot: ``mju_quat2Mat`` of the trunk quaternion ``qpos[3:7]``, row-major. Shape: (..., 9).
        foot_world: foot-sphere centres in W [m]. Shape: (..., 4, 3).
        foot_force: the feet's touch sensors [N]. Shape: (..., 4).
        trunk_force: the trunk's touch sensor [N]. Shape: (...).
        joint_torque: actuator forces [N·m]. Shape: (..., 12).
        com: the trunk's subtree centre of mass in W [m]. Shape: (..., 3).
    """
    base_pos = qpos[..., 0:3]
    base_rot = rot.reshape(*rot.shape[:-1], 3, 3)
    lin_vel_world = qvel[..., 0:3]
    ang_vel_base = qvel[..., 3:6]
    trunk_contact = trunk_force > 0.0
    return (
        time,
        base_pos,
        qpos[..., 3:7],
        base_rot,
        _rpy(rot),
        -base_rot[..., 2, :],
        lin_vel_world,
        np.matmul(lin_vel_world[..., None, :], base_rot)[..., 0, :],
        np.matmul(base_rot, ang_vel_base[..., None])[..., 0],
        ang_vel_base,
        qpos[..., 7:19],
        qvel[..., 6:18],
        joint_torque,
        foot_world,
        np.matmul(foot_world - base_pos[..., None, :], base_rot),
        foot_force,
        foot_force > 0.0,
        com,
        trunk_contact,
        trunk_contact | (rot[..., 8] < _COS_FALL_TILT),
    )


def _rpy(rot: np.ndarray) -> np.ndarray:
    """Roll, pitch, yaw [rad] of row-major rotation matrices (shape (..., 9)), shape (..., 3).

    With ``math``'s (libm's) atan2 and asin, one robot at a time: NumPy's SIMD arctan2/arcsin can differ
    from them in the last bit, and the readout of one robot and of a batch must agree exactly.
    """
    flat = rot.reshape(-1, 9).T.tolist()
    r00, r10, r20, r21, r22 = flat[0], flat[3], flat[6], flat[7], flat[8]
    rpy = [
        (math.atan2(a21, a22), -math.asin(min(1.0, max(-1.0, a20))), math.atan2(a10, a00))
        for a00, a10, a20, a21, a22 in zip(r00, r10, r20, r21, r22, strict=True)
    ]
    return np.array(rpy).reshape(*rot.shape[:-1], 3)
