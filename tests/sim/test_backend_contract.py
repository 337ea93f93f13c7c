"""The simulator backend contract (:class:`krl.sim.backend.SimBackend`): what every backend of
:data:`krl.sim.backend.BACKENDS` must pass, through its public methods only (a GPU backend's ``data(i)``
may be a host copy, so nothing here writes ``MjData``).

* **the same states for the same actions**: N robots stepped together are each robot stepped alone, and a
  short rollout is the one plain MuJoCo (``mj_step``, computed here) gives, within :data:`TOLERANCE`;
* **pushes**: a push changes the free robot's momentum by its impulse, and ends when its window does;
* **divergence**: a blown-up robot is flagged and explained, the others step on, and raising is asked for;
* **resets**: a reset gives the spawn state whatever came before; a replace puts the robot on the new terrain.
"""

from __future__ import annotations

import copy
import dataclasses
import inspect

import mujoco
import numpy as np
import pytest

from krl.robots.a1.constants import (
    KD,
    KP,
    MOTOR_TORQUE_LIMIT,
    NUM_JOINTS,
    STANDING_HEIGHT,
    STANDING_JOINT_ANGLES,
    TOTAL_MASS,
)
from krl.sim.backend import BACKENDS, SimBackend, make_backend
from krl.sim.batch import SPAWN_CLEARANCE, SimulationUnstableError, motor_torque_bounds
from krl.sim.model import build_model
from krl.sim.pushes import Push
from krl.sim.scan import heading_points_to_world
from krl.sim.state import StateBatch
from krl.util.timing import CONTROL_DT, SUBSTEPS

TOLERANCE: dict[str, float] = {"mujoco-cpu": 0.0}
"""Largest absolute difference allowed between a backend's states and the reference's (same units as each
field: m, rad, m/s, N, …). The MuJoCo CPU backend is the reference itself: bit for bit. A backend that
integrates in float32 or sums contacts in another order states its own figure here, with its reason."""

FIELDS = [field.name for field in dataclasses.fields(StateBatch)]


@pytest.fixture(params=BACKENDS)
def kind(request) -> str:
    return request.param


def assert_close(got: StateBatch, want: StateBatch, tolerance: float) -> None:
    for name in FIELDS:
        actual, expected = getattr(got, name), getattr(want, name)
        assert actual.shape == expected.shape, name
        if actual.dtype == bool:
            np.testing.assert_array_equal(actual, expected, err_msg=name)
        else:
            np.testing.assert_allclose(actual, expected, rtol=0.0, atol=tolerance, err_msg=name)


def test_a_backend_has_every_member_of_the_protocol_as_the_protocol_spells_it(kind):
    backend = make_backend([build_model("flat")], kind=kind)
    assert isinstance(backend, SimBackend)
    for name, member in vars(SimBackend).items():
        if callable(member) and (not name.startswith("_") or name == "__len__"):
            want = inspect.signature(member).parameters
            got = inspect.signature(getattr(type(backend), name)).parameters
            assert [(p.name, p.default) for p in got.values()] == [
                (p.name, p.default) for p in want.values()
            ], name


def test_an_unknown_backend_is_refused_naming_the_known_ones():
    with pytest.raises(ValueError, match=r"unknown simulator backend 'warp'; known: mujoco-cpu"):
        make_backend([build_model("flat")], kind="warp")


def test_robots_stepped_together_are_robots_stepped_alone(kind):
    models = [
        build_model("heightfield", {"max_height_low": 0.03, "max_height_high": 0.045}, 3),
        build_model("seesaw"),
        build_model("flat"),
    ]
    together = make_backend(models, kind=kind)
    alone = [make_backend([built], kind=kind) for built in models]
    rng = np.random.default_rng(1)
    for k in range(120):
        if k == 10:
            push = Push(0.06, np.array([150.0, 60.0, 30.0]), np.array([0.1, 0.04, 0.05]), duration=0.05)
            together.push(0, push)
            alone[0].push(0, push)
        if k == 60:
            for backend, index in ((together, 2), (alone[2], 0)):
                backend.reset(index, xy=(0.4, -0.2), yaw=0.3)
        rows = np.array([0, 2]) if 30 <= k < 40 else None  # robot 1 held out for ten steps
        q = STANDING_JOINT_ANGLES + rng.uniform(-0.3, 0.3, (3, NUM_JOINTS))
        kp, kd = KP * rng.uniform(0.8, 1.2, (3, 1)), KD * rng.uniform(0.8, 1.2, (3, 1))
        tau = rng.uniform(-2.0, 2.0, (3, NUM_JOINTS))
        states = together.step(q, kp, kd, tau, rows=rows)
        for index, backend in enumerate(alone):
            if rows is None or index in rows:
                backend.step(
                    q[index : index + 1], kp[index : index + 1], kd[index : index + 1], tau[index : index + 1]
                )
        assert_close(states, StateBatch.from_states([b.states.row(0) for b in alone]), TOLERANCE[kind])
    np.testing.assert_array_equal(together.step_counts, [120, 110, 60])


def test_a_short_rollout_is_plain_mujocos(kind):
    """20 control steps of the PD law with feed-forward torques, motor envelope and five 1 ms ``mj_step``
    each, written out here; the steps are wide enough that the envelope cuts torques."""
    built = build_model("flat")
    backend = make_backend([built], kind=kind)
    model, data = copy.copy(built.model), mujoco.MjData(built.model)
    model.actuator_biasprm[:NUM_JOINTS, 1], model.actuator_biasprm[:NUM_JOINTS, 2] = -KP, -KD
    x, y = built.terrain.spawn_xy
    ground = float(np.asarray(built.terrain.height(np.array([x]), np.array([y])))[0])
    data.qpos[:3] = x, y, ground + STANDING_HEIGHT + SPAWN_CLEARANCE
    data.qpos[3:7] = 1.0, 0.0, 0.0, 0.0
    data.qpos[7:19] = STANDING_JOINT_ANGLES
    data.ctrl[:NUM_JOINTS] = KP * STANDING_JOINT_ANGLES
    mujoco.mj_forward(model, data)
    forcerange = model.actuator_forcerange[:NUM_JOINTS]  # [N·m], (12, 2)
    cut = 0  # physics results the envelope (not the constant limit) bounded
    for k in range(20):
        q = STANDING_JOINT_ANGLES + 0.6 * np.sin(0.2 * k + np.arange(NUM_JOINTS))  # [rad]
        tau = 10.0 * np.cos(0.3 * k + np.arange(NUM_JOINTS))  # [N·m]
        data.ctrl[:NUM_JOINTS] = KP * q + tau
        forcerange[:, 0], forcerange[:, 1] = motor_torque_bounds(data.qvel[6:18])
        mujoco.mj_step(model, data, nstep=SUBSTEPS)
        bounded = np.isclose(data.actuator_force[:NUM_JOINTS, None], forcerange, rtol=0.0, atol=1e-9)
        cut += int(np.sum(bounded & (np.abs(forcerange) < MOTOR_TORQUE_LIMIT)))
        states = backend.step(q[None], tau_ff=tau[None])
    assert cut and states.time[0] == pytest.approx(20 * CONTROL_DT)
    got = np.concatenate([states.base_pos[0], states.base_quat[0], states.joint_pos[0]])
    np.testing.assert_allclose(got, data.qpos[:19], rtol=0.0, atol=TOLERANCE[kind])
    got = np.concatenate([states.lin_vel_world[0], states.ang_vel_base[0], states.joint_vel[0]])
    np.testing.assert_allclose(got, data.qvel[:18], rtol=0.0, atol=TOLERANCE[kind])
    np.testing.assert_allclose(
        states.joint_torque[0], data.actuator_force[:NUM_JOINTS], rtol=0.0, atol=TOLERANCE[kind]
    )


@pytest.mark.parametrize("mode", ["control_step", "continuous"])
def test_a_push_changes_the_free_robots_momentum_by_its_impulse(kind, mode):
    built = build_model("flat")
    built.model.opt.gravity[:] = 0.0  # the backend copies the model: this one is the test's
    backend = make_backend([built], kind=kind)
    qpos = np.concatenate(
        [[0.0, 0.0, 3.0, 1.0, 0.0, 0.0, 0.0], STANDING_JOINT_ANGLES]
    )  # far above the ground
    backend.set_state(0, qpos, np.zeros(18))
    push = Push(0.02, np.array([120.0, -80.0, 40.0]), np.array([0.1, 0.05, 0.03]), duration=0.1, mode=mode)
    backend.push(0, push)
    assert backend.pending_push(0) is push
    coms = [backend.step(STANDING_JOINT_ANGLES[None]).com[0] for _ in range(40)]
    com_velocity = (coms[-1] - coms[-11]) / (10 * CONTROL_DT)  # [m/s], after the push's window
    np.testing.assert_allclose(TOTAL_MASS * com_velocity, push.impulse, rtol=1e-3)
    assert backend.pending_push(0) is None
    with pytest.raises(ValueError, match="already over"):
        backend.push(0, push)


def test_a_blown_up_robot_is_flagged_and_explained_and_the_others_step_on(kind):
    backend = make_backend([build_model("flat")] * 3, kind=kind)
    q = np.tile(STANDING_JOINT_ANGLES, (3, 1))
    before = backend.step(q)
    blown = backend.read_state(1)
    qvel = np.zeros(18)
    qvel[6] = 1e12  # [rad/s]: past MuJoCo's 1e10 bound
    backend.set_state(1, np.concatenate([blown.base_pos, blown.base_quat, blown.joint_pos]), qvel)
    after = backend.step(q)
    np.testing.assert_array_equal(backend.unstable, [False, True, False])
    np.testing.assert_array_equal(after.fallen, [False, True, False])
    assert isinstance(backend.divergence(1), SimulationUnstableError)
    assert backend.divergence(0) is None and backend.divergence(2) is None
    assert np.all(after.time[[0, 2]] > before.time[[0, 2]])
    with pytest.raises(SimulationUnstableError, match="unstable"):
        backend.step(q, raise_on_divergence=True)
    backend.reset(1)
    assert not backend.unstable.any() and backend.divergence(1) is None
    assert not backend.step(q).fallen.any()


def test_a_reset_gives_the_spawn_state_whatever_came_before(kind):
    built = build_model("heightfield", seed=2)
    backend, fresh = make_backend([built] * 2, kind=kind), make_backend([built], kind=kind)
    spawn = fresh.states
    x, y = built.terrain.spawn_xy
    ground = float(np.asarray(built.terrain.height(np.array([x]), np.array([y])))[0])
    np.testing.assert_allclose(spawn.base_pos[0], [x, y, ground + STANDING_HEIGHT + SPAWN_CLEARANCE])
    np.testing.assert_array_equal(spawn.joint_pos[0], STANDING_JOINT_ANGLES)
    assert not spawn.lin_vel_world.any() and not spawn.joint_vel.any() and spawn.time[0] == 0.0
    backend.push(1, Push(0.5, np.array([300.0, 0.0, 0.0]), np.zeros(3)))
    rng = np.random.default_rng(4)
    for _ in range(30):
        backend.step(
            STANDING_JOINT_ANGLES + rng.uniform(-0.5, 0.5, (2, NUM_JOINTS)), kp=np.full((2, 12), 30.0)
        )
    state = backend.reset(1)
    assert_close(backend.states, StateBatch.from_states([backend.read_state(0), state]), 0.0)
    assert_close(StateBatch.from_states([state]), spawn, TOLERANCE[kind])
    np.testing.assert_array_equal(backend.step_counts, [30, 0])
    assert backend.pending_push(1) is None
    # the gains are Table 4.2's again: the next step is a fresh robot's
    stepped = backend.step(np.tile(STANDING_JOINT_ANGLES, (2, 1)))
    assert_close(stepped.rows(np.array([1])), fresh.step(STANDING_JOINT_ANGLES[None]), TOLERANCE[kind])


def test_a_replace_puts_the_robot_on_the_new_terrain(kind):
    backend = make_backend([build_model("flat")] * 2, kind=kind)
    stairs = build_model("stairs")
    state = backend.replace(1, stairs)
    assert backend.terrain(1) is stairs.terrain and backend.terrain(0).name == "flat"
    assert_close(StateBatch.from_states([state]), make_backend([stairs], kind=kind).states, TOLERANCE[kind])
    points = np.array([[0.0, 0.0], [0.5, 0.1], [1.5, -0.2], [3.0, 0.0]])  # heading frame [m]
    heights = backend.terrain_heights(points)
    states = backend.states
    for index, terrain in enumerate((backend.terrain(0), stairs.terrain)):
        xy = heading_points_to_world(points, states.base_pos[index], states.rpy[index, 2])
        np.testing.assert_allclose(heights[index], terrain.height(xy[:, 0], xy[:, 1]), atol=1e-9)
    assert np.ptp(heights[1]) > 0.05 and not heights[0].any()  # the stairs rise, the flat ground does not
