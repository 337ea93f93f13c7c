"""The MPC expert walks: fixed commands tracked, waypoints reached, bad settings and QP failures."""

import numpy as np
import pytest

from krl.control import mpc as mpc_module
from krl.control.expert import ExpertParams, MPCExpert
from krl.control.mpc import MPCError
from krl.sim.model import build_model
from krl.sim.robot import A1Sim
from krl.task import random_targets
from krl.task.runner import Runner


@pytest.fixture(scope="module")
def runner():
    return Runner(A1Sim(build_model("flat")), MPCExpert())


def test_tracks_forward_command_within_ten_percent(runner):
    result = runner.hold_command(np.array([0.5, 0.0, 0.0]), duration=5.0)
    assert not result.fell
    vx, vy, wz = result.mean_velocity()
    assert vx == pytest.approx(0.5, rel=0.1)
    assert abs(vy) < 0.05 and abs(wz) < 0.05


@pytest.mark.parametrize("command", [(0.0, 0.0, 0.5), (0.0, 0.0, -0.5), (-0.4, 0.0, 0.0), (0.0, 0.3, 0.0)])
def test_turns_and_walks_backward_and_sideways(runner, command):
    result = runner.hold_command(np.array(command), duration=4.0)
    assert not result.fell
    np.testing.assert_allclose(result.mean_velocity(), command, atol=0.06)


@pytest.mark.parametrize("seed", [0, 1])
def test_reaches_random_waypoints(runner, seed):
    targets = random_targets(np.random.default_rng(seed), 3, distance=(1.0, 1.5))
    result = runner.walk_to(targets)
    assert result.targets_reached == 3 and not result.fell and not result.timed_out


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_reaches_ten_waypoints_two_and_a_half_metres_apart(runner, seed):
    targets = random_targets(np.random.default_rng(seed), 10)
    result = runner.walk_to(targets)
    assert result.targets_reached == 10 and not result.fell


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("stance_duration", -0.2, "stance_duration"),
        ("step_height", 0.3, "step_height"),
        ("ride_height", 0.1, "ride_height"),
        ("gait", "gallop", "gallop"),
    ],
)
def test_bad_expert_parameters(field, value, message):
    with pytest.raises(ValueError, match=message):
        ExpertParams(**{field: value})


def test_qp_failures_are_bridged_then_reported(monkeypatch):
    sim = A1Sim(build_model("flat"))
    expert = MPCExpert()
    state = sim.reset()
    expert.reset(state)
    for _ in range(50):
        state = sim.step(*expert.act(state, np.zeros(3)))
    monkeypatch.setattr(mpc_module.daqp, "solve", lambda *args: (np.zeros(1), 0.0, -1, {}))
    for _ in range(5):  # bridged with the previous plan, counted
        state = sim.step(*expert.act(state, np.zeros(3)))
    assert expert.mpc_failures == 5 and not state.fallen
    with pytest.raises(MPCError, match="DAQP exit flag -1"):
        expert.act(state, np.zeros(3))
