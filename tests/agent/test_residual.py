"""The residual action path: zero action = the kernel, the filter's state, the scaling bounds."""

from __future__ import annotations

import numpy as np
import pytest
from agent_fakes import make_policy

from krl.agent.config import AgentConfig, AgentConfigError, ResidualConfig
from krl.agent.controller import AgentController
from krl.agent.residual import ResidualController
from krl.kernel.controller import KernelController
from krl.kernel.registry import load_model
from krl.sim.model import build_model
from krl.sim.robot import A1Sim
from krl.sim.state import StateBatch
from krl.task.runner import Runner


def test_zero_action_reproduces_the_kernels_joint_targets_exactly():
    config = AgentConfig()
    agent = AgentController(make_policy(config, scale=0.0))
    kernel = KernelController(load_model("base"))
    sims = [A1Sim(build_model("heightfield", seed=4)) for _ in range(2)]
    commands = []
    for controller, sim in zip((agent, kernel), sims, strict=True):
        joint_targets = []

        def on_step(record, out=joint_targets):
            out.append(record.joint_command.q_target.copy())

        runner = Runner(sim, controller, on_step=on_step)
        runner.walk_to(np.array([[1.5, 0.5]]), target_time_limit=2.0)
        commands.append(np.array(joint_targets))
    assert commands[0].shape == commands[1].shape and len(commands[0]) > 100
    np.testing.assert_array_equal(commands[0], commands[1])


def test_the_filter_follows_eq_4_4_and_resets_per_robot():
    config = ResidualConfig(residual_bound=(0.02, 0.03, 0.04), residual_alpha=0.1)
    residual = ResidualController(load_model("base"), config, 2)
    sim = A1Sim(build_model("flat"))
    states = StateBatch.from_states([sim.state, sim.state])
    action = np.ones((2, 12))
    expected = np.zeros((4, 3))
    for _ in range(3):
        residual.prepare(states, np.zeros((2, 3)))
        residual.joint_targets(action)
        expected = 0.1 * np.array([0.02, 0.03, 0.04]) + 0.9 * expected
    np.testing.assert_allclose(residual.residual[0], expected, rtol=0, atol=1e-15)
    residual.reset([1])
    assert np.all(residual.residual[1] == 0) and np.all(residual.residual[0] == expected)
    assert residual.clock.tolist() == [3, 0]


def test_actions_are_clipped_to_the_residual_bound():
    config = ResidualConfig(residual_bound=(0.05, 0.05, 0.08), residual_alpha=1.0)
    residual = ResidualController(load_model("base"), config, 1)
    sim = A1Sim(build_model("flat"))
    states = StateBatch.from_states([sim.state])
    residual.prepare(states, np.zeros((1, 3)))
    residual.joint_targets(np.full((1, 12), 7.0))
    np.testing.assert_allclose(residual.residual[0], np.tile([0.05, 0.05, 0.08], (4, 1)))
    with pytest.raises(ValueError, match="shape"):
        residual.joint_targets(np.zeros((1, 11)))
    with pytest.raises(ValueError, match="finite"):
        residual.joint_targets(np.full((1, 12), np.nan))


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"residual_bound": (0.05, 0.05)}, "3 values"),
        ({"residual_bound": (0.05, -1.0, 0.05)}, "positive"),
        ({"residual_alpha": 0.0}, r"residual_alpha must be in \(0, 1\]"),
    ],
)
def test_bad_residual_settings_are_refused(kwargs, message):
    with pytest.raises(AgentConfigError, match=message):
        ResidualConfig(**kwargs)
