"""SimBatch, the MuJoCo CPU backend (built by make_backend): its batched step and readout are N single
robots' steps and one-robot readouts, bit for bit; A1Sim is the batch of one."""

import dataclasses

import numpy as np
import pytest

from krl.robots.a1.constants import STANDING_JOINT_ANGLES
from krl.sim.backend import make_backend
from krl.sim.model import build_model
from krl.sim.pushes import Push
from krl.sim.robot import A1Sim, SimulationUnstableError
from krl.sim.state import StateBatch

FIELDS = [field.name for field in dataclasses.fields(StateBatch)]


def assert_same_states(batch: StateBatch, states) -> None:
    expected = StateBatch.from_states(states)
    for name in FIELDS:
        got, want = getattr(batch, name), getattr(expected, name)
        assert got.dtype == want.dtype and got.shape == want.shape, name
        np.testing.assert_array_equal(got, want, err_msg=name, strict=True)


def test_batched_steps_and_readout_are_single_simulators_bit_for_bit():
    models = [
        build_model("heightfield", {"max_height_low": 0.03, "max_height_high": 0.045}, 3),
        build_model("perlin", None, 4),
        build_model("flat"),
    ]
    batch = make_backend(models)
    singles = [A1Sim(built) for built in models]
    assert_same_states(batch.states, [sim.state for sim in singles])
    rng = np.random.default_rng(0)
    for k in range(240):
        if k == 10:  # pushes of both modes, one strong enough to topple the robot on the flat ground
            for index, push in (
                (0, Push(0.06, np.array([200.0, 60.0, 30.0]), np.array([0.1, 0.04, 0.05]))),
                (2, Push(0.06, np.array([0.0, 900.0, 100.0]), np.array([0.0, 0.0, 0.05]), mode="continuous")),
            ):
                batch.push(index, push)
                singles[index].push(push)
        if k == 120:  # a reset and a terrain swap
            np.testing.assert_array_equal(
                batch.reset(0, xy=(0.5, -0.3), yaw=0.4).base_pos,
                singles[0].reset(xy=(0.5, -0.3), yaw=0.4).base_pos,
            )
            swapped = build_model("heightfield", None, 9)
            batch.replace(1, swapped)
            singles[1] = A1Sim(swapped)
            batch.reset(1, yaw=-1.0)
            singles[1].reset(yaw=-1.0)
            assert_same_states(batch.states, [sim.state for sim in singles])
        q = STANDING_JOINT_ANGLES + rng.uniform(-0.4, 0.4, (3, 12))
        states = batch.step(q)
        assert_same_states(states, [sim.step(target) for sim, target in zip(singles, q, strict=True)])
        assert batch.states is states
    assert states.fallen[2] and not states.fallen[:2].any()
    # the one-robot readout of each robot's MjData is the batched readout's row, bit for bit
    assert_same_states(batch.states, [batch.read_state(index) for index in range(len(batch))])


def test_an_earlier_batch_is_a_snapshot():
    batch = make_backend([build_model("flat")] * 2)
    first = batch.step(np.tile(STANDING_JOINT_ANGLES, (2, 1)))
    saved = first.joint_pos.copy(), first.base_pos.copy(), first.time.copy()
    batch.step(np.tile(STANDING_JOINT_ANGLES, (2, 1)))
    batch.reset(1)
    np.testing.assert_array_equal(first.joint_pos, saved[0])
    np.testing.assert_array_equal(first.base_pos, saved[1])
    np.testing.assert_array_equal(first.time, saved[2])


def test_a_diverged_robot_keeps_its_last_state_marked_fallen():
    batch = make_backend([build_model("flat")] * 3)
    q = np.tile(STANDING_JOINT_ANGLES, (3, 1))
    before = batch.step(q)
    batch.data(1).qvel[0] = np.nan
    after = batch.step(q)
    np.testing.assert_array_equal(batch.unstable, [False, True, False])
    np.testing.assert_array_equal(after.fallen, [False, True, False])
    for name in FIELDS:
        if name != "fallen":
            np.testing.assert_array_equal(getattr(after, name)[1], getattr(before, name)[1], err_msg=name)
    with pytest.raises(SimulationUnstableError, match=r"starting at t=0\.010 s"):
        batch.step(q, raise_on_divergence=True)
    batch.reset(1)
    assert not batch.unstable.any()
    batch.step(q)
    assert not batch.unstable.any()


def test_bad_targets_are_refused():
    batch = make_backend([build_model("flat")] * 2)
    with pytest.raises(ValueError, match=r"shape \(2, 12\)"):
        batch.step(np.zeros((3, 12)))
    with pytest.raises(ValueError, match="non-finite"):
        batch.step(np.full((2, 12), np.nan))


def test_models_with_markers_before_the_robots_sites_are_read_out_alike():
    models = [build_model("flat"), build_model("flat", markers=[(1.0, 0.0), (2.0, 1.0)])]
    batch, singles = make_backend(models), [A1Sim(built) for built in models]
    assert models[0].model.site("FR_foot").id != models[1].model.site("FR_foot").id
    for _ in range(20):
        states = batch.step(np.tile(STANDING_JOINT_ANGLES, (2, 1)))
        assert_same_states(states, [sim.step(STANDING_JOINT_ANGLES) for sim in singles])
