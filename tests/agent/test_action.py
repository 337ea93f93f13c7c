"""The action's drive parts: layout, bounds, smoothing, and the faithful agent as the all-off special case."""

from __future__ import annotations

import json

import numpy as np
import pytest
from agent_fakes import make_policy

from krl.agent.action import action_parts
from krl.agent.config import CORE_FEATURES, AgentConfig, AgentConfigError, ResidualConfig
from krl.agent.controller import AgentController
from krl.agent.observation import observe
from krl.agent.residual import ResidualController
from krl.cli import main
from krl.control.expert import RIDE_HEIGHT_RANGE, STEP_HEIGHT_RANGE
from krl.envs.residual import A1ResidualEnv
from krl.kernel.registry import load_model
from krl.sim.backend import make_backend
from krl.sim.model import build_model
from krl.sim.robot import A1Sim

ALL_DRIVES = {"drive_command": True, "drive_heights": True, "drive_rhythm": True}


def _rollout(config: ResidualConfig, actions: np.ndarray, kernel: str = "ext") -> np.ndarray:
    """Joint targets of two robots on a height field, driven by ``actions`` (steps, 2, D) and a fixed
    task command. Shape: (steps, 2, 12)."""
    controller = ResidualController(load_model(kernel), config, 2)
    sims = make_backend([build_model("heightfield", seed=3)] * 2)
    states = sims.states
    command = np.array([[0.3, 0.0, 0.1], [0.2, -0.1, 0.0]])
    out = []
    for action in actions:
        controller.prepare(states, command)
        q = controller.joint_targets(action)
        out.append(q)
        states = sims.step(q)
    return np.array(out)


def test_the_action_size_counts_the_switched_on_parts():
    assert ResidualConfig().action_size == 12
    assert ResidualConfig(**ALL_DRIVES).action_size == 18
    assert ResidualConfig(residuals=False, drive_command=True).action_size == 3
    names = [p.name for p in action_parts(ResidualConfig(**ALL_DRIVES), load_model("ext"))]
    assert names == ["residual", "command", "heights", "clock_rate"]
    steering = ResidualConfig(drive_steer=True, drive_heights=True, drive_rhythm=True)
    assert steering.action_size == 18
    assert [p.name for p in action_parts(steering, load_model("ext"))] == [
        "residual",
        "steer",
        "heights",
        "clock_rate",
    ]


def test_zero_drives_reproduce_the_residual_agent_bit_for_bit():
    rng = np.random.default_rng(0)
    residuals = rng.uniform(-1.2, 1.2, size=(150, 2, 12))
    faithful = _rollout(ResidualConfig(kernel="ext"), residuals)
    config = ResidualConfig(kernel="ext", drive_heights=True, drive_rhythm=True)
    driven = _rollout(config, np.concatenate([residuals, np.zeros((150, 2, 3))], axis=2))
    np.testing.assert_array_equal(driven, faithful)
    config = ResidualConfig(kernel="ext", drive_steer=True, drive_heights=True, drive_rhythm=True)
    steered = _rollout(config, np.concatenate([residuals, np.zeros((150, 2, 6))], axis=2))
    np.testing.assert_array_equal(steered, faithful)  # the task's commands lie in the kernel's ranges


def test_steering_offsets_the_tasks_command_within_the_kernels_ranges():
    config = ResidualConfig(residuals=False, drive_steer=True, gait_alpha=1.0)
    controller = ResidualController(load_model("base"), config, 1)
    sims = make_backend([build_model("flat")])
    command = np.array([[0.3, 0.1, 0.4]])
    controller.prepare(sims.states, command)
    np.testing.assert_array_equal(controller.kernel_command, command)
    controller.joint_targets(np.array([[1.0, -1.0, 0.5]]))  # offsets (0.5, -0.3, 0.25) from the next step
    np.testing.assert_allclose(controller.gait_inputs[0, :3], [0.5, -0.3, 0.25])
    controller.prepare(sims.states, command)
    np.testing.assert_allclose(controller.kernel_command[0], [0.5, -0.2, 0.5])  # (0.8, -0.2, 0.65) clipped


def test_driven_inputs_are_bounded_and_low_pass_filtered():
    config = ResidualConfig(kernel="ext", residuals=False, **ALL_DRIVES, gait_alpha=0.2)
    controller = ResidualController(load_model("ext"), config, 1)
    sims = make_backend([build_model("flat")])
    action = np.array([[7.0, -7.0, 7.0, 7.0, -7.0, 7.0]])  # clipped to ±1
    high = np.array([0.5, -0.3, 0.5, STEP_HEIGHT_RANGE[1], RIDE_HEIGHT_RANGE[0], config.rhythm_range[1]])
    nominal = controller.gait_inputs[0].copy()
    for step in range(1, 6):
        controller.prepare(sims.states, np.zeros((1, 3)))
        controller.joint_targets(action)
        expected = nominal + (1 - 0.8**step) * (high - nominal)
        np.testing.assert_allclose(controller.gait_inputs[0], expected, rtol=0, atol=1e-12)
    controller.prepare(sims.states, np.zeros((1, 3)))
    np.testing.assert_allclose(controller.kernel_command[0], controller.gait_inputs[0, :3])
    controller.reset()
    np.testing.assert_array_equal(controller.gait_inputs[0], nominal)
    assert controller.clock[0] == 0.0


def test_a_driven_clock_advances_at_its_rate():
    config = ResidualConfig(residuals=False, drive_rhythm=True, gait_alpha=1.0, rhythm_range=(0.5, 2.0))
    controller = ResidualController(load_model("base"), config, 2)
    sims = make_backend([build_model("flat")] * 2)
    for _ in range(4):
        controller.prepare(sims.states, np.zeros((2, 3)))
        controller.joint_targets(np.array([[1.0], [-1.0]]))
    assert controller.clock.tolist() == [1 + 3 * 2.0, 1 + 3 * 0.5]  # the first step ran at the rate 1


def test_the_drive_features_observe_what_the_kernel_receives():
    config = ResidualConfig(kernel="ext", residuals=False, **ALL_DRIVES, gait_alpha=1.0)
    controller = ResidualController(load_model("ext"), config, 1)
    sims = make_backend([build_model("flat")])
    controller.prepare(sims.states, np.zeros((1, 3)))
    controller.joint_targets(np.full((1, 6), 0.5))
    controller.prepare(sims.states, np.zeros((1, 3)))
    observed = observe(
        ("kernel_command", "heights", "clock_rate"), controller.observation_inputs(sims.states)
    )
    np.testing.assert_allclose(observed[0], controller.gait_inputs[0], rtol=1e-6)


@pytest.mark.parametrize(
    ("kwargs", "kernel", "message"),
    [
        ({"residuals": False}, None, "action is empty"),
        ({"rhythm_range": (1.0, 1.5)}, None, "rhythm_range must satisfy"),
        ({"gait_alpha": 0.0}, None, r"gait_alpha must be in \(0, 1\]"),
        ({"drive_heights": True}, "base", "drive_heights needs kernel-ext"),
        ({"drive_command": True, "drive_steer": True}, None, "drive_command and drive_steer both set"),
    ],
)
def test_bad_drive_settings_are_refused(kwargs, kernel, message):
    with pytest.raises(AgentConfigError, match=message):
        config = ResidualConfig(**kwargs)
        ResidualController(load_model(kernel), config, 1)


def test_actions_of_the_wrong_size_are_refused():
    controller = ResidualController(load_model("base"), ResidualConfig(drive_command=True), 1)
    sims = make_backend([build_model("flat")])
    controller.prepare(sims.states, np.zeros((1, 3)))
    with pytest.raises(ValueError, match=r"shape \(1, 15\)"):
        controller.joint_targets(np.zeros((1, 12)))


def test_a_gait_driving_policy_walks_in_the_controller_and_the_env():
    config = AgentConfig.from_json(
        {
            "residual": {"kernel": "ext", "drive_heights": True, "drive_rhythm": True},
            "observation": {"features": [*CORE_FEATURES, "residual", "heights", "clock_rate"]},
        }
    )
    agent = AgentController(make_policy(config, scale=0.3, seed=4))
    sim = A1Sim(build_model("flat"))
    agent.reset(sim.state)
    for _ in range(5):
        sim.step(agent.act(sim.state, np.array([0.3, 0.0, 0.0])).q_target)
    assert agent.last_action.shape == (15,)
    env = A1ResidualEnv(config)
    assert env.action_space.shape == (15,)
    observation, _ = env.reset(seed=0)
    observation, *_ = env.step(np.zeros(15, dtype=np.float32))
    assert observation.shape == env.observation_space.shape


def test_krl_agent_rhythm_walks_the_kernel_at_fixed_clock_rates(capsys):
    argv = ["agent", "rhythm", "--rates", "0.5,2", "--terrain", "flat", "--seconds", "3", "--json"]
    assert main(argv) == 0
    walks = json.loads(capsys.readouterr().out)["walks"]
    assert [(w["terrain"], w["rate"], w["fell"]) for w in walks] == [
        ("flat", 0.5, False),
        ("flat", 2.0, False),
    ]
    assert walks[1]["velocity"][0] > walks[0]["velocity"][0] + 0.1  # a faster clock, a faster walk
    for bad, message in ((["--rates", "0"], "--rates must be positive"), (["--seconds", "1"], "--seconds")):
        assert main(["agent", "rhythm", *bad]) == 2
        assert message in capsys.readouterr().err
