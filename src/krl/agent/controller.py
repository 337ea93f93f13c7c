"""The trained residual agent as a walking controller (:class:`krl.control.types.Controller`).

Each control step: the kernel's targets for the command and the gait phases, the policy's action from the
observation, the filtered residual added, IK, PD (:class:`krl.agent.residual.ResidualController`, the
object the training environment uses). The policy runs in NumPy (:mod:`krl.agent.policy`).
"""

from __future__ import annotations

import numpy as np

from krl.agent.observation import observe
from krl.agent.policy import Policy, check_kernel_file
from krl.agent.residual import ResidualController
from krl.control.types import JointCommand
from krl.kernel.model import load_kernel
from krl.sim.state import RobotState, StateBatch


class AgentController:
    """Implements :class:`krl.control.types.Controller` with a trained policy and its kernel.

    Args:
        policy: the trained policy.
        kernel_path: its kernel file (default: the one its config names; checked by SHA-256).
    """

    def __init__(self, policy: Policy, kernel_path: str | None = None) -> None:
        self.policy = policy
        path = check_kernel_file(policy, kernel_path, "policy")
        self.residual = ResidualController(load_kernel(path), policy.config.residual, 1)
        self.features = policy.config.observation.features
        self.last_action = np.zeros(policy.config.residual.action_size)
        """The policy's last action, in [-1, 1]. Shape: (D,) (:mod:`krl.agent.action`)."""

    def reset(self, state: RobotState) -> None:
        self.residual.reset()

    def act(self, state: RobotState, command: np.ndarray) -> JointCommand:
        states = StateBatch.from_states([state])
        self.residual.prepare(states, np.asarray(command, dtype=float)[None])
        observation = observe(self.features, self.residual.observation_inputs(states))
        action = self.policy.act(observation)
        self.last_action = action[0]
        return JointCommand(self.residual.joint_targets(action)[0])

    @property
    def last_targets(self) -> np.ndarray:
        """The kernel's foot targets of the last step, base frame [m]. Shape: (4, 3)."""
        return self.residual.kernel_targets[0]
