"""The reward (Table 4.8 + roll/pitch) on hand-worked states, and rewards as data (named, saved, checked)."""

import json
import math

import numpy as np
import pytest
from eval_fakes import make_state

from krl.task.reward import (
    AGENT_BASE_REWARD,
    EVALUATION_REWARD,
    INITIAL_REWARD,
    REWARDS,
    RBFTerm,
    RewardConfig,
    RewardConfigError,
    reward_name,
    reward_terms,
)

TERM_NAMES = (
    "linear_velocity",
    "angular_velocity",
    "gravity",
    "target_distance",
    "roll_pitch",
    "fall",
    "target_reached",
)


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
    with pytest.raises(RewardConfigError, match="steepness"):
        RBFTerm("gravity", "gravity", (0.0, 0.0, -1.0), steepness=-1.0, weight=1.0)
    with pytest.raises(RewardConfigError, match="weight"):
        RBFTerm("gravity", "gravity", (0.0, 0.0, -1.0), steepness=1.0, weight=math.nan)
    with pytest.raises(RewardConfigError, match="no commanded value"):
        RBFTerm("gravity", "gravity", "command", steepness=1.0, weight=1.0)
    with pytest.raises(RewardConfigError, match="3 numbers"):
        RBFTerm("gravity", "gravity", (0.0, -1.0), steepness=1.0, weight=1.0)
    with pytest.raises(RewardConfigError, match="unknown quantity 'energy'"):
        RBFTerm("energy", "energy", (0.0,), steepness=1.0, weight=1.0)


def test_the_thesis_rewards_by_name():
    assert REWARDS["rp"] is EVALUATION_REWARD and REWARDS["base"] is AGENT_BASE_REWARD
    assert EVALUATION_REWARD.term_names == TERM_NAMES
    assert AGENT_BASE_REWARD.terms == EVALUATION_REWARD.terms[:4]
    # Table 4.6: the same four terms and steepnesses, every weight 0.01, no nominal terms
    assert [(t.name, t.steepness, t.weight) for t in INITIAL_REWARD.terms] == [
        (t.name, t.steepness, 0.01) for t in AGENT_BASE_REWARD.terms
    ]
    terms = reward_terms(INITIAL_REWARD, np.zeros(3), make_state(), 0.3, True, True)
    assert list(terms) == list(TERM_NAMES[:4])
    assert reward_name(AGENT_BASE_REWARD) == "base" and reward_name(INITIAL_REWARD) == "initial"


def test_a_reward_round_trips_through_json_and_names_resolve():
    for name, reward in REWARDS.items():
        data = json.loads(json.dumps(reward.to_json()))
        assert RewardConfig.from_json(data) == reward
        assert RewardConfig.from_json(name) == reward
    custom = RewardConfig(
        terms=(RBFTerm("upright", "gravity", (0.0, 0.0, -1.0), 5.0, 0.02),), target_bonus=None
    )
    assert reward_name(custom) is None
    assert RewardConfig.from_json(json.loads(json.dumps(custom.to_json()))) == custom
    assert reward_terms(custom, np.zeros(3), make_state(), 0.3, True, True) == {
        "upright": 0.02,
        "fall": -19.8,
    }


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ("rpp", "unknown reward 'rpp'; known: rp, base, initial"),
        ({"terms": [], "bonus": 1}, "unknown reward setting 'bonus'"),
        ({"terms": [{"name": "a", "quantity": "gravity"}]}, "reward term 'a': missing 'target'"),
        ({"terms": "gravity"}, "reward terms must be a list of tables"),
        ({"terms": [], "fall_penalty": "big"}, "fall_penalty must be a finite number"),
    ],
)
def test_malformed_rewards_are_one_line_errors(data, message):
    with pytest.raises(RewardConfigError, match=message.replace("(", r"\(")) as error:
        RewardConfig.from_json(data)
    assert "\n" not in str(error.value)


def test_a_shortfall_term_costs_only_falling_short_of_the_command():
    term = RBFTerm("v", "planar_velocity", "command", 10.0, 1.0, shortfall=True)
    reward = RewardConfig((term,), None, None)
    command = np.array([0.5, 0.0, 0.0])
    faster = reward_terms(reward, command, make_state(lin_vel=(0.7, 0.1, 0.0)), 0.0, False, False)
    assert faster["v"] == pytest.approx(1.0)  # ahead of the command, and sideways where it asks nothing
    slower = reward_terms(reward, command, make_state(lin_vel=(0.3, 0.1, 0.0)), 0.0, False, False)
    assert slower["v"] == pytest.approx(math.exp(-10.0 * 0.04))
    backward = np.array([-0.5, 0.0, 0.0])
    assert reward_terms(reward, backward, make_state(lin_vel=(-0.2, 0.0, 0.0)), 0.0, False, False)[
        "v"
    ] == pytest.approx(math.exp(-10.0 * 0.09))
    with pytest.raises(RewardConfigError, match="shortfall needs the command"):
        RBFTerm("g", "gravity", (0.0, 0.0, -1.0), 1.0, 1.0, shortfall=True)


def test_penalty_terms_and_the_new_velocity_quantities():
    terms = (
        RBFTerm("vz", "vertical_velocity", (0.0,), 18.42, 0.01, penalty=True),
        RBFTerm("rates", "roll_pitch_rate", (0.0, 0.0), 7.47, 0.01),
    )
    state = make_state(lin_vel=(0.0, 0.0, 0.2), ang_vel=(0.3, 0.0, 0.0))  # roll rate 0.3 (level trunk)
    values = reward_terms(RewardConfig(terms, None, None), np.zeros(3), state, 0.0, False, False)
    assert values["vz"] == pytest.approx(0.01 * (math.exp(-18.42 * 0.04) - 1.0))
    assert values["rates"] == pytest.approx(0.01 * math.exp(-7.47 * 0.09))


def test_stance_memory_measures_slip_and_drift_of_feet_on_the_ground():
    from types import SimpleNamespace

    from krl.task.reward import StanceMemory

    def feet(dx, contact):
        positions = np.zeros((4, 3))
        positions[:, 0] = dx
        return SimpleNamespace(foot_pos_world=positions, foot_contact=np.array(contact, dtype=bool))

    memory = StanceMemory()
    assert memory.update(feet([0, 0, 0, 0], [1, 1, 0, 0])) == {"stance_slip": 0.0, "stance_drift": 0.0}
    step = memory.update(feet([0.001, 0.001, 0.002, 0], [1, 1, 1, 0]))  # foot 2 lands: not yet in stance
    assert step["stance_slip"] == pytest.approx(0.002) and step["stance_drift"] == pytest.approx(0.002)
    step = memory.update(feet([0.002, 0.001, 0.003, 0], [1, 1, 1, 0]))
    assert step["stance_slip"] == pytest.approx(0.001 + 0.0 + 0.001)
    assert step["stance_drift"] == pytest.approx(0.002 + 0.001 + 0.001)  # foot 2 from where it landed
    memory.reset()
    assert memory.update(feet([5, 5, 5, 5], [1, 1, 1, 1]))["stance_slip"] == 0.0
    stance = RewardConfig((RBFTerm("slip", "stance_slip", (0.0,), 1.0, 1.0),), None, None)
    assert stance.needs_stance and not EVALUATION_REWARD.needs_stance
    with pytest.raises(RewardConfigError, match="StanceMemory"):
        reward_terms(stance, np.zeros(3), make_state(), 0.0, False, False)


def test_term_options_round_trip_and_are_written_only_when_set():
    term = RBFTerm("v", "planar_velocity", "command", 10.0, 1.0, shortfall=True, penalty=True)
    reward = RewardConfig((term,), -5.0, 5.0)
    data = json.loads(json.dumps(reward.to_json()))
    assert data["terms"][0]["shortfall"] is True and RewardConfig.from_json(data) == reward
    assert all("shortfall" not in t and "penalty" not in t for t in INITIAL_REWARD.to_json()["terms"])
    data["terms"][0]["penalty"] = "yes"
    with pytest.raises(RewardConfigError, match="penalty must be true or false"):
        RewardConfig.from_json(data)
