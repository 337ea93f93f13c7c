"""N simulated A1s stepped together, and their states as arrays with a leading robot axis.

:class:`SimBatch` holds one :class:`krl.sim.robot.A1Sim` per robot (each on its own model, so terrains
can differ) and steps them one after the other in this process, the physics of each exactly as
:meth:`krl.sim.robot.A1Sim.step` runs it: a step of the batch is bit-identical to stepping N single
simulators, which is what lets the residual agent's batched environment promise the transitions of N
single environments. Around the physics the batch works on all N at once: the motor envelope, and the
state readout, which gathers each robot's ``MjData`` arrays into ``(N, ...)`` arrays and computes the
:class:`StateBatch` from them with the single robot's own :func:`krl.sim.robot.state_fields`.
Everything downstream (kernel, filter, IK, observation, reward) then works on :class:`StateBatch` arrays
as well. ``benchmarks/README.md`` records why this was preferred over ``mujoco.batch.Batch``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, fields

import mujoco
import numpy as np

from krl.robots.a1.constants import NUM_JOINTS
from krl.sim.model import BuiltModel
from krl.sim.robot import A1Sim, RobotState, SimulationUnstableError, _torque_bounds_into, state_fields
from krl.util.timing import CONTROL_DT


@dataclass(slots=True)
class StateBatch:
    """The fields of :class:`krl.sim.robot.RobotState` for N robots, each with a leading axis of N.

    Shapes: ``time`` (N,), ``base_pos`` (N, 3), ``base_quat`` (N, 4), ``base_rot`` (N, 3, 3), ``rpy``
    (N, 3), ``projected_gravity``/``lin_vel_*``/``ang_vel_*``/``com`` (N, 3), ``joint_*`` (N, 12),
    ``foot_pos_*`` (N, 4, 3), ``foot_force``/``foot_contact`` (N, 4), ``trunk_contact``/``fallen`` (N,).
    Units and frames as in :class:`krl.sim.robot.RobotState`.
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
        return cls(*(np.array([getattr(s, name) for s in states]) for name in _FIELD_NAMES))

    def __len__(self) -> int:
        return len(self.time)

    def rows(self, index: np.ndarray | slice) -> StateBatch:
        """The robots ``index`` selects (an index array or a slice), as a new batch of copies."""
        return StateBatch(*(np.array(getattr(self, name)[index]) for name in _FIELD_NAMES))

    def row(self, index: int) -> RobotState:
        """Robot ``index`` as a single state (copies of its rows)."""
        values = {name: getattr(self, name)[index] for name in _FIELD_NAMES}
        return RobotState(
            **{name: value.copy() for name, value in values.items() if isinstance(value, np.ndarray)},
            time=float(values["time"]),
            trunk_contact=bool(values["trunk_contact"]),
            fallen=bool(values["fallen"]),
        )


_FIELD_NAMES: tuple[str, ...] = tuple(f.name for f in fields(RobotState))
if _FIELD_NAMES != tuple(f.name for f in fields(StateBatch)):  # pragma: no cover - a guard for editors
    raise RuntimeError("StateBatch must list RobotState's fields in RobotState's order")


def _readout_layout(sim: A1Sim) -> tuple[int, int, tuple[list[int], list[int], int]]:
    """The first foot site and the first of the touch sensors in ``sim``'s model, and the feet's and the
    sensors' places from there: ``(foot sites, foot sensors, trunk sensor)`` (other sites, e.g. a course's
    markers, may come before the robot's)."""
    site_start = int(sim._foot_sites.min())
    sensor_start = int(min(sim._foot_sensor_adr.min(), sim._trunk_sensor_adr))
    layout = (
        [int(i) - site_start for i in sim._foot_sites],
        [int(i) - sensor_start for i in sim._foot_sensor_adr],
        sim._trunk_sensor_adr - sensor_start,
    )
    return site_start, sensor_start, layout


class SimBatch:
    """N simulators stepped together.

    The batch keeps the robots' states (:attr:`states`): step and reset its simulators through
    :meth:`step` and :meth:`reset` only (pushes may be scheduled on them directly).

    Args:
        models: one compiled model per robot (:func:`krl.sim.model.build_model`).
    """

    def __init__(self, models: Sequence[BuiltModel]) -> None:
        if not models:
            raise ValueError("a simulator batch needs at least one model")
        self.sims = [A1Sim(built) for built in models]
        self._layout = _readout_layout(self.sims[0])[2]
        """Where the readout finds the feet in the ``site_xpos`` rows it copies, and the feet's and the
        trunk's touch sensors in the ``sensordata`` it copies: the same in every A1 model."""
        self._views = [self._readout_views(sim) for sim in self.sims]
        self.unstable = np.zeros(len(self.sims), dtype=bool)
        """Robots whose physics diverged in the last :meth:`step`."""
        self._states = StateBatch.from_states([sim.state for sim in self.sims])

    def __len__(self) -> int:
        return len(self.sims)

    def _readout_views(self, sim: A1Sim) -> tuple[np.ndarray, ...]:
        """The views into ``sim``'s MjData a step reads: qpos, qvel, foot sites, sensors, torques, CoM."""
        site_start, sensor_start, layout = _readout_layout(sim)
        if layout != self._layout:
            raise ValueError("a simulator batch needs models whose A1 sites and sensors lie alike")
        feet, foot_sensors, trunk_sensor = layout
        sites = sim._site_xpos[site_start : site_start + max(feet) + 1]
        sensors = sim._sensordata[sensor_start : sensor_start + max(*foot_sensors, trunk_sensor) + 1]
        return sim._qpos, sim._qvel, sites, sensors, sim._actuator_force, sim._trunk_com

    def replace(self, index: int, built: BuiltModel) -> None:
        """Put robot ``index`` on another model (a new terrain); reset it afterwards."""
        sim = A1Sim(built)
        self._views[index] = self._readout_views(sim)
        self.sims[index] = sim
        self._reload(index)

    def reset(self, index: int, xy: tuple[float, float] | None = None, yaw: float = 0.0) -> RobotState:
        """Reset robot ``index`` (:meth:`krl.sim.robot.A1Sim.reset`)."""
        state = self.sims[index].reset(xy=xy, yaw=yaw)
        self._reload(index)
        return state

    def _reload(self, index: int) -> None:
        """Take robot ``index``'s state from its simulator (after a reset) into a new :attr:`states`."""
        states = self._states.rows(slice(None))
        state = self.sims[index].state
        for name in _FIELD_NAMES:
            getattr(states, name)[index] = getattr(state, name)
        self._states = states

    @property
    def states(self) -> StateBatch:
        """The robots' current states (the batch the last :meth:`step` returned, or newer after a reset);
        treat it as read-only."""
        return self._states

    def step(self, q_target: np.ndarray) -> StateBatch:
        """One control step of every robot with joint-angle targets [rad] (shape (N, 12)) and the Table 4.2
        PD.

        Each robot's physics is :meth:`krl.sim.robot.A1Sim.step`'s (its pushes included); the motor
        envelope and the readout are computed for all N at once. A robot whose physics diverges
        (:class:`krl.sim.robot.SimulationUnstableError`) keeps its last state, marked fallen, and is
        flagged in :attr:`unstable` until the next step; reset it. Raises ``ValueError`` for a
        wrong-shaped or non-finite ``q_target``.
        """
        q_target = np.asarray(q_target, dtype=float)
        n = len(self.sims)
        if q_target.shape != (n, NUM_JOINTS):
            raise ValueError(f"q_target must have shape ({n}, 12), got {q_target.shape}")
        if not np.isfinite(q_target).all():
            raise ValueError("q_target contains non-finite values")
        previous = self._states
        joint_vel = np.array([sim._qvel[6 : 6 + NUM_JOINTS] for sim in self.sims])  # [rad/s]
        bounds = np.empty((n, NUM_JOINTS, 2))  # the actuators' force ranges, (lower, upper) [N·m]
        _torque_bounds_into(joint_vel, bounds[..., 0], bounds[..., 1])
        self.unstable[:] = False
        for index, (sim, q) in enumerate(zip(self.sims, q_target, strict=True)):
            np.multiply(sim._kp, q, out=sim._ctrl)
            if sim.motor_envelope:
                sim._forcerange[:] = bounds[index]
            try:
                sim._physics_step(previous.base_pos[index], previous.base_rot[index])
            except SimulationUnstableError:
                self.unstable[index] = True
                sim._state = previous.row(index)
            else:
                sim._state = None  # read from its MjData when asked for
        # what the robots' MjData hold after the step (zero where a robot diverged: its last state is kept)
        qpos, qvel, sites, sensors, torque, com = (
            np.array(views) for views in zip(*self._views, strict=True)
        )
        diverged = np.flatnonzero(self.unstable)
        if len(diverged):
            for raw in (qpos, qvel, sites, sensors, torque, com):
                raw[diverged] = 0.0
        rot = np.empty((n, 9))
        for matrix, quat in zip(rot, qpos[:, 3:7], strict=True):
            mujoco.mju_quat2Mat(matrix, quat)
        feet, foot_sensors, trunk_sensor = self._layout
        states = StateBatch(
            *state_fields(
                np.array([sim._step for sim in self.sims]) * CONTROL_DT,
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
        for index in diverged:
            for name in _FIELD_NAMES:
                getattr(states, name)[index] = getattr(previous, name)[index]
            states.fallen[index] = True
        self._states = states
        return states
