"""The simulator seam: what krl asks of a simulator of N robots (:class:`SimBackend`), and the one place
that builds one (:func:`make_backend`).

Everything above this module (the episode loop, the training environment, the evaluation, the controllers)
drives robots only through :class:`SimBackend`; only a backend writes MuJoCo's data
(``tests/sim/test_mjdata_owner.py``). Today's one backend is MuJoCo on the CPU
(:class:`krl.sim.batch.SimBatch`: one ``MjData`` per robot, stepped one after the other); a batched GPU
backend (MuJoCo Warp: all N robots in one kernel launch) would be a second entry of :data:`BACKENDS` that
passes ``tests/sim/test_backend_contract.py``. ``docs/sim.md`` ("The simulator seam") says what it would
implement and what above the seam would have to move onto the device with it.

Conventions every backend keeps: robot ``index`` counts from 0 to ``len(backend) - 1``; states come as a
:class:`krl.sim.state.StateBatch` of ``(N, ...)`` host arrays in SI units (``docs/sim.md``, "RobotState");
a robot's clock counts 200 Hz control steps since its reset; a robot whose physics diverges is flagged, not
raised, unless the step is asked to raise.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol, runtime_checkable

import mujoco
import numpy as np

from krl.sim.batch import SimBatch, SimulationUnstableError
from krl.sim.model import BuiltModel
from krl.sim.pushes import Push
from krl.sim.state import RobotState, StateBatch
from krl.sim.terrains import Terrain


@runtime_checkable
class SimBackend(Protocol):
    """N simulated A1s, each on its own scene (:class:`krl.sim.model.BuiltModel`), stepped together at
    200 Hz with hybrid PD joint commands."""

    motor_envelope: bool
    """Whether motoring torque is limited with joint speed (:func:`krl.sim.batch.motor_torque_bounds`)."""

    unstable: np.ndarray
    """Robots whose physics diverged in the last :meth:`step` (until reset or set). Shape: (N,), bool."""

    def __len__(self) -> int:
        """N, the number of robots."""

    # --- one robot ---------------------------------------------------------------------------------

    def model(self, index: int) -> mujoco.MjModel:
        """Robot ``index``'s ``MjModel`` on the host, for reading (renderers, analyses)."""

    def data(self, index: int) -> mujoco.MjData:
        """Robot ``index``'s ``MjData`` on the host as the last step or reset left it, for reading."""

    def terrain(self, index: int) -> Terrain:
        """The terrain robot ``index`` stands on."""

    def replace(self, index: int, built: BuiltModel) -> RobotState:
        """Put robot ``index`` on another scene (a new terrain), at rest at its spawn point; its state."""

    def reset(
        self,
        index: int,
        xy: tuple[float, float] | None = None,
        yaw: float = 0.0,
        joint_angles: np.ndarray | None = None,
    ) -> RobotState:
        """Put robot ``index`` at rest at ``xy`` [m] (default: the terrain's spawn point) facing ``yaw``
        [rad], the joints at ``joint_angles`` [rad] (shape (12,); default: standing), the base
        ``STANDING_HEIGHT + SPAWN_CLEARANCE`` above the ground, props at rest, clock at 0, gains Table 4.2,
        no pending push; its state."""

    def set_state(self, index: int, qpos: np.ndarray, qvel: np.ndarray) -> RobotState:
        """Put robot ``index`` in ``qpos`` (shape (19,)) and ``qvel`` (shape (18,)), keeping its clock, gains
        and pending push; its state. ``ValueError`` for other shapes."""

    def push(self, index: int, push: Push) -> None:
        """Schedule ``push`` on robot ``index`` (replacing any pending one); ``ValueError`` if it is over."""

    def pending_push(self, index: int) -> Push | None:
        """Robot ``index``'s scheduled or active push, if any."""

    def divergence(self, index: int) -> SimulationUnstableError | None:
        """Why robot ``index`` is flagged in :attr:`unstable`, or None."""

    def read_state(self, index: int) -> RobotState:
        """Robot ``index``'s state read now, one robot alone (what :attr:`states` holds for it, bit for bit,
        unless it diverged)."""

    # --- all robots --------------------------------------------------------------------------------

    @property
    def step_counts(self) -> np.ndarray:
        """Control steps of each robot since its last reset. Shape: (N,), int."""

    @property
    def states(self) -> StateBatch:
        """The robots' current states (the last step's, or newer after a reset); read-only."""

    def terrain_heights(self, points: np.ndarray) -> np.ndarray:
        """Height of each robot's ground [m] under heading-frame ``points`` [m] (shape (P, 2): x forward,
        y left, origin under the trunk, turned with its yaw), moving props where they are now. Shape:
        (N, P)."""

    def step(
        self,
        q_target: np.ndarray,
        kp: np.ndarray | None = None,
        kd: np.ndarray | None = None,
        tau_ff: np.ndarray | None = None,
        raise_on_divergence: bool = False,
        rows: np.ndarray | None = None,
    ) -> StateBatch:
        """One control step (5 physics steps of 1 ms) of every robot (of ``rows``): torque
        ``kp (q_target - q) - kd q̇ + tau_ff`` [N·m] at every physics step, clipped to the motor envelope,
        a pending push acting on the trunk. Shapes: (N, 12) [rad, N·m/rad, N·m·s/rad, N·m]. Gains given
        persist; a diverged robot keeps its last state, marked fallen, and is flagged in :attr:`unstable`
        (raised when ``raise_on_divergence``); robots out of ``rows`` keep state, clock and gains.
        ``ValueError`` for a wrong-shaped, non-finite or (gains) negative command."""


BACKENDS = ("mujoco-cpu",)
"""The simulator backends krl has, the default first."""


def make_backend(
    models: Sequence[BuiltModel], motor_envelope: bool = True, kind: str = BACKENDS[0]
) -> SimBackend:
    """A simulator of ``len(models)`` robots, robot ``i`` on ``models[i]`` (each robot simulates a private
    copy), at rest at its terrain's spawn point.

    Args:
        models: one compiled scene per robot (:func:`krl.sim.model.build_model`); at least one.
        motor_envelope: limit motoring torque with joint speed; when False only the constant
            ±``MOTOR_TORQUE_LIMIT`` clamp applies.
        kind: which backend (:data:`BACKENDS`).

    Raises ``ValueError`` for an unknown ``kind`` or no models.
    """
    if kind not in BACKENDS:
        raise ValueError(f"unknown simulator backend {kind!r}; known: {', '.join(BACKENDS)}")
    return SimBatch(models, motor_envelope=motor_envelope)
