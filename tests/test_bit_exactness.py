"""The bit-exactness rule (docs/architecture.md, krl.util.affine, krl.sim.state): a robot's numbers computed
in a batch are the numbers computed for it alone, bit for bit, whatever the batch's size and order.

A walk is chaotic, so a last-bit difference grows into another run: a robot's record must not depend on
which robots are evaluated beside it. This checks every row-wise computation on the way from a state to an
action: the dense layer, the kernel and the policy made of it, and the state readout. Replacing a row-wise
product by one batched product (which BLAS sums in another order) fails here.
"""

from __future__ import annotations

import numpy as np
import pytest

from krl.agent.policy import load_policy, shipped_policy_dir
from krl.kernel.registry import load_model
from krl.sim.state import FIELD_NAMES, state_fields
from krl.util.affine import affine

ROBOTS = 12
"""The largest batch checked; every size from 1 to it is."""


def _orders(size: int, rng: np.random.Generator) -> list[np.ndarray]:
    """Row orders a batch of ``size`` robots is checked in: as given, reversed, and two shuffles."""
    return [np.arange(size), np.arange(size)[::-1], rng.permutation(size), rng.permutation(size)]


def _assert_rows_as_alone(batched, rows: np.ndarray, what: str) -> None:
    """``batched(rows[order])`` equals, row for row and bit for bit, ``batched`` of each row alone, for
    every batch size 1..ROBOTS and the orders of :func:`_orders`. ``batched``: (N, ...) -> (N, ...)."""
    alone = np.concatenate([batched(rows[k : k + 1]) for k in range(ROBOTS)])
    rng = np.random.default_rng(0)
    for size in range(1, ROBOTS + 1):
        for order in _orders(size, rng):
            got = batched(rows[order])
            if not np.array_equal(got, alone[order]):
                wrong = sorted(int(order[k]) for k in np.flatnonzero((got != alone[order]).any(axis=1)))
                pytest.fail(f"{what}: robots {wrong} in a batch of {size} differ from themselves alone")


@pytest.mark.parametrize(("size_in", "size_out"), [(7, 256), (256, 256), (54, 128), (128, 12)])
def test_the_row_wise_dense_layer_computes_each_row_as_alone(size_in, size_out):
    rng = np.random.default_rng(size_in)
    weight, bias = rng.normal(size=(size_out, size_in)), rng.normal(size=size_out)
    rows = rng.normal(size=(ROBOTS, size_in))
    _assert_rows_as_alone(lambda x: affine(x, weight, bias, rowwise=True), rows, "affine(rowwise=True)")


def test_the_check_catches_a_batched_product():
    """Where this machine's BLAS sums a batched product's rows otherwise than each row alone (as here), the
    check above fails a dense layer that computes the batch in one product."""
    rng = np.random.default_rng(54)
    weight, bias, rows = rng.normal(size=(128, 54)), rng.normal(size=128), rng.normal(size=(ROBOTS, 54))
    alone = np.concatenate([affine(rows[k : k + 1], weight, bias) for k in range(ROBOTS)])
    if np.array_equal(affine(rows, weight, bias), alone):
        pytest.skip(
            "this machine's BLAS computes a batch's rows as alone: a batched product goes unseen here"
        )
    with pytest.raises(pytest.fail.Exception, match="differ from themselves alone"):
        _assert_rows_as_alone(lambda x: x @ weight.T + bias, rows, "one batched product")


def test_the_shipped_kernel_predicts_each_robot_as_alone():
    kernel = load_model("base")
    rows = np.random.default_rng(1).normal(size=(ROBOTS, kernel.input_size))
    _assert_rows_as_alone(lambda x: kernel.predict(x, rowwise=True), rows, "Kernel.predict(rowwise=True)")


def test_a_shipped_policy_acts_for_each_robot_as_alone():
    policy = load_policy(shipped_policy_dir() / "agent-rp" / "seed150.npz")
    scale = np.sqrt(policy.obs_var)
    rows = policy.obs_mean + scale * np.random.default_rng(2).normal(size=(ROBOTS, policy.observation_size))
    _assert_rows_as_alone(lambda x: policy.act(x, rowwise=True), rows, "Policy.act(rowwise=True)")


def _robots(count: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """What ``MjData`` holds after a step for ``count`` robots (the inputs of :func:`state_fields`, each a
    C-contiguous copy as :mod:`krl.sim.batch` passes them), drawn at random: trunk orientations all round,
    some of them fallen, feet and trunk in and out of contact."""
    quat = rng.normal(size=(count, 4))
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    w, x, y, z = quat.T
    rot = np.stack(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    ).transpose(2, 0, 1)
    qpos = rng.normal(size=(count, 19))
    qpos[:, 3:7] = quat
    return {
        "time": rng.uniform(0, 60, size=count),
        "qpos": qpos,
        "qvel": rng.normal(size=(count, 18)),
        "rot": rot.reshape(count, 9).copy(),  # contiguous, as the simulator's copies are
        "foot_world": rng.normal(size=(count, 4, 3)),
        "foot_force": np.maximum(rng.normal(size=(count, 4)) * 50, 0.0),
        "trunk_force": np.maximum(rng.normal(size=count) * 50 - 40, 0.0),
        "joint_torque": rng.normal(size=(count, 12)) * 20,
        "com": rng.normal(size=(count, 3)),
    }


def test_the_state_readout_of_a_batch_is_each_robots_readout_alone():
    robots = _robots(ROBOTS, np.random.default_rng(3))
    alone = [state_fields(*(value[k] for value in robots.values())) for k in range(ROBOTS)]
    rng = np.random.default_rng(4)
    for size in range(1, ROBOTS + 1):
        for order in _orders(size, rng):
            batch = state_fields(*(value[order] for value in robots.values()))
            for position, robot in enumerate(order):
                for name, got, want in zip(FIELD_NAMES, batch, alone[robot], strict=True):
                    assert np.array_equal(got[position], want), (
                        f"state_fields' {name} of robot {robot} in a batch of {size} differs from its "
                        "readout alone"
                    )
