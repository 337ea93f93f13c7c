"""The reward (Table 4.8 + roll/pitch) on hand-worked states."""

import math

import numpy as np
import pytest
from eval_fakes import make_state

from krl.task.reward import AGENT_BASE_REWARD, EVALUATION_REWARD, TERM_NAMES, RBFTerm, reward_terms


def test_terms_by_hand():
    # heading yaw 0: realised (vx, vy, wz) = (0.4, 0.1, 0.0); command (0.5, 0.0, 0.2); level trunk
    state = make_state(xy=(0.0, 0.0), yaw=0.0, lin_vel=(0.4, 0.1, 0.0), ang_vel=(0.0, 0.0, 0.0))
    terms = reward_terms(EVALUATION_REWARD, np.array([0.5, 0.0, 0.2]), state, 2.0, False, False)
    assert list(terms) == list(TERM_NAMES)
    assert terms["linear_velocity"] == pytest.approx(0.0076 * math.exp(-18.42 * (0.01 + 0.01)))
    assert terms["angular_velocity"] == pytest.approx(0.0264 * math.exp(-7.47 * 0.04))
    assert terms["gravity"] == pytest.approx(0.0298)
    assert terms["target_distance"] == pytest.approx(0.0169 * math.exp(-0.74 * 4.0))
    assert terms["roll_pitch"] == pytest.approx(0.0298)
    assert terms["fall"] == 0.0 and terms["target_reached"] == 0.0


def test_velocity_is_read_in_the_heading_frame():
    # facing +y and moving along +y at 0.5 m/s is forward motion: no velocity error for command (0.5, 0, 0)
    state = make_state(xy=(0.0, 0.0), yaw=math.pi / 2, lin_vel=(0.0, 0.5, 0.0))
    terms = reward_terms(EVALUATION_REWARD, np.array([0.5, 0.0, 0.0]), state, 0.0, False, False)
    assert terms["linear_velocity"] == pytest.approx(0.0076)


def test_tilt_lowers_gravity_and_roll_pitch_terms():
    state = make_state(roll=0.2)
    terms = reward_terms(EVALUATION_REWARD, np.zeros(3), state, 0.0, False, False)
    # projected gravity of a roll r: (0, -sin r, -cos r); squared distance to (0, 0, -1) = 2 - 2 cos r
    assert terms["gravity"] == pytest.approx(0.0298 * math.exp(-2.35 * (2 - 2 * math.cos(0.2))))
    assert terms["roll_pitch"] == pytest.approx(0.0298 * math.exp(-7.47 * 0.04))


def test_nominal_terms_and_agent_base():
    state = make_state()
    terms = reward_terms(AGENT_BASE_REWARD, np.zeros(3), state, 0.3, True, True)
    assert "roll_pitch" not in terms
    assert terms["fall"] == -19.8 and terms["target_reached"] == 8.75


def test_bad_rbf_parameters():
    with pytest.raises(ValueError, match="steepness"):
        RBFTerm(steepness=-1.0, weight=1.0)
    with pytest.raises(ValueError, match="weight"):
        RBFTerm(steepness=1.0, weight=math.nan)
