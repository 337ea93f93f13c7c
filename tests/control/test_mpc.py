"""Convex MPC: exact discretisation, static balance, elimination of swing feet, limits, errors."""

import numpy as np
import pytest
import scipy.linalg

from krl.control.mpc import GRAVITY, ConvexMPC, MPCParams, skew
from krl.robots.a1.constants import STANDING_INERTIA, TOTAL_MASS

FEET = np.array([[0.18, -0.13, -0.25], [0.18, 0.13, -0.25], [-0.18, -0.13, -0.25], [-0.18, 0.13, -0.25]])


def standing_problem(height=0.25):
    x0 = np.zeros(13)
    x0[5], x0[12] = height, GRAVITY
    return x0, np.tile(x0, (10, 1))


def test_closed_form_discretisation_equals_matrix_exponential():
    mpc = ConvexMPC()
    b = mpc.input_matrix(FEET, np.eye(3))
    a = np.zeros((13, 13))
    a[0:3, 6:9] = a[3:6, 9:12] = np.eye(3)
    a[11, 12] = 1.0
    block = np.zeros((25, 25))
    block[:13, :13], block[:13, 13:] = a, b
    expm = scipy.linalg.expm(block * 0.025)
    np.testing.assert_allclose(mpc.a_d, expm[:13, :13], atol=1e-14)
    np.testing.assert_allclose(mpc.phi @ b, expm[:13, 13:], atol=1e-12)


def test_input_matrix_is_the_rigid_body_dynamics():
    mpc = ConvexMPC()
    b = mpc.input_matrix(FEET, np.eye(3))
    force = np.array([1.0, 2.0, 30.0])
    u = np.zeros(12)
    u[3:6] = force  # FL only
    np.testing.assert_allclose(b[9:12] @ u, force / TOTAL_MASS)
    np.testing.assert_allclose(b[6:9] @ u, np.linalg.solve(STANDING_INERTIA, np.cross(FEET[1], force)))
    np.testing.assert_allclose(skew(FEET[1]) @ force, np.cross(FEET[1], force))


def test_standing_robot_is_held_up_by_its_weight():
    x0, reference = standing_problem()
    solution = ConvexMPC().solve(x0, reference, FEET, np.eye(3), np.ones((10, 4), bool))
    assert solution.forces[:, 2].sum() == pytest.approx(TOTAL_MASS * -GRAVITY, rel=0.05)
    np.testing.assert_allclose(solution.forces[:, :2], 0.0, atol=1.0)
    assert solution.num_variables == 120


def test_swing_feet_are_eliminated_and_forces_respect_the_pyramid():
    params = MPCParams()
    x0, reference = standing_problem(0.22)  # too low: the MPC pushes up hard
    reference[:, 9] = 0.5  # and wants to accelerate forward
    contacts = np.ones((10, 4), bool)
    contacts[:5, [1, 2]] = False
    contacts[5:, [0, 3]] = False
    solution = ConvexMPC(params).solve(x0, reference, FEET, np.eye(3), contacts)
    assert solution.num_variables == 3 * contacts.sum()
    assert np.all(solution.plan[~contacts] == 0.0)
    fz = solution.plan[..., 2]
    assert fz.min() >= params.min_normal_force - 1e-6 and fz.max() <= params.max_normal_force + 1e-6
    tangential = np.abs(solution.plan[..., :2])
    assert np.all(tangential <= params.friction * fz[..., None] + 1e-6)
    assert solution.forces[0, 0] > 0  # pushes forward


def test_no_stance_feet_gives_zero_forces():
    x0, reference = standing_problem()
    solution = ConvexMPC().solve(x0, reference, FEET, np.eye(3), np.zeros((10, 4), bool))
    assert solution.num_variables == 0 and not solution.forces.any()


@pytest.mark.parametrize(
    ("field", "value"),
    [("horizon", 0), ("dt", -0.1), ("friction", 0.0), ("max_normal_force", -1.0), ("weights", (1.0,) * 12)],
)
def test_bad_parameters_are_rejected(field, value):
    with pytest.raises(ValueError, match="MPC"):
        MPCParams(**{field: value})
