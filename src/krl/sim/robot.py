"""The simulated A1 one robot at a time: hybrid PD control at 1 kHz inside MuJoCo, state readout, pushes,
fall detection.

:class:`A1Sim` is a simulator backend (:class:`krl.sim.backend.SimBackend`) with one robot, for code that
drives a single robot (the MPC expert, the kernel, the evaluation, the viewer): one call of
:meth:`A1Sim.step` is one 200 Hz control step of its backend, and a single robot and N robots step and
read out alike, bit for bit.
This module also names what a user of one robot needs: :class:`krl.sim.state.RobotState`, the fall rule
(:data:`krl.sim.state.FALL_TILT`), the motor envelope and :class:`SimulationUnstableError`.
"""

from __future__ import annotations

import mujoco
import numpy as np

from krl.sim.backend import SimBackend, make_backend
from krl.sim.batch import (
    SPAWN_CLEARANCE,
    SimulationUnstableError,
    joint_vector,
    motor_torque_bounds,
)
from krl.sim.model import BuiltModel
from krl.sim.pushes import Push
from krl.sim.state import FALL_TILT, RobotState, StateBatch
from krl.sim.terrains import Terrain
from krl.util.timing import CONTROL_DT

__all__ = [
    "FALL_TILT",
    "SPAWN_CLEARANCE",
    "A1Sim",
    "RobotState",
    "SimulationUnstableError",
    "motor_torque_bounds",
]


class A1Sim:
    """One simulated A1 on one terrain: a simulator backend (:class:`krl.sim.backend.SimBackend`) of one
    robot.

    Args:
        built: the compiled model (:func:`krl.sim.model.build_model`); the simulator works on a private
            copy.
        motor_envelope: limit motoring torque with speed (:func:`motor_torque_bounds`), updated once per
            control step; when False only the constant ±``MOTOR_TORQUE_LIMIT`` clamp applies.
    """

    def __init__(self, built: BuiltModel, motor_envelope: bool = True) -> None:
        self.backend: SimBackend = make_backend([built], motor_envelope=motor_envelope)
        """The simulator backend of one robot this simulator wraps (what
        :class:`krl.task.episode.EpisodeBatch` steps)."""
        self._read: tuple[StateBatch, RobotState] | None = None

    @property
    def model(self) -> mujoco.MjModel:
        """The robot's model (the simulator's private copy), for reading."""
        return self.backend.model(0)

    @property
    def data(self) -> mujoco.MjData:
        """The robot's ``MjData``, for reading (rendering, analysis)."""
        return self.backend.data(0)

    @property
    def terrain(self) -> Terrain:
        """The terrain the robot stands on."""
        return self.backend.terrain(0)

    @property
    def state(self) -> RobotState:
        """The state after the last step or reset (after a :class:`SimulationUnstableError`: the last one
        before it, marked fallen)."""
        states = self.backend.states
        if self._read is None or self._read[0] is not states:
            self._read = states, states.row(0)
        return self._read[1]

    @property
    def time(self) -> float:
        """Simulation time [s]."""
        return self.step_count * CONTROL_DT

    @property
    def step_count(self) -> int:
        """Control steps since the last reset."""
        return int(self.backend.step_counts[0])

    def reset(
        self,
        xy: tuple[float, float] | None = None,
        yaw: float = 0.0,
        joint_angles: np.ndarray | None = None,
    ) -> RobotState:
        """Put the robot at rest at ``xy`` (default: the terrain's spawn point) facing ``yaw`` [rad]
        (:meth:`krl.sim.backend.SimBackend.reset`: ``joint_angles`` default to the standing pose, shape
        (12,))."""
        self.backend.reset(0, xy=xy, yaw=yaw, joint_angles=joint_angles)
        return self.state

    def set_state(self, qpos: np.ndarray, qvel: np.ndarray) -> RobotState:
        """Put the robot in the state ``qpos`` (shape (19,)) and ``qvel`` (shape (18,)), keeping the time,
        gains and pending push (:meth:`krl.sim.backend.SimBackend.set_state`)."""
        self.backend.set_state(0, qpos, qvel)
        return self.state

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
            kd: per-joint damping [N·m·s/rad], shape (12,); default Table 4.2. Gains persist until changed.
            tau_ff: feed-forward torques [N·m], shape (12,); default zero.

        Returns the state after the step. Raises :class:`SimulationUnstableError` if the physics
        diverged and ``ValueError`` for a wrong-shaped or non-finite command.
        """
        rows = [
            None if value is None else joint_vector(value, name)[None]
            for value, name in ((q_target, "q_target"), (kp, "kp"), (kd, "kd"), (tau_ff, "tau_ff"))
        ]
        self.backend.step(*rows, raise_on_divergence=True)
        return self.state

    def push(self, push: Push) -> None:
        """Schedule ``push`` (replacing any pending one); it acts from its ``start_time`` on."""
        self.backend.push(0, push)

    @property
    def pending_push(self) -> Push | None:
        """The scheduled or active push, if any."""
        return self.backend.pending_push(0)
