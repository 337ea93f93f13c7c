"""Types shared by the controllers."""

from __future__ import annotations

from typing import NamedTuple, Protocol

import numpy as np

from krl.sim.state import RobotState


class JointCommand(NamedTuple):
    """A hybrid per-joint command for one control step (see :meth:`krl.sim.robot.A1Sim.step`)."""

    q_target: np.ndarray
    """Joint-angle targets [rad]. Shape: (12,)."""
    kp: np.ndarray | None = None
    """Stiffness [N·m/rad], shape (12,); None: Table 4.2."""
    kd: np.ndarray | None = None
    """Damping [N·m·s/rad], shape (12,); None: Table 4.2."""
    tau_ff: np.ndarray | None = None
    """Feed-forward torques [N·m], shape (12,); None: zero."""


class Controller(Protocol):
    """What a locomotion controller offers the runners: velocity command in, joint command out."""

    def reset(self, state: RobotState) -> None:
        """Start a new run from ``state``."""

    def act(self, state: RobotState, command: np.ndarray) -> JointCommand:
        """The joint command for the next control step, given the velocity command (vx, vy, wz)."""


def attach_scene(controller, sims) -> None:
    """Give a controller that reads the scene (a perceptive agent's height scan) the simulators it acts in
    (a :class:`krl.sim.backend.SimBackend`), through its ``attach(sims)``; other controllers need nothing.
    Every loop that steps a controller calls it once, before the first step."""
    attach = getattr(controller, "attach", None)
    if attach is not None:
        attach(sims)
