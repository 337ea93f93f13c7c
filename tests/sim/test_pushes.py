"""Pushes: hand-worked impulses, exact momentum transfer in the simulator, random distributions."""

import mujoco
import numpy as np
import pytest

from krl.robots.a1.constants import STANDING_JOINT_ANGLES, TOTAL_MASS, TRUNK_HALF_SIZE
from krl.sim.model import build_model
from krl.sim.pushes import Push, PushDistribution, PushSchedule, random_trunk_point, scripted_push
from krl.sim.robot import A1Sim


def test_impulse_hand_worked():
    push = Push(start_time=1.0, force=np.array([300.0, 0, 0]), point=np.zeros(3))
    assert push.num_steps == 60
    assert push.applied_seconds == pytest.approx(0.06)  # 60 control steps x one 1 ms physics step
    np.testing.assert_allclose(push.impulse, [18.0, 0, 0])
    assert push.delta_v == pytest.approx(18.0 / TOTAL_MASS)
    held = Push(start_time=1.0, force=np.array([300.0, 0, 0]), point=np.zeros(3), mode="continuous")
    assert held.applied_seconds == pytest.approx(0.3)
    assert held.summary()["impulse"] == pytest.approx(90.0)


@pytest.mark.parametrize("mode", ["control_step", "continuous"])
def test_momentum_change_equals_impulse_in_free_flight(mode):
    built = build_model("flat")
    sim = A1Sim(built)
    sim.model.opt.gravity[:] = 0.0
    sim.reset()
    sim.data.qpos[2] = 3.0  # far above the ground: no contact, no gravity
    mujoco.mj_forward(sim.model, sim.data)
    push = Push(
        start_time=0.02,
        force=np.array([120.0, -80.0, 40.0]),
        point=np.array([0.1, 0.05, 0.03]),
        duration=0.1,
        mode=mode,
    )
    sim.push(push)

    def momentum():
        mujoco.mj_forward(sim.model, sim.data)
        mujoco.mj_subtreeVel(sim.model, sim.data)
        return TOTAL_MASS * sim.data.subtree_linvel[sim.model.body("trunk").id].copy()

    before = momentum()
    for _ in range(40):
        sim.step(STANDING_JOINT_ANGLES)
    # exact up to the O(dt) error of evaluating momentum after a discrete step while the legs move
    np.testing.assert_allclose(momentum() - before, push.impulse, rtol=1e-3)
    assert sim.pending_push is None


def test_push_in_the_past_is_rejected():
    sim = A1Sim(build_model("flat"))
    for _ in range(100):
        sim.step(STANDING_JOINT_ANGLES)
    with pytest.raises(ValueError, match="already over"):
        sim.push(Push(start_time=0.0, force=np.ones(3), point=np.zeros(3), duration=0.1))


def test_bad_push_rejected():
    with pytest.raises(ValueError, match="force"):
        Push(start_time=0.0, force=np.array([1.0, np.nan, 0]), point=np.zeros(3))
    with pytest.raises(ValueError, match="mode"):
        Push(start_time=0.0, force=np.ones(3), point=np.zeros(3), mode="sometimes")
    with pytest.raises(ValueError, match="magnitude"):
        PushDistribution(magnitude=(350.0, 100.0))


def test_trunk_points_lie_on_the_box_surface():
    rng = np.random.default_rng(0)
    for _ in range(200):
        ratio = np.abs(random_trunk_point(rng)) / TRUNK_HALF_SIZE
        assert ratio.max() == pytest.approx(1.0)
        assert (ratio <= 1.0 + 1e-12).all()


def test_a_top_share_sets_how_often_the_top_face_is_struck_and_none_draws_as_before():
    """The option's default draws the very points it drew before it existed (seed 7, by hand from the old
    code); with a share, the top face takes it and the other five faces the rest by area."""
    rng = np.random.default_rng(7)
    assert [random_trunk_point(rng).round(6).tolist() for _ in range(2)] == [
        [0.106056, 0.053483, -0.057],
        [-0.132094, 0.062318, -0.057],
    ]
    for share in (0.0, 0.5, 1.0):
        rng = np.random.default_rng(1)
        points = np.array([random_trunk_point(rng, share) for _ in range(4000)])
        ratio = np.abs(points) / TRUNK_HALF_SIZE
        assert np.allclose(ratio.max(axis=1), 1.0) and (ratio <= 1.0 + 1e-12).all()
        top = np.isclose(points[:, 2], TRUNK_HALF_SIZE[2])
        assert abs(top.mean() - share) < 0.03
        bottom = np.isclose(points[:, 2], -TRUNK_HALF_SIZE[2])
        if share < 1:  # the bottom's share of the five other faces' area: 0.330
            assert abs(bottom.sum() / (~top).sum() - 0.330) < 0.03
    drawn = PushDistribution(top_share=1.0).sample(np.random.default_rng(3), 1.0)
    assert drawn.point[2] == TRUNK_HALF_SIZE[2]
    for bad in (-0.1, 1.5, float("nan")):
        with pytest.raises(ValueError, match="push top_share must be in"):
            PushDistribution(top_share=bad)


def test_training_schedule_follows_the_thesis_distribution():
    schedule = PushSchedule(PushDistribution(), np.random.default_rng(7))
    times = np.arange(0, 600, 0.005)
    starts = [push.start_time for t in times if (push := schedule.due(t)) is not None]
    gaps = np.diff(starts)
    assert len(starts) > 60
    assert gaps.min() >= 5.0 - 0.006 and gaps.max() <= 8.0 + 0.006
    magnitudes = np.array([push.magnitude for push in schedule.pushes])
    assert magnitudes.min() >= 100 and magnitudes.max() <= 350
    elevations = np.array([np.arcsin(push.force[2] / push.magnitude) for push in schedule.pushes])
    assert elevations.min() >= 0 and elevations.max() <= 0.3
    again = PushSchedule(PushDistribution(), np.random.default_rng(7))
    repeat = [push.start_time for t in times if (push := again.due(t)) is not None]
    assert repeat == starts


def test_scripted_push():
    push = scripted_push(650.0, np.random.default_rng(1), window=(1.0, 3.0))
    assert push.magnitude == pytest.approx(650.0)
    assert 1.0 <= push.start_time <= 3.0
    with pytest.raises(ValueError, match="magnitude"):
        scripted_push(-1.0, np.random.default_rng(1), window=(1.0, 3.0))
