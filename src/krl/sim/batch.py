"""N simulated A1s, each on its own terrain, stepped together: the one owner of MuJoCo's data in krl.

:class:`SimBatch` holds one ``MjModel``/``MjData`` pair per robot (the models are private copies, because
the PD gains and the motor envelope are written into them every step; so terrain, ground friction, gains
and pushes are each robot's own) and is the only code in krl that writes ``MjData``. One
:meth:`SimBatch.step` is one 200 Hz control step of every robot: it writes the joint commands into the
actuators (``ctrl = kp * q_target + tau_ff`` with ``kp``/``kd`` in the actuators' bias parameters, so MuJoCo
evaluates ``tau = kp (q_target - q) - kd q̇ + tau_ff`` at every 1 ms physics step), runs the five physics
steps in one ``mj_step`` call (a pending push acts on the trunk), refreshes positions (``mj_kinematics``,
``mj_comPos``) and reads every robot's state out at once into a :class:`krl.sim.state.StateBatch`
(:func:`krl.sim.state.state_fields` on ``(N, ...)`` copies of the ``MjData`` arrays). The physics runs one
robot after the other in this process; the motor envelope and the readout are computed for all N together.
A single robot is the batch of one (:class:`krl.sim.robot.A1Sim`).

:class:`SimBatch` is the MuJoCo CPU implementation of the simulator seam,
:class:`krl.sim.backend.SimBackend`, and is built through :func:`krl.sim.backend.make_backend`: nothing
outside this module sees how the physics is stepped. ``benchmarks/README.md`` records why the CPU batch
keeps one ``MjData`` per robot rather than ``mujoco.batch.Batch``. Plain MuJoCo without krl around it (the
benchmarks' floor, :class:`BarePhysics`; a logged frame posed for drawing, :func:`pose_for_drawing`) is
written here too, so that this module stays the only one that writes ``MjData``.
"""

from __future__ import annotations

import copy
import time
from collections.abc import Sequence

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
from krl.sim.scan import GroundStack, TerrainScanner, heading_points_to_world
from krl.sim.state import FIELD_NAMES, RobotState, StateBatch, state_fields
from krl.sim.terrains import Terrain
from krl.util.timing import CONTROL_DT, SUBSTEPS

_BAD_QPOS = int(mujoco.mjtWarning.mjWARN_BADQPOS)
_BAD_QVEL = int(mujoco.mjtWarning.mjWARN_BADQVEL)
_BAD_QACC = int(mujoco.mjtWarning.mjWARN_BADQACC)

SPAWN_CLEARANCE: float = 0.01
"""Height added above the standing height at reset so the feet start just above the ground [m]."""


class SimulationUnstableError(RuntimeError):
    """The physics diverged (non-finite or exploding state); the episode cannot go on."""


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


class _Robot:
    """One robot's MuJoCo model and data, the views into them a step uses, its gains, clock and push."""

    def __init__(self, built: BuiltModel) -> None:
        self.model = copy.copy(built.model)
        self.terrain = built.terrain
        self.data = mujoco.MjData(self.model)
        m = self.model
        self.trunk = m.body("trunk").id
        self.foot_sites = np.array([m.site(name).id for name in FOOT_NAMES])
        self.foot_sensor_adr = np.array([m.sensor_adr[m.sensor(name).id] for name in FOOT_NAMES])
        self.trunk_sensor_adr = int(m.sensor_adr[m.sensor("trunk_contact").id])
        actuator_ids = [m.actuator(name).id for name in JOINT_NAMES]
        if actuator_ids != list(range(NUM_JOINTS)):
            raise RuntimeError("A1 model: actuators must be the first 12, in krl joint order")
        joint_qpos = [m.jnt_qposadr[m.joint(name).id] for name in JOINT_NAMES]
        if joint_qpos != list(range(7, 7 + NUM_JOINTS)):
            raise RuntimeError("A1 model: joint qpos must follow the free joint, in krl joint order")
        self.bias = m.actuator_biasprm[:NUM_JOINTS]
        self.forcerange = m.actuator_forcerange[:NUM_JOINTS]
        """The actuators' force ranges, (lower, upper) [N·m]: the motor envelope writes them in place."""
        self.kp = KP.copy()
        self.kd = KD.copy()
        self.write_gains()
        self.warning_counts = self.data.warning.number  # a view into MjData
        self.step = 0
        self.push: Push | None = None
        # views into MjData read after every step (MjData's attributes make a new array on every access)
        self.ctrl = self.data.ctrl[:NUM_JOINTS]
        self.qpos = self.data.qpos[:19]
        self.qvel = self.data.qvel[:18]
        self.site_xpos = self.data.site_xpos
        self.sensordata = self.data.sensordata
        self.actuator_force = self.data.actuator_force[:NUM_JOINTS]
        self.trunk_com = self.data.subtree_com[self.trunk]
        self.scanner: TerrainScanner | None = None
        """The terrain's height scanner, made on first use (:meth:`SimBatch.terrain_heights`)."""

    def readout_layout(self) -> tuple[int, int, tuple[list[int], list[int], int]]:
        """The first foot site and the first of the touch sensors in the model, and the feet's and the
        sensors' places from there: ``(foot sites, foot sensors, trunk sensor)`` (other sites, e.g. a
        course's markers, may come before the robot's)."""
        site_start = int(self.foot_sites.min())
        sensor_start = int(min(self.foot_sensor_adr.min(), self.trunk_sensor_adr))
        layout = (
            [int(i) - site_start for i in self.foot_sites],
            [int(i) - sensor_start for i in self.foot_sensor_adr],
            self.trunk_sensor_adr - sensor_start,
        )
        return site_start, sensor_start, layout

    def reset(self, xy: tuple[float, float] | None, yaw: float, joint_angles: np.ndarray | None) -> None:
        mujoco.mj_resetData(self.model, self.data)
        x, y = self.terrain.spawn_xy if xy is None else xy
        ground = float(np.asarray(self.terrain.height(np.array([x]), np.array([y])))[0])
        angles = STANDING_JOINT_ANGLES if joint_angles is None else joint_vector(joint_angles, "joint_angles")
        qpos = self.data.qpos
        qpos[0:3] = (x, y, ground + STANDING_HEIGHT + SPAWN_CLEARANCE)
        qpos[3:7] = (np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2))
        qpos[7:19] = angles
        self.step = 0
        self.push = None
        self.kp[:] = KP
        self.kd[:] = KD
        self.write_gains()
        self.data.ctrl[:NUM_JOINTS] = self.kp * angles
        mujoco.mj_forward(self.model, self.data)

    def set_gains(self, kp: np.ndarray, kd: np.ndarray) -> None:
        if not (np.array_equal(kp, self.kp) and np.array_equal(kd, self.kd)):
            self.kp[:] = kp
            self.kd[:] = kd
            self.write_gains()

    def write_gains(self) -> None:
        self.bias[:, 1] = -self.kp
        self.bias[:, 2] = -self.kd

    def physics_step(self, base_pos: np.ndarray, base_rot: np.ndarray) -> None:
        """The physics of one control step once the actuators hold the command and the motor envelope:
        the five physics steps (with the pending push), the stability check and the kinematics the
        readout needs. ``base_pos`` [m] (shape (3,)) and ``base_rot`` (shape (3, 3)): the trunk's pose
        before the step, as the last readout gave it; a push acts there. Raises
        :class:`SimulationUnstableError`."""
        push = self.push
        if push is not None and push.active_at(self.step):
            self.step_pushed(push, base_pos, base_rot)
        else:
            mujoco.mj_step(self.model, self.data, nstep=SUBSTEPS)
        self.step += 1
        if push is not None and self.step >= push.start_step + push.num_steps:
            self.push = None
        self.check_stable()
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_comPos(self.model, self.data)

    def step_pushed(self, push: Push, base_pos: np.ndarray, base_rot: np.ndarray) -> None:
        d = self.data
        point_world = base_pos + base_rot @ push.point
        torque = np.cross(point_world - d.xipos[self.trunk], push.force)
        d.xfrc_applied[self.trunk, :3] = push.force
        d.xfrc_applied[self.trunk, 3:] = torque
        if push.mode == "continuous":
            mujoco.mj_step(self.model, d, nstep=SUBSTEPS)
            d.xfrc_applied[self.trunk] = 0.0
        else:
            mujoco.mj_step(self.model, d, nstep=1)
            d.xfrc_applied[self.trunk] = 0.0
            mujoco.mj_step(self.model, d, nstep=SUBSTEPS - 1)

    def check_stable(self) -> None:
        # MuJoCo counts non-finite or huge qpos/qvel/qacc in its warning statistics (the model disables
        # its automatic reset, so the diverged state stays visible); the counters are zeroed by reset().
        counts = self.warning_counts
        if counts[_BAD_QPOS] or counts[_BAD_QVEL] or counts[_BAD_QACC]:
            start = (self.step - 1) * CONTROL_DT
            raise SimulationUnstableError(
                f"simulation became unstable in the control step starting at t={start:.3f} s on terrain "
                f"'{self.terrain.name}' (MuJoCo reported a non-finite or huge qpos/qvel/qacc)"
            )

    def read_state(self) -> RobotState:
        qpos = self.qpos.copy()
        rot = np.empty(9)
        mujoco.mju_quat2Mat(rot, qpos[3:7])
        sensors = self.sensordata
        *fields, trunk_contact, fallen = state_fields(
            self.step * CONTROL_DT,
            qpos,
            self.qvel.copy(),
            rot,
            self.site_xpos[self.foot_sites],
            sensors[self.foot_sensor_adr],
            sensors[self.trunk_sensor_adr],
            self.actuator_force.copy(),
            self.trunk_com.copy(),
        )
        return RobotState(*fields, trunk_contact=bool(trunk_contact), fallen=bool(fallen))


class SimBatch:
    """N simulated A1s stepped together.

    The batch keeps the robots' states (:attr:`states`); every change of a robot goes through its methods.
    ``model(i)`` and ``data(i)`` hand robot ``i``'s MuJoCo structures out for reading (rendering, analysis).

    Args:
        models: one compiled model per robot (:func:`krl.sim.model.build_model`); each robot simulates a
            private copy.
        motor_envelope: limit motoring torque with speed (:func:`motor_torque_bounds`), updated once per
            control step; when False only the constant ±``MOTOR_TORQUE_LIMIT`` clamp applies.
    """

    def __init__(self, models: Sequence[BuiltModel], motor_envelope: bool = True) -> None:
        if not models:
            raise ValueError("a simulator batch needs at least one model")
        self.motor_envelope = motor_envelope
        self._robots = [_Robot(built) for built in models]
        self._layout = self._robots[0].readout_layout()[2]
        """Where the readout finds the feet in the ``site_xpos`` rows it copies, and the feet's and the
        trunk's touch sensors in the ``sensordata`` it copies: the same in every A1 model."""
        self._views = [self._readout_views(robot) for robot in self._robots]
        self.unstable = np.zeros(len(self._robots), dtype=bool)
        self._ground = GroundStack()
        """The robots' fixed ground, read at once by :meth:`terrain_heights`."""
        """Robots whose physics diverged in the last :meth:`step`. Shape: (N,), bool."""
        self._errors: list[SimulationUnstableError | None] = [None] * len(self._robots)
        for robot in self._robots:
            robot.reset(None, 0.0, None)
        self._states = StateBatch.from_states([robot.read_state() for robot in self._robots])

    def __len__(self) -> int:
        return len(self._robots)

    def _readout_views(self, robot: _Robot) -> tuple[np.ndarray, ...]:
        """The views into ``robot``'s MjData a step reads: qpos, qvel, foot sites, sensors, torques, CoM."""
        site_start, sensor_start, layout = robot.readout_layout()
        if layout != self._layout:
            raise ValueError("a simulator batch needs models whose A1 sites and sensors lie alike")
        feet, foot_sensors, trunk_sensor = layout
        sites = robot.site_xpos[site_start : site_start + max(feet) + 1]
        sensors = robot.sensordata[sensor_start : sensor_start + max(*foot_sensors, trunk_sensor) + 1]
        return robot.qpos, robot.qvel, sites, sensors, robot.actuator_force, robot.trunk_com

    # --- one robot ---------------------------------------------------------------------------------

    def model(self, index: int) -> mujoco.MjModel:
        """Robot ``index``'s model (its private copy), for reading."""
        return self._robots[index].model

    def data(self, index: int) -> mujoco.MjData:
        """Robot ``index``'s ``MjData``, for reading (rendering, analysis)."""
        return self._robots[index].data

    def terrain(self, index: int) -> Terrain:
        """The terrain robot ``index`` stands on."""
        return self._robots[index].terrain

    @property
    def step_counts(self) -> np.ndarray:
        """Control steps of each robot since its last reset. Shape: (N,), int."""
        return np.array([robot.step for robot in self._robots])

    def replace(self, index: int, built: BuiltModel) -> RobotState:
        """Put robot ``index`` on another model (a new terrain), at rest at its spawn point; returns its
        state."""
        robot = _Robot(built)
        robot.reset(None, 0.0, None)
        self._views[index] = self._readout_views(robot)
        self._robots[index] = robot
        return self._reload(index)

    def reset(
        self,
        index: int,
        xy: tuple[float, float] | None = None,
        yaw: float = 0.0,
        joint_angles: np.ndarray | None = None,
    ) -> RobotState:
        """Put robot ``index`` at rest at ``xy`` (default: the terrain's spawn point) facing ``yaw`` [rad];
        returns its state.

        The base is placed ``STANDING_HEIGHT + SPAWN_CLEARANCE`` above the terrain's rest height, with the
        joints at ``joint_angles`` (default: standing pose, shape (12,)); props return to rest, the clock
        to zero, the gains to Table 4.2, and a pending push is dropped.
        """
        self._robots[index].reset(xy, yaw, joint_angles)
        return self._reload(index)

    def set_state(self, index: int, qpos: np.ndarray, qvel: np.ndarray) -> RobotState:
        """Put robot ``index`` in the state ``qpos`` (the free joint, then the 12 joints; shape (19,)) and
        ``qvel`` (shape (18,)), keeping its clock, gains and pending push; returns its readout (after
        ``mj_forward``). The next :meth:`step` starts from it."""
        qpos, qvel = np.asarray(qpos, dtype=float), np.asarray(qvel, dtype=float)
        if qpos.shape != (19,) or qvel.shape != (18,):
            raise ValueError(
                f"qpos and qvel must have shapes (19,) and (18,), got {qpos.shape}, {qvel.shape}"
            )
        robot = self._robots[index]
        robot.qpos[:] = qpos
        robot.qvel[:] = qvel
        mujoco.mj_forward(robot.model, robot.data)
        return self._reload(index)

    def push(self, index: int, push: Push) -> None:
        """Schedule ``push`` on robot ``index`` (replacing any pending one); it acts from its start on."""
        robot = self._robots[index]
        if push.start_step + push.num_steps <= robot.step:
            now = robot.step * CONTROL_DT
            raise ValueError(f"push at t={push.start_time:.3f} s is already over (now t={now:.3f} s)")
        robot.push = push

    def pending_push(self, index: int) -> Push | None:
        """Robot ``index``'s scheduled or active push, if any."""
        return self._robots[index].push

    def divergence(self, index: int) -> SimulationUnstableError | None:
        """Why robot ``index`` is flagged in :attr:`unstable` (its physics diverged in the last step), or
        None."""
        return self._errors[index]

    def read_state(self, index: int) -> RobotState:
        """Robot ``index``'s state read from its ``MjData`` now, by the one-robot readout (what
        :attr:`states` holds for it, bit for bit, unless it diverged)."""
        return self._robots[index].read_state()

    def _reload(self, index: int) -> RobotState:
        """Read robot ``index``'s state (after a reset) into a new :attr:`states`; returns it."""
        states = self._states.rows(slice(None))
        state = self._robots[index].read_state()
        for name in FIELD_NAMES:
            getattr(states, name)[index] = getattr(state, name)
        self._states = states
        self.unstable[index] = False
        self._errors[index] = None
        return state

    # --- all robots --------------------------------------------------------------------------------

    def terrain_heights(self, points: np.ndarray) -> np.ndarray:
        """Height of the terrain's surface [m] under heading-frame ``points`` [m] (shape (P, 2): x forward,
        y left, origin under each robot's trunk, turned with its yaw), as each scene stands now: moving
        props where they are (:mod:`krl.sim.scan`). Shape: (N, P)."""
        states = self._states
        xy = heading_points_to_world(points, states.base_pos, states.rpy[:, 2])
        heights = self._ground.heights([robot.terrain for robot in self._robots], xy)
        for index, robot in enumerate(self._robots):
            if robot.scanner is None:
                robot.scanner = TerrainScanner(robot.model, robot.terrain)
            if len(robot.scanner.moving_boxes):
                heights[index] = robot.scanner.add_props(robot.data, xy[index], heights[index])
        return heights

    @property
    def states(self) -> StateBatch:
        """The robots' current states (the batch the last :meth:`step` returned, or newer after a reset);
        treat it as read-only."""
        return self._states

    def step(
        self,
        q_target: np.ndarray,
        kp: np.ndarray | None = None,
        kd: np.ndarray | None = None,
        tau_ff: np.ndarray | None = None,
        raise_on_divergence: bool = False,
        rows: np.ndarray | None = None,
    ) -> StateBatch:
        """One control step (5 physics steps of 1 ms) of every robot (of ``rows``) with a hybrid joint
        command.

        Args:
            q_target: joint angle targets [rad]. Shape: (N, 12).
            kp: per-joint stiffness [N·m/rad], shape (N, 12); 0 makes a joint torque-controlled.
            kd: per-joint damping [N·m·s/rad], shape (N, 12). When either is given the other defaults to
                Table 4.2; when neither is, each robot keeps the gains it had (Table 4.2 after a reset).
            tau_ff: feed-forward torques [N·m], shape (N, 12); default zero.
            raise_on_divergence: raise the first diverged robot's :class:`SimulationUnstableError` after
                the step, instead of only flagging it.
            rows: the robots to step (indices); the others keep their state, clock and gains (their rows
                of the command are not used). None: every robot.

        A robot whose physics diverges keeps its last state, marked fallen, and is flagged in
        :attr:`unstable` until it is reset or set. Raises ``ValueError`` for a wrong-shaped, non-finite or
        (gains) negative command.
        """
        n = len(self._robots)
        q_target = joint_rows(q_target, n, "q_target")
        if kp is not None or kd is not None:
            kp = np.broadcast_to(KP, (n, NUM_JOINTS)) if kp is None else joint_rows(kp, n, "kp")
            kd = np.broadcast_to(KD, (n, NUM_JOINTS)) if kd is None else joint_rows(kd, n, "kd")
            if np.any(kp < 0) or np.any(kd < 0):
                raise ValueError("kp and kd must be >= 0")
        stepped = range(n) if rows is None else np.unique(np.asarray(rows, dtype=np.int64)).tolist()
        if kp is not None:
            for index in stepped:
                self._robots[index].set_gains(kp[index], kd[index])
        if tau_ff is not None:
            tau_ff = joint_rows(tau_ff, n, "tau_ff")
        previous = self._states
        self._physics(q_target, tau_ff, previous, stepped)
        held = np.ones(n, dtype=bool)
        held[list(stepped)] = False
        self._states = states = self._readout(previous, held)
        if raise_on_divergence and self.unstable.any():
            raise self.divergence(int(np.flatnonzero(self.unstable)[0]))
        return states

    def _physics(
        self, q_target: np.ndarray, tau_ff: np.ndarray | None, previous: StateBatch, stepped
    ) -> None:
        """The actuators, motor envelope and physics of the robots ``stepped`` (indices) for one control
        step (a diverged robot is flagged in :attr:`unstable`)."""
        n = len(self._robots)
        lower, upper = np.empty((n, NUM_JOINTS)), np.empty((n, NUM_JOINTS))  # force ranges [N·m]
        if self.motor_envelope:
            joint_vel = np.array([robot.qvel[6 : 6 + NUM_JOINTS] for robot in self._robots])  # [rad/s]
            _torque_bounds_into(joint_vel, lower, upper)
        self.unstable[:] = False
        for index in stepped:
            robot = self._robots[index]
            np.multiply(robot.kp, q_target[index], out=robot.ctrl)
            if tau_ff is not None:
                robot.ctrl += tau_ff[index]
            if self.motor_envelope:
                robot.forcerange[:, 0] = lower[index]
                robot.forcerange[:, 1] = upper[index]
            try:
                robot.physics_step(previous.base_pos[index], previous.base_rot[index])
            except SimulationUnstableError as error:
                self.unstable[index] = True
                self._errors[index] = error
            else:
                self._errors[index] = None

    def _readout(self, previous: StateBatch, held: np.ndarray) -> StateBatch:
        """The robots' states from their ``MjData`` after a step (a diverged robot's: its previous state,
        marked fallen; a robot ``held`` (shape (N,), bool) out of the step: its previous state)."""
        n = len(self._robots)
        # what the robots' MjData hold after the step (zero where a robot diverged or was held: kept)
        qpos, qvel, sites, sensors, torque, com = (
            np.array(views) for views in zip(*self._views, strict=True)
        )
        diverged = np.flatnonzero(self.unstable)
        kept = np.flatnonzero(self.unstable | held)
        if len(kept):
            for raw in (qpos, qvel, sites, sensors, torque, com):
                raw[kept] = 0.0
        rot = np.empty((n, 9))
        for matrix, quat in zip(rot, qpos[:, 3:7], strict=True):
            mujoco.mju_quat2Mat(matrix, quat)
        feet, foot_sensors, trunk_sensor = self._layout
        states = StateBatch(
            *state_fields(
                self.step_counts * CONTROL_DT,
                qpos,
                qvel,
                rot,
                sites[:, feet],
                sensors[:, foot_sensors],
                sensors[:, trunk_sensor],
                torque,
                com,
            )
        )
        for index in kept:
            for name in FIELD_NAMES:
                getattr(states, name)[index] = getattr(previous, name)[index]
        states.fallen[diverged] = True
        return states


class BarePhysics:
    """Plain MuJoCo on a private copy of one robot's scene, with nothing of krl around it: the floor the
    benchmarks set the simulator's cost against. It starts, and :meth:`reset` puts it back, in the state
    :meth:`SimBatch.reset` gives (standing at the spawn point) with constant controls that hold the
    standing pose at Table 4.2's gains; no motor envelope, no readout."""

    def __init__(self, built: BuiltModel) -> None:
        self._robot = _Robot(built)
        self.reset()

    def reset(self) -> None:
        """Back to the standing reset state."""
        self._robot.reset(None, 0.0, None)

    def seconds(self, steps: int, nstep: int = SUBSTEPS) -> float:
        """Wall seconds of ``steps`` calls of ``mj_step(nstep=nstep)`` (default: one control step each)."""
        robot = self._robot
        start = time.perf_counter()
        for _ in range(steps):
            mujoco.mj_step(robot.model, robot.data, nstep=nstep)
        return time.perf_counter() - start

    @property
    def contacts(self) -> int:
        """The contacts of the last physics step."""
        return int(self._robot.data.ncon)


def pose_for_drawing(model: mujoco.MjModel, data: mujoco.MjData, qpos: np.ndarray) -> None:
    """Put ``data`` (a renderer's own ``MjData`` of ``model``, never a simulator's) in the pose ``qpos``
    (shape (model.nq,)) with its positions computed (``mj_forward``), to draw a logged frame."""
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)


def joint_vector(value: np.ndarray, name: str) -> np.ndarray:
    """``value`` as a finite float vector of the 12 joints, or ``ValueError`` naming ``name``."""
    array = np.asarray(value, dtype=float)
    if array.shape != (NUM_JOINTS,):
        raise ValueError(f"{name} must have shape (12,), got {array.shape}")
    if not np.isfinite(array).all():
        raise ValueError(f"{name} contains non-finite values")
    return array


def joint_rows(value: np.ndarray, n: int, name: str) -> np.ndarray:
    """``value`` as finite float rows of the 12 joints for ``n`` robots, or ``ValueError`` naming ``name``."""
    array = np.asarray(value, dtype=float)
    if array.shape != (n, NUM_JOINTS):
        raise ValueError(f"{name} must have shape ({n}, 12), got {array.shape}")
    if not np.isfinite(array).all():
        raise ValueError(f"{name} contains non-finite values")
    return array
