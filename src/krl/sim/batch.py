"""N simulated A1s stepped together, and their states as arrays with a leading robot axis.

:class:`SimBatch` holds one :class:`krl.sim.robot.A1Sim` per robot (each on its own model, so terrains
can differ) and steps them one after the other in this process: a step of the batch is bit-identical to
stepping N single simulators, which is what lets the residual agent's batched environment promise the
transitions of N single environments. Everything around the physics (kernel, filter, IK, observation,
reward) then works on :class:`StateBatch` arrays at once. ``benchmarks/README.md`` records why this was
preferred over ``mujoco.batch.Batch`` for the agent's environment.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass, fields

import numpy as np

from krl.sim.model import BuiltModel
from krl.sim.robot import A1Sim, RobotState, SimulationUnstableError


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


_FIELD_NAMES: tuple[str, ...] = tuple(f.name for f in fields(RobotState))
if _FIELD_NAMES != tuple(f.name for f in fields(StateBatch)):  # pragma: no cover - a guard for editors
    raise RuntimeError("StateBatch must list RobotState's fields in RobotState's order")


class SimBatch:
    """N simulators stepped together.

    Args:
        models: one compiled model per robot (:func:`krl.sim.model.build_model`).
    """

    def __init__(self, models: Sequence[BuiltModel]) -> None:
        if not models:
            raise ValueError("a simulator batch needs at least one model")
        self.sims = [A1Sim(built) for built in models]
        self.unstable = np.zeros(len(self.sims), dtype=bool)
        """Robots whose physics diverged in the last :meth:`step`."""

    def __len__(self) -> int:
        return len(self.sims)

    def replace(self, index: int, built: BuiltModel) -> None:
        """Put robot ``index`` on another model (a new terrain); reset it afterwards."""
        self.sims[index] = A1Sim(built)

    def reset(self, index: int, xy: tuple[float, float] | None = None, yaw: float = 0.0) -> RobotState:
        """Reset robot ``index`` (:meth:`krl.sim.robot.A1Sim.reset`)."""
        return self.sims[index].reset(xy=xy, yaw=yaw)

    @property
    def states(self) -> StateBatch:
        """The robots' current states."""
        return StateBatch.from_states([sim.state for sim in self.sims])

    def step(self, q_target: np.ndarray) -> StateBatch:
        """One control step of every robot with joint-angle targets [rad] (shape (N, 12)) and the Table 4.2
        PD.

        A robot whose physics diverges (:class:`krl.sim.robot.SimulationUnstableError`) keeps its last
        state, marked fallen, and is flagged in :attr:`unstable` until the next step; reset it.
        """
        q_target = np.asarray(q_target, dtype=float)
        if q_target.shape != (len(self.sims), 12):
            raise ValueError(f"q_target must have shape ({len(self.sims)}, 12), got {q_target.shape}")
        states = []
        self.unstable[:] = False
        for index, (sim, q) in enumerate(zip(self.sims, q_target, strict=True)):
            try:
                states.append(sim.step(q))
            except SimulationUnstableError:
                self.unstable[index] = True
                states.append(dataclasses.replace(sim.state, fallen=True))
        return StateBatch.from_states(states)
