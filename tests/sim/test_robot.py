"""A1Sim: PD law inside MuJoCo, hybrid commands, motor envelope, state readout, falls, divergence."""

import mujoco
import numpy as np
import pytest

from krl.control.kinematics import foot_positions
from krl.robots.a1.constants import (
    KD,
    KP,
    MOTOR_TORQUE_LIMIT,
    STANDING_JOINT_ANGLES,
    TOTAL_MASS,
)
from krl.sim.model import build_model
from krl.sim.robot import A1Sim, SimulationUnstableError, motor_torque_bounds
from krl.util.timing import CONTROL_DT


@pytest.fixture(scope="module")
def flat():
    return build_model("flat")


def stand(sim, seconds):
    for _ in range(round(seconds / CONTROL_DT)):
        state = sim.step(STANDING_JOINT_ANGLES)
    return state


def test_model_mass_and_timestep(flat):
    assert flat.model.opt.timestep == pytest.approx(0.001)
    assert flat.model.body_subtreemass[flat.model.body("trunk").id] == pytest.approx(TOTAL_MASS)


def test_stands_two_seconds_on_flat_ground(flat):
    sim = A1Sim(flat)
    state = stand(sim, 2.0)
    assert state.time == pytest.approx(2.0)
    assert not state.fallen
    assert 0.23 < state.base_pos[2] < 0.28
    assert state.foot_contact.all()
    # the feet carry the robot's weight
    assert state.foot_force.sum() == pytest.approx(TOTAL_MASS * 9.81, rel=0.05)
    assert np.abs(state.rpy[:2]).max() < 0.05


def test_actuator_implements_hybrid_pd_law(flat):
    """torque = kp (q* - q) - kd q̇ + tau_ff, clamped, at the state MuJoCo sees."""
    sim = A1Sim(flat, motor_envelope=False)
    rng = np.random.default_rng(3)
    kp = rng.uniform(0, 150, 12)
    kd = rng.uniform(0, 3, 12)
    target = STANDING_JOINT_ANGLES + rng.uniform(-0.2, 0.2, 12)
    tau_ff = rng.uniform(-5, 5, 12)
    sim.step(target, kp=kp, kd=kd, tau_ff=tau_ff)
    d = sim.data
    mujoco.mj_forward(sim.model, d)
    q, qd = d.qpos[7:19], d.qvel[6:18]
    expected = np.clip(kp * (target - q) - kd * qd + tau_ff, -MOTOR_TORQUE_LIMIT, MOTOR_TORQUE_LIMIT)
    np.testing.assert_allclose(d.actuator_force[:12], expected, atol=1e-9)


def test_pure_torque_command_and_saturation(flat):
    sim = A1Sim(flat, motor_envelope=False)
    zeros = np.zeros(12)
    tau = np.linspace(-50, 50, 12)
    state = sim.step(STANDING_JOINT_ANGLES, kp=zeros, kd=zeros, tau_ff=tau)
    np.testing.assert_allclose(state.joint_torque, np.clip(tau, -33.5, 33.5))
    # gains persist until changed, and the default gains come back on request
    state = sim.step(STANDING_JOINT_ANGLES, kp=KP, kd=KD)
    assert not np.allclose(state.joint_torque, np.clip(tau, -33.5, 33.5))


def test_motor_envelope_hand_worked():
    lower, upper = motor_torque_bounds(np.array([0.0, 10.5, 15.75, 21.0, 30.0, -15.75, -25.0]))
    np.testing.assert_allclose(upper, [33.5, 33.5, 16.75, 0.0, 0.0, 33.5, 33.5])
    np.testing.assert_allclose(lower, [-33.5, -33.5, -33.5, -33.5, -33.5, -16.75, 0.0])


def test_state_frames_are_consistent(flat):
    sim = A1Sim(flat)
    sim.reset(xy=(1.0, -2.0), yaw=0.7)
    state = stand(sim, 0.3)
    assert state.rpy[2] == pytest.approx(0.7, abs=0.02)
    np.testing.assert_allclose(state.base_rot @ state.lin_vel_base, state.lin_vel_world, atol=1e-12)
    np.testing.assert_allclose(state.base_rot @ state.ang_vel_base, state.ang_vel_world, atol=1e-12)
    np.testing.assert_allclose(state.projected_gravity, state.base_rot.T @ [0, 0, -1], atol=1e-12)
    # foot positions from MuJoCo agree with krl's own forward kinematics of the current joint angles
    np.testing.assert_allclose(state.foot_pos_base, foot_positions(state.joint_pos), atol=1e-9)
    world = state.base_pos + state.foot_pos_base @ state.base_rot.T
    np.testing.assert_allclose(world, state.foot_pos_world, atol=1e-12)
    assert state.com[2] < state.base_pos[2]


def test_state_is_a_snapshot(flat):
    sim = A1Sim(flat)
    first = sim.step(STANDING_JOINT_ANGLES)
    saved = first.joint_pos.copy(), first.base_pos.copy()
    stand(sim, 0.1)
    np.testing.assert_array_equal(first.joint_pos, saved[0])
    np.testing.assert_array_equal(first.base_pos, saved[1])


def test_upside_down_robot_has_fallen(flat):
    sim = A1Sim(flat)
    sim.reset()
    sim.data.qpos[3:7] = (0.0, 1.0, 0.0, 0.0)  # rolled by π
    sim.data.qpos[2] = 0.4
    state = stand(sim, 1.0)
    assert state.fallen


def test_divergence_raises_clear_error(flat):
    sim = A1Sim(flat)
    before = sim.state
    sim.data.qvel[0] = np.nan
    with pytest.raises(SimulationUnstableError, match=r"starting at t=0\.000 s"):
        sim.step(STANDING_JOINT_ANGLES)
    assert sim.state.fallen  # the last state before the divergence, marked fallen
    np.testing.assert_array_equal(sim.state.joint_pos, before.joint_pos)


@pytest.mark.parametrize(
    ("bad", "message"),
    [(np.zeros(11), r"q_target must have shape \(12,\)"), (np.full(12, np.nan), "non-finite")],
)
def test_bad_commands_rejected(flat, bad, message):
    sim = A1Sim(flat)
    with pytest.raises(ValueError, match=message):
        sim.step(bad)
    with pytest.raises(ValueError, match="kp and kd must be >= 0"):
        sim.step(STANDING_JOINT_ANGLES, kp=-KP)


def test_standing_inertia_constant_matches_the_model(flat):
    """constants.STANDING_INERTIA is the whole robot's inertia about its CoM in the standing pose."""
    from krl.robots.a1.constants import STANDING_INERTIA

    m = flat.model
    d = mujoco.MjData(m)
    d.qpos[:7] = (0, 0, 0.3, 1, 0, 0, 0)
    d.qpos[7:19] = STANDING_JOINT_ANGLES
    mujoco.mj_forward(m, d)
    trunk = m.body("trunk").id
    com = d.subtree_com[trunk]
    inertia = np.zeros((3, 3))
    for body in range(trunk, m.nbody):
        if m.body_rootid[body] != trunk:
            continue
        rot = d.ximat[body].reshape(3, 3)
        offset = d.xipos[body] - com
        inertia += rot @ np.diag(m.body_inertia[body]) @ rot.T
        inertia += m.body_mass[body] * (offset @ offset * np.eye(3) - np.outer(offset, offset))
    np.testing.assert_allclose(STANDING_INERTIA, inertia, atol=1e-4)


def test_set_state_is_the_state_the_next_step_starts_from(flat):
    sim = A1Sim(flat)
    walked = A1Sim(flat)
    for _ in range(20):
        walked.step(STANDING_JOINT_ANGLES + 0.05)
    state = sim.set_state(walked.data.qpos[:19], walked.data.qvel[:18])
    np.testing.assert_array_equal(state.base_pos, walked.state.base_pos)
    np.testing.assert_array_equal(state.joint_vel, walked.state.joint_vel)
    assert sim.step_count == 0  # the time stays
    with pytest.raises(ValueError, match=r"qpos and qvel must have shapes \(19,\) and \(18,\)"):
        sim.set_state(np.zeros(18), np.zeros(18))
