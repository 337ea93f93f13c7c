"""How fast can the kernel's gait clock run? The measurement behind ``rhythm_range`` (docs/agent-gait.md).

A gait-driving agent (:mod:`krl.agent.action`) may scale the clock that feeds the kernel its phases. Each
rate of :func:`clock_rate_walks` holds the kernel at a fixed clock rate (no residual) while it walks a fixed
command for a few seconds from the spawn point, the command ramped as ``krl kernel sweep`` ramps it; the
table gives whether it fell and the velocity it realised against the command. The bounds a policy may
choose are the rates at which the kernel alone still walks.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from krl.agent.config import ResidualConfig
from krl.agent.residual import ResidualController
from krl.control.types import JointCommand
from krl.kernel.registry import load_model
from krl.sim.model import build_model
from krl.sim.robot import A1Sim, RobotState
from krl.sim.state import StateBatch
from krl.task.runner import Runner

SWEEP_RANGE: tuple[float, float] = (0.2, 5.0)
"""The clock-rate range the sweep's controller allows (wider than any rate it is asked for)."""


class FixedRateKernel:
    """A :class:`krl.control.types.Controller`: the kernel with its gait clock at a fixed ``rate``."""

    def __init__(self, kernel: str, rate: float) -> None:
        config = ResidualConfig(
            kernel=kernel, residuals=False, drive_rhythm=True, rhythm_range=SWEEP_RANGE, gait_alpha=1.0
        )
        self.path = ResidualController(load_model(kernel), config, 1)
        self.action = self.path.parts[0].action(np.array([[rate]]))

    def reset(self, state: RobotState) -> None:
        self.path.reset()

    def act(self, state: RobotState, command: np.ndarray) -> JointCommand:
        self.path.prepare(StateBatch.from_states([state]), np.asarray(command, dtype=float)[None])
        return JointCommand(self.path.joint_targets(self.action)[0])


def clock_rate_walks(
    rates: Sequence[float],
    terrains: Sequence[str] = ("flat", "heightfield_mild"),
    command: Sequence[float] = (0.4, 0.0, 0.0),
    seconds: float = 8.0,
    kernel: str = "base",
) -> list[dict[str, Any]]:
    """One walk per terrain and rate: ``{"terrain", "rate", "fell", "seconds", "velocity" (vx, vy, wz)
    realised [m/s, m/s, rad/s], "vx_error" [m/s]}``."""
    rows = []
    for terrain in terrains:
        for rate in rates:
            sim = A1Sim(build_model(terrain, seed=0))
            result = Runner(sim, FixedRateKernel(kernel, rate)).hold_command(np.asarray(command), seconds)
            velocity = result.mean_velocity()
            rows.append(
                {
                    "terrain": terrain,
                    "rate": float(rate),
                    "fell": result.fell,
                    "seconds": round(result.sim_seconds, 3),
                    "velocity": [round(v, 4) for v in velocity],
                    "vx_error": round(velocity[0] - float(command[0]), 4),
                }
            )
    return rows
