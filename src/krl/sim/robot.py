"""The simulated A1: hybrid PD control at 1 kHz inside MuJoCo, state readout, pushes, fall detection.

One call of :meth:`A1Sim.step` is one 200 Hz control step: it writes the joint commands into the
actuators (``ctrl = kp * q_target + tau_ff`` with ``kp``/``kd`` in the actuators' bias parameters, so
MuJoCo evaluates ``tau = kp (q_target - q) - kd q̇ + tau_ff`` at every 1 ms physics step), runs the
five physics steps in one ``mj_step`` call, refreshes positions with ``mj_kinematics`` and returns a
:class:`RobotState`. Only this module and :mod:`krl.sim.batch` (which steps many simulators through
:meth:`A1Sim._physics_step` and reads their states out together with :func:`state_fields`) mutate
``MjData``.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass

import mujoco
import numpy as np

from krl.robots.a1.constants import (
    FOOT_NAMES,
    JOINT_NAMES,
    KD,
    KP,
    MOTOR_FULL_TORQUE_SPEED,
    MOTOR_MAX_SPEED,
    MOTOR_TORQUE_LIMIT,
    NUM_JOINTS,
    STANDING_HEIGHT,
    STANDING_JOINT_ANGLES,
)
from krl.sim.model import BuiltModel
from krl.sim.pushes import Push
from krl.util.timing import CONTROL_DT, SUBSTEPS

FALL_TILT: float = np.pi / 3
"""The robot has fallen when its trunk's up axis is tilted more than this from vertical [rad]."""

_COS_FALL_TILT = math.cos(FALL_TILT)

_BAD_QPOS = int(mujoco.mjtWarning.mjWARN_BADQPOS)
_BAD_QVEL = int(mujoco.mjtWarning.mjWARN_BADQVEL)
_BAD_QACC = int(mujoco.mjtWarning.mjWARN_BADQACC)

SPAWN_CLEARANCE: float = 0.01
"""Height added above the standing height at reset so the feet start just above the ground [m]."""


class SimulationUnstableError(RuntimeError):
    """The physics diverged (non-finite or exploding state); the episode cannot go on."""


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


def motor_torque_bounds(joint_vel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Torque-speed envelope of the A1 motor: (lower, upper) output torque [N·m] at joint speeds [rad/s].

    Braking (torque against the motion) always has the full ``MOTOR_TORQUE_LIMIT``. Motoring (torque
    along the motion) has the full limit up to ``MOTOR_FULL_TORQUE_SPEED`` and falls linearly to zero
    at ``MOTOR_MAX_SPEED``. Shapes: like ``joint_vel``.
    """
    upper = np.empty_like(joint_vel, dtype=float)
    lower = np.empty_like(joint_vel, dtype=float)
    _torque_bounds_into(np.asarray(joint_vel, dtype=float), lower, upper)
    return lower, upper


_ENVELOPE_SLOPE = MOTOR_TORQUE_LIMIT / (MOTOR_MAX_SPEED - MOTOR_FULL_TORQUE_SPEED)


def _torque_bounds_into(joint_vel: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> None:
    # upper = limit * clip((v_max - v) / (v_max - v_full), 0, 1): for v <= v_full this is the full
    # limit, so no case split on the sign of v is needed (and likewise for lower with -v).
    # (np.minimum/np.maximum with out= are several times cheaper than np.clip on 12 values.)
    np.subtract(MOTOR_MAX_SPEED, joint_vel, out=upper)
    np.multiply(upper, _ENVELOPE_SLOPE, out=upper)
    np.maximum(upper, 0.0, out=upper)
    np.minimum(upper, MOTOR_TORQUE_LIMIT, out=upper)
    np.add(MOTOR_MAX_SPEED, joint_vel, out=lower)
    np.multiply(lower, -_ENVELOPE_SLOPE, out=lower)
    np.minimum(lower, 0.0, out=lower)
    np.maximum(lower, -MOTOR_TORQUE_LIMIT, out=lower)


class A1Sim:
    """One simulated A1 on one terrain.

    Args:
        built: the compiled model (:func:`krl.sim.model.build_model`).
        motor_envelope: limit motoring torque with speed (:func:`motor_torque_bounds`), updated once per
            control step; when False only the constant ±``MOTOR_TORQUE_LIMIT`` clamp applies.
    """

    def __init__(self, built: BuiltModel, motor_envelope: bool = True) -> None:
        # A private copy: the PD gains and motor envelope are written into the model every step, so two
        # simulators must never share one MjModel.
        self.model = copy.copy(built.model)
        self.terrain = built.terrain
        self.data = mujoco.MjData(self.model)
        self.motor_envelope = motor_envelope
        m = self.model
        self._trunk = m.body("trunk").id
        self._foot_sites = np.array([m.site(name).id for name in FOOT_NAMES])
        self._foot_sensor_adr = np.array([m.sensor_adr[m.sensor(name).id] for name in FOOT_NAMES])
        self._trunk_sensor_adr = int(m.sensor_adr[m.sensor("trunk_contact").id])
        actuator_ids = [m.actuator(name).id for name in JOINT_NAMES]
        if actuator_ids != list(range(NUM_JOINTS)):
            raise RuntimeError("A1 model: actuators must be the first 12, in krl joint order")
        joint_qpos = [m.jnt_qposadr[m.joint(name).id] for name in JOINT_NAMES]
        if joint_qpos != list(range(7, 7 + NUM_JOINTS)):
            raise RuntimeError("A1 model: joint qpos must follow the free joint, in krl joint order")
        self._bias = m.actuator_biasprm[:NUM_JOINTS]
        self._forcerange = m.actuator_forcerange[:NUM_JOINTS]
        self._kp = KP.copy()
        self._kd = KD.copy()
        self._write_gains(self._kp, self._kd)
        self._warning_counts = self.data.warning.number  # a view into MjData
        # views into the model's actuator force ranges, written in place by the motor envelope
        self._lower = self._forcerange[:, 0]
        self._upper = self._forcerange[:, 1]
        self._step = 0
        self._push: Push | None = None
        # views into MjData read after every step (MjData's attributes make a new array on every access)
        self._ctrl = self.data.ctrl[:NUM_JOINTS]
        self._qpos = self.data.qpos[:19]
        self._qvel = self.data.qvel[:18]
        self._site_xpos = self.data.site_xpos
        self._sensordata = self.data.sensordata
        self._actuator_force = self.data.actuator_force[:NUM_JOINTS]
        self._trunk_com = self.data.subtree_com[self._trunk]
        self._state: RobotState | None = None
        self.reset()

    @property
    def state(self) -> RobotState:
        """The state after the last step or reset (after a :class:`SimulationUnstableError`: the last one
        before it)."""
        if self._state is None:  # a step of krl.sim.batch.SimBatch, which reads its states out itself
            self._state = self._read_state()
        return self._state

    # --- reset -------------------------------------------------------------------------------------

    def reset(
        self,
        xy: tuple[float, float] | None = None,
        yaw: float = 0.0,
        joint_angles: np.ndarray | None = None,
    ) -> RobotState:
        """Put the robot at rest at ``xy`` (default: the terrain's spawn point) facing ``yaw`` [rad].

        The base is placed ``STANDING_HEIGHT + SPAWN_CLEARANCE`` above the terrain's rest height, with
        the joints at ``joint_angles`` (default: standing pose, shape (12,)); props return to rest.
        """
        mujoco.mj_resetData(self.model, self.data)
        x, y = self.terrain.spawn_xy if xy is None else xy
        ground = float(np.asarray(self.terrain.height(np.array([x]), np.array([y])))[0])
        angles = (
            STANDING_JOINT_ANGLES
            if joint_angles is None
            else _check_joint_vector(joint_angles, "joint_angles")
        )
        qpos = self.data.qpos
        qpos[0:3] = (x, y, ground + STANDING_HEIGHT + SPAWN_CLEARANCE)
        qpos[3:7] = (np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2))
        qpos[7:19] = angles
        self._step = 0
        self._push = None
        self._kp[:] = KP
        self._kd[:] = KD
        self._write_gains(self._kp, self._kd)
        self.data.ctrl[:NUM_JOINTS] = self._kp * angles
        mujoco.mj_forward(self.model, self.data)
        self._state = self._read_state()
        return self._state

    def set_state(self, qpos: np.ndarray, qvel: np.ndarray) -> RobotState:
        """Put the robot in the state ``qpos`` (the free joint, then the 12 joints; shape (19,)) and
        ``qvel`` (shape (18,)), keeping the time, gains and pending push; returns its readout (after
        ``mj_forward``). The next :meth:`step` starts from it."""
        qpos, qvel = np.asarray(qpos, dtype=float), np.asarray(qvel, dtype=float)
        if qpos.shape != (19,) or qvel.shape != (18,):
            raise ValueError(
                f"qpos and qvel must have shapes (19,) and (18,), got {qpos.shape}, {qvel.shape}"
            )
        self._qpos[:] = qpos
        self._qvel[:] = qvel
        mujoco.mj_forward(self.model, self.data)
        self._state = self._read_state()
        return self._state

    # --- stepping ----------------------------------------------------------------------------------

    @property
    def time(self) -> float:
        """Simulation time [s]."""
        return self._step * CONTROL_DT

    @property
    def step_count(self) -> int:
        """Control steps since the last reset."""
        return self._step

    def step(
        self,
        q_target: np.ndarray,
        kp: np.ndarray | None = None,
        kd: np.ndarray | None = None,
        tau_ff: np.ndarray | None = None,
    ) -> RobotState:
        """Run one control step (5 physics steps of 1 ms) with a hybrid joint command.

        Args:
            q_target: joint angle targets [rad]. Shape: (12,).
            kp: per-joint stiffness [N·m/rad], shape (12,); default Table 4.2. 0 makes a joint
                torque-controlled.
            kd: per-joint damping [N·m·s/rad], shape (12,); default Table 4.2.
            tau_ff: feed-forward torques [N·m], shape (12,); default zero.

        Returns the state after the step. Raises :class:`SimulationUnstableError` if the physics
        diverged and ``ValueError`` for a wrong-shaped or non-finite command.
        """
        q_target = _check_joint_vector(q_target, "q_target")
        if kp is not None or kd is not None:
            kp = KP if kp is None else _check_joint_vector(kp, "kp")
            kd = KD if kd is None else _check_joint_vector(kd, "kd")
            if np.any(kp < 0) or np.any(kd < 0):
                raise ValueError("kp and kd must be >= 0")
            if not (np.array_equal(kp, self._kp) and np.array_equal(kd, self._kd)):
                self._kp[:] = kp
                self._kd[:] = kd
                self._write_gains(self._kp, self._kd)
        ctrl = self._kp * q_target
        if tau_ff is not None:
            ctrl += _check_joint_vector(tau_ff, "tau_ff")
        self._ctrl[:] = ctrl
        if self.motor_envelope:
            _torque_bounds_into(self._qvel[6 : 6 + NUM_JOINTS], self._lower, self._upper)
        state = self.state
        self._physics_step(state.base_pos, state.base_rot)
        self._state = self._read_state()
        return self._state

    def _physics_step(self, base_pos: np.ndarray, base_rot: np.ndarray) -> None:
        """The physics of one control step once the actuators hold the command and the motor envelope:
        the five physics steps (with the pending push), the stability check and the kinematics the
        readout needs (``mj_kinematics``, ``mj_comPos``). ``base_pos`` [m] (shape (3,)) and ``base_rot``
        (shape (3, 3)): the trunk's pose before the step, as the last readout gave it; a push acts there.
        Raises :class:`SimulationUnstableError`.
        """
        push = self._push
        if push is not None and push.active_at(self._step):
            self._step_pushed(push, base_pos, base_rot)
        else:
            mujoco.mj_step(self.model, self.data, nstep=SUBSTEPS)
        self._step += 1
        if push is not None and self._step >= push.start_step + push.num_steps:
            self._push = None
        self._check_stable()
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_comPos(self.model, self.data)

    def push(self, push: Push) -> None:
        """Schedule ``push`` (replacing any pending one); it acts from its ``start_time`` on."""
        if push.start_step + push.num_steps <= self._step:
            raise ValueError(f"push at t={push.start_time:.3f} s is already over (now t={self.time:.3f} s)")
        self._push = push

    @property
    def pending_push(self) -> Push | None:
        """The scheduled or active push, if any."""
        return self._push

    def _step_pushed(self, push: Push, base_pos: np.ndarray, base_rot: np.ndarray) -> None:
        d = self.data
        point_world = base_pos + base_rot @ push.point
        torque = np.cross(point_world - d.xipos[self._trunk], push.force)
        d.xfrc_applied[self._trunk, :3] = push.force
        d.xfrc_applied[self._trunk, 3:] = torque
        if push.mode == "continuous":
            mujoco.mj_step(self.model, d, nstep=SUBSTEPS)
            d.xfrc_applied[self._trunk] = 0.0
        else:
            mujoco.mj_step(self.model, d, nstep=1)
            d.xfrc_applied[self._trunk] = 0.0
            mujoco.mj_step(self.model, d, nstep=SUBSTEPS - 1)

    # --- internals ---------------------------------------------------------------------------------

    def _write_gains(self, kp: np.ndarray, kd: np.ndarray) -> None:
        self._bias[:, 1] = -kp
        self._bias[:, 2] = -kd

    def _check_stable(self) -> None:
        # MuJoCo counts non-finite or huge qpos/qvel/qacc in its warning statistics (the model disables
        # its automatic reset, so the diverged state stays visible); the counters are zeroed by reset().
        counts = self._warning_counts
        if counts[_BAD_QPOS] or counts[_BAD_QVEL] or counts[_BAD_QACC]:
            start = (self._step - 1) * CONTROL_DT
            raise SimulationUnstableError(
                f"simulation became unstable in the control step starting at t={start:.3f} s on terrain "
                f"'{self.terrain.name}' (MuJoCo reported a non-finite or huge qpos/qvel/qacc)"
            )

    def _read_state(self) -> RobotState:
        qpos = self._qpos.copy()
        rot = np.empty(9)
        mujoco.mju_quat2Mat(rot, qpos[3:7])
        sensors = self._sensordata
        *fields, trunk_contact, fallen = state_fields(
            self.time,
            qpos,
            self._qvel.copy(),
            rot,
            self._site_xpos[self._foot_sites],
            sensors[self._foot_sensor_adr],
            sensors[self._trunk_sensor_adr],
            self._actuator_force.copy(),
            self._trunk_com.copy(),
        )
        return RobotState(*fields, trunk_contact=bool(trunk_contact), fallen=bool(fallen))


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
    readout of :meth:`A1Sim.step` and of :meth:`krl.sim.batch.SimBatch.step` (N robots at once).

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


def _check_joint_vector(value: np.ndarray, name: str) -> np.ndarray:
    array = np.asarray(value, dtype=float)
    if array.shape != (NUM_JOINTS,):
        raise ValueError(f"{name} must have shape (12,), got {array.shape}")
    if not np.isfinite(array).all():
        raise ValueError(f"{name} contains non-finite values")
    return array
