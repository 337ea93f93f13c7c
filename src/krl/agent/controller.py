"""The trained residual agent as a walking controller (:class:`krl.control.types.Controller`).

Each control step: the kernel's targets for the command and the gait phases, the policy's action from the
observation, the filtered residual added, IK, PD (:class:`krl.agent.residual.ResidualController`, the
object the training environment uses). The policy runs in NumPy (:mod:`krl.agent.policy`).
"""

from __future__ import annotations

import numpy as np

from krl.agent.config import ResidualConfig
from krl.agent.observation import observe
from krl.agent.policy import Policy, check_kernel_file
from krl.agent.residual import ResidualController
from krl.agent.sensing import Sensing
from krl.control.types import JointCommand
from krl.kernel.model import Kernel, load_kernel
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
        self.senses = _SceneSenses(policy)
        self.last_action = np.zeros(policy.config.residual.action_size)
        """The policy's last action, in [-1, 1]. Shape: (D,) (:mod:`krl.agent.action`)."""

    def attach(self, sims) -> None:
        """The simulator (a batch of one) whose scene the policy's height scan reads
        (:func:`krl.control.types.attach_scene`)."""
        self.senses.sims = sims

    def reset(self, state: RobotState) -> None:
        self.residual.reset()

    def act(self, state: RobotState, command: np.ndarray) -> JointCommand:
        states = StateBatch.from_states([state])
        self.residual.prepare(states, np.asarray(command, dtype=float)[None])
        inputs = self.residual.observation_inputs(states, self.senses.measure(states))
        observation = observe(self.features, inputs)
        action = self.policy.act(observation)
        self.last_action = action[0]
        return JointCommand(self.residual.joint_targets(action)[0])

    @property
    def last_targets(self) -> np.ndarray:
        """The kernel's foot targets of the last step, base frame [m]. Shape: (4, 3)."""
        return self.residual.kernel_targets[0]


class AgentBatchController:
    """The trained agent driving N robots at once, each exactly as :class:`AgentController` drives it alone:
    the kernel and the policy run row by row (:func:`krl.util.affine.affine`) for the robots walking,
    everything else batched. What batched evaluation (:mod:`krl.eval.batch`) steps.

    Args:
        policy: the trained policy.
        num_robots: N.
        kernel_path: its kernel file (default: the one its config names; checked by SHA-256).
    """

    def __init__(self, policy: Policy, num_robots: int, kernel_path: str | None = None) -> None:
        self.policy = policy
        path = check_kernel_file(policy, kernel_path, "policy")
        kernel = load_kernel(path)
        self.residual = ResidualController(kernel, policy.config.residual, num_robots, rowwise=True)
        self.features = policy.config.observation.features
        self.senses = _SceneSenses(policy)

    def attach(self, sims) -> None:
        """The simulators whose scenes the policy's height scan reads
        (:func:`krl.control.types.attach_scene`)."""
        self.senses.sims = sims

    def reset(self, index: int, state: RobotState) -> None:
        """Start robot ``index``'s new run (from ``state``)."""
        self.residual.reset([index])

    def act(
        self, states: StateBatch, commands: np.ndarray, rows: np.ndarray
    ) -> tuple[JointCommand, dict[int, Exception]]:
        """Joint targets of every robot (shape (N, 12)) for the velocity commands (shape (N, 3)); the robots
        of ``rows`` are the ones walking: only theirs are the kernel's and the policy's (the others' hold
        zero actions on their last kernel targets, and are reset before they walk again). No robot fails:
        the second item is empty."""
        _prepare_walking(self.residual, states, commands, rows)
        inputs = self.residual.observation_inputs(states, self.senses.measure(states))
        observation = observe(self.features, inputs)
        action = np.zeros((len(commands), self.residual.config.action_size))
        action[rows] = self.policy.act(observation[rows], rowwise=True)
        return JointCommand(self.residual.joint_targets(action)), {}


class _SceneSenses:
    """What a policy observes of the scene (a height scan), noise-free, from the simulators it is attached to;
    nothing for a blind policy."""

    def __init__(self, policy: Policy) -> None:
        self.sensing = Sensing(policy.config.observation)
        self.sims = None

    def measure(self, states: StateBatch) -> dict[str, np.ndarray] | None:
        if not self.sensing.needed:
            return None
        if self.sims is None:
            raise RuntimeError(
                f"the policy observes {', '.join(self.sensing.names)} and has no simulator to read it from "
                "(krl.control.types.attach_scene)"
            )
        return self.sensing.measure(self.sims, states)


class KernelBatchController:
    """A kernel at its trained gait and heights driving N robots at once (batched evaluation): the residual
    path with zero residuals, the kernel run row by row, so each robot gets exactly the joint targets
    :class:`krl.kernel.controller.KernelController` gives it alone
    (tests/eval/test_batched_evaluation.py). Kernel variants of
    :data:`krl.agent.residual.BATCHABLE_VARIANTS` only.

    Args:
        kernel: the kernel.
        num_robots: N.
    """

    def __init__(self, kernel: Kernel, num_robots: int) -> None:
        self.residual = ResidualController(kernel, ResidualConfig(), num_robots, rowwise=True)
        self._no_action = np.zeros((num_robots, self.residual.config.action_size))

    def reset(self, index: int, state: RobotState) -> None:
        """Start robot ``index``'s new run (from ``state``): its gait clock from zero."""
        self.residual.reset([index])

    def act(
        self, states: StateBatch, commands: np.ndarray, rows: np.ndarray
    ) -> tuple[JointCommand, dict[int, Exception]]:
        """Joint targets of every robot (shape (N, 12)) for the velocity commands (shape (N, 3)); the kernel
        runs for the robots of ``rows``, the ones walking (the others hold their last targets). No robot
        fails."""
        _prepare_walking(self.residual, states, commands, rows)
        return JointCommand(self.residual.joint_targets(self._no_action)), {}


def _prepare_walking(
    residual: ResidualController, states: StateBatch, commands: np.ndarray, rows: np.ndarray
) -> None:
    """The gait clocks and kernel targets of the robots ``rows`` (indices) only: a robot's row does not
    depend on the others' (the kernel runs row by row), and a robot not walking needs none."""
    if len(rows) == residual.num_robots:
        residual.prepare(states, commands)
    else:
        residual.prepare(states.rows(rows), commands[rows], rows)
