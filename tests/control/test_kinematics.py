"""krl.control.kinematics against MuJoCo's own kinematics of the packaged A1 model."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

import krl.robots.a1 as a1
from krl.control.kinematics import (
    IKResult,
    foot_jacobians,
    foot_positions,
    foot_positions_in_hip,
    foot_velocities,
    inverse_kinematics,
)
from krl.robots.a1.constants import (
    ABDUCTION_OFFSET,
    FOOT_NAMES,
    HIP_OFFSETS,
    JOINT_LOWER,
    JOINT_UPPER,
    LEG_SIDE,
    STANDING_JOINT_ANGLES,
)

# A sub-box well inside the joint limits, for round trips.
INNER_LOWER = np.tile([-0.6, -0.8, -2.5], 4)
INNER_UPPER = np.tile([0.6, 2.0, -1.1], 4)


@pytest.fixture(scope="module")
def mj():
    model = mujoco.MjModel.from_xml_path(str(a1.MJCF_PATH))
    data = mujoco.MjData(model)
    sites = [model.site(name).id for name in FOOT_NAMES]
    trunk = model.body("trunk").id
    return model, data, sites, trunk


def _set_pose(mj, q, quat=(1.0, 0.0, 0.0, 0.0)):
    model, data, _, _ = mj
    data.qpos[0:3] = [0.0, 0.0, 0.5]
    data.qpos[3:7] = quat
    data.qpos[7:19] = q
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)


def _random_q(rng, n, lower=JOINT_LOWER, upper=JOINT_UPPER):
    return rng.uniform(lower, upper, size=(n, 12))


def test_foot_positions_match_mujoco(mj):
    _, data, sites, trunk = mj
    rng = np.random.default_rng(0)
    qs = _random_q(rng, 300)
    ours = foot_positions(qs)
    for i, q in enumerate(qs):
        quat = (1.0, 0.0, 0.0, 0.0) if i % 2 == 0 else rng.normal(size=4)
        quat = np.asarray(quat) / np.linalg.norm(quat)
        _set_pose(mj, q, quat)
        rot = data.xmat[trunk].reshape(3, 3)
        expected = (data.site_xpos[sites] - data.xpos[trunk]) @ rot
        np.testing.assert_allclose(ours[i], expected, rtol=0, atol=1e-9)
    np.testing.assert_allclose(foot_positions_in_hip(qs), ours - HIP_OFFSETS, rtol=0, atol=1e-15)


def test_foot_jacobians_match_mujoco(mj):
    model, data, sites, _ = mj
    rng = np.random.default_rng(1)
    qs = _random_q(rng, 100)
    ours = foot_jacobians(qs)
    assert ours.shape == (100, 4, 3, 3)
    jacp = np.zeros((3, model.nv))
    for i, q in enumerate(qs):
        _set_pose(mj, q)
        for leg, site in enumerate(sites):
            mujoco.mj_jacSite(model, data, jacp, None, site)
            np.testing.assert_allclose(ours[i, leg], jacp[:, 6 + 3 * leg : 9 + 3 * leg], rtol=0, atol=1e-9)
            # a foot does not move with the other legs' joints
            others = np.delete(jacp[:, 6:], np.s_[3 * leg : 3 * leg + 3], axis=1)
            assert np.all(others == 0.0)


def test_foot_velocities_are_jacobian_times_qd_and_match_finite_differences():
    rng = np.random.default_rng(2)
    q = _random_q(rng, 20)
    qd = rng.normal(size=(20, 12))
    v = foot_velocities(q, qd)
    np.testing.assert_allclose(v, np.einsum("nlij,nlj->nli", foot_jacobians(q), qd.reshape(20, 4, 3)))
    h = 1e-6
    fd = (foot_positions(q + h * qd) - foot_positions(q - h * qd)) / (2 * h)
    np.testing.assert_allclose(v, fd, rtol=0, atol=1e-8)
    # batch dimensions broadcast: one configuration, many velocities
    np.testing.assert_allclose(foot_velocities(q[0], qd), foot_velocities(np.broadcast_to(q[0], q.shape), qd))


def test_ik_inverts_fk_inside_limits():
    rng = np.random.default_rng(3)
    q = _random_q(rng, 5000, INNER_LOWER, INNER_UPPER).reshape(-1, 4, 3)
    # leg-plane z of each foot; the preferred IK branch has the foot below the abduction axis (z < 0)
    z = -0.2 * np.cos(q[..., 1]) - 0.2 * np.cos(q[..., 1] + q[..., 2])
    p = foot_positions(q)
    res = inverse_kinematics(p)
    assert isinstance(res, IKResult)
    assert res.q.shape == (5000, 12) and res.reachable.shape == (5000, 4)
    assert res.reachable.all()
    below = z < -1e-3
    assert below.mean() > 0.8
    np.testing.assert_allclose(res.q.reshape(-1, 4, 3)[below], q[below], rtol=0, atol=1e-9)
    # where the other branch was used, the position still round-trips
    np.testing.assert_allclose(foot_positions(res.q), p, rtol=0, atol=1e-9)
    # the standing pose exactly
    np.testing.assert_allclose(
        inverse_kinematics(foot_positions(STANDING_JOINT_ANGLES)).q, STANDING_JOINT_ANGLES, atol=1e-12
    )


def test_fk_of_ik_recovers_reachable_targets():
    rng = np.random.default_rng(4)
    p = foot_positions(_random_q(rng, 5000))  # any configuration within the limits: reachable targets
    for clip in (True, False):
        res = inverse_kinematics(p, clip_to_limits=clip)
        assert res.reachable.all()
        assert np.all(res.q >= JOINT_LOWER - 1e-9) and np.all(res.q <= JOINT_UPPER + 1e-9)
        np.testing.assert_allclose(foot_positions(res.q), p, rtol=0, atol=1e-7)


def test_reachable_flag_is_consistent_with_fk():
    rng = np.random.default_rng(5)
    p = HIP_OFFSETS + rng.uniform([-0.45, -0.45, -0.45], [0.45, 0.45, 0.3], size=(20000, 4, 3))
    res = inverse_kinematics(p)
    assert np.isfinite(res.q).all()
    assert np.all(res.q >= JOINT_LOWER) and np.all(res.q <= JOINT_UPPER)
    err = np.linalg.norm(foot_positions(res.q) - p, axis=-1)
    assert 0.05 < res.reachable.mean() < 0.95
    assert np.all(err[res.reachable] < 1e-7)
    assert np.all(err[~res.reachable] > 1e-9)


def _leg_targets(offsets_in_hip):
    """Base-frame targets from per-leg hip-relative offsets, y mirrored for the right legs."""
    off = np.asarray(offsets_in_hip, dtype=float)
    return HIP_OFFSETS + off * np.array([1.0, 0.0, 1.0]) + np.outer(LEG_SIDE, [0.0, 1.0, 0.0]) * off[1]


@pytest.mark.parametrize(
    ("name", "offset"),
    [
        ("too far below", (0.0, ABDUCTION_OFFSET, -0.6)),
        ("too far forward", (1.0, ABDUCTION_OFFSET, -0.2)),
        ("too close to the hip joint", (0.0, ABDUCTION_OFFSET, -0.05)),
        ("inside the abduction offset", (0.1, 0.0, -0.02)),
        ("on the abduction axis", (0.0, 0.0, 0.0)),
        ("through the body", (0.0, -0.15, -0.1)),
        ("forward and up", (0.3, ABDUCTION_OFFSET, 0.1)),
        ("far away", (1e6, -3e6, 2e5)),
    ],
)
def test_unreachable_targets_are_finite_clipped_and_flagged(name, offset):
    p = _leg_targets(offset)
    for clip in (True, False):
        res = inverse_kinematics(p, clip_to_limits=clip)
        assert np.isfinite(res.q).all(), name
        assert not res.reachable.any(), name
        if clip:
            assert np.all(res.q >= JOINT_LOWER) and np.all(res.q <= JOINT_UPPER), name


def test_out_of_reach_targets_are_projected_along_the_ray():
    knee_lo, knee_hi = JOINT_LOWER[2], JOINT_UPPER[2]
    reach_max = 0.4 * np.cos(knee_hi / 2)  # thigh = calf = 0.2
    reach_min = 0.4 * np.cos(knee_lo / 2)
    for length, expected in ((0.6, reach_max), (0.05, reach_min)):
        direction = np.array([0.3, 0.0, -1.0]) / np.hypot(0.3, 1.0)
        hip_pitch = np.outer(LEG_SIDE, [0.0, ABDUCTION_OFFSET, 0.0])
        p = HIP_OFFSETS + hip_pitch + length * direction
        res = inverse_kinematics(p)
        assert not res.reachable.any()
        np.testing.assert_allclose(
            foot_positions(res.q), HIP_OFFSETS + hip_pitch + expected * direction, atol=1e-12
        )
    # without clipping the leg stretches to its geometric reach (knee angle 0)
    res = inverse_kinematics(HIP_OFFSETS + hip_pitch + 0.6 * direction, clip_to_limits=False)
    np.testing.assert_allclose(res.q.reshape(4, 3)[:, 2], 0.0, atol=1e-12)
    np.testing.assert_allclose(foot_positions(res.q), HIP_OFFSETS + hip_pitch + 0.4 * direction, atol=1e-12)


def test_batched_shapes_match_looping():
    rng = np.random.default_rng(6)
    q = _random_q(rng, 35).reshape(7, 5, 12)
    p = foot_positions(q) + rng.normal(scale=0.05, size=(7, 5, 4, 3))
    qd = rng.normal(size=(7, 5, 4, 3))
    fk, jac, vel, ik = foot_positions(q), foot_jacobians(q), foot_velocities(q, qd), inverse_kinematics(p)
    assert fk.shape == (7, 5, 4, 3) and jac.shape == (7, 5, 4, 3, 3) and vel.shape == (7, 5, 4, 3)
    assert ik.q.shape == (7, 5, 12) and ik.reachable.shape == (7, 5, 4) and ik.reachable.dtype == bool
    np.testing.assert_array_equal(foot_positions(q.reshape(7, 5, 4, 3)), fk)
    for i in range(7):
        for j in range(5):
            np.testing.assert_array_equal(foot_positions(q[i, j]), fk[i, j])
            np.testing.assert_array_equal(foot_jacobians(q[i, j]), jac[i, j])
            np.testing.assert_array_equal(foot_velocities(q[i, j], qd[i, j]), vel[i, j])
            single = inverse_kinematics(p[i, j])
            np.testing.assert_array_equal(single.q, ik.q[i, j])
            np.testing.assert_array_equal(single.reachable, ik.reachable[i, j])
    # unbatched shapes and integer / list input
    assert foot_positions(np.zeros(12, dtype=int)).shape == (4, 3)
    assert inverse_kinematics(foot_positions(STANDING_JOINT_ANGLES).tolist()).q.shape == (12,)
    empty = inverse_kinematics(np.zeros((0, 4, 3)))
    assert empty.q.shape == (0, 12) and empty.reachable.shape == (0, 4)


@pytest.mark.parametrize(
    ("func", "value"),
    [
        (foot_positions, np.zeros(11)),
        (foot_positions, np.zeros((4, 4))),
        (foot_positions, np.zeros((2, 3, 3))),
        (foot_positions, np.float64(0.0)),
        (foot_jacobians, np.zeros((5, 13))),
        (foot_positions_in_hip, np.full(12, np.nan)),
        (foot_jacobians, np.full((4, 3), np.inf)),
        (foot_positions, np.array(["a"] * 12)),
        (foot_positions, np.zeros(12, dtype=complex)),
        (inverse_kinematics, np.zeros(12)),
        (inverse_kinematics, np.zeros((4, 2))),
        (inverse_kinematics, np.array([[0.0, 0.0, np.nan]] * 4)),
        (inverse_kinematics, [[0.0, 0.0], [1.0]]),
    ],
)
def test_bad_input_raises_value_error(func, value):
    with pytest.raises(ValueError) as info:
        func(value)
    message = str(info.value)
    assert "\n" not in message
    assert "shape" in message


def test_bad_velocity_input_raises_value_error():
    with pytest.raises(ValueError, match=r"shape \(3,\)"):
        foot_velocities(np.zeros(12), np.zeros(3))
    with pytest.raises(ValueError, match="broadcast"):
        foot_velocities(np.zeros((2, 12)), np.zeros((3, 12)))
