"""krl/A1-v0: Gymnasium API conformance on every terrain, observation layout, episode rules."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import krl  # noqa: F401  (registers the environments)
from krl.envs.a1 import OBSERVATION_SIZE, OBSERVATION_SLICES
from krl.robots.a1.constants import STANDING_JOINT_ANGLES
from krl.sim.terrains import TERRAIN_NAMES
from krl.util.timing import CONTROL_DT


@pytest.mark.parametrize("terrain", TERRAIN_NAMES)
def test_check_env_and_standing_on_every_terrain(terrain):
    env = gym.make("krl/A1-v0", terrain=terrain)
    check_env(env.unwrapped, skip_render_check=True)
    obs, _ = env.reset(seed=4)
    assert obs.shape == (OBSERVATION_SIZE,)
    action = STANDING_JOINT_ANGLES.astype(np.float32)
    for _ in range(400):  # 2 s
        obs, reward, terminated, truncated, _ = env.step(action)
        assert np.isfinite(obs).all()
        assert not truncated
    assert not terminated, f"fell on {terrain}"
    assert obs[OBSERVATION_SLICES["base_height"]][0] > 0.2
    assert reward == 1.0
    env.close()


def test_observation_layout_and_seeding():
    env = gym.make("krl/A1-v0")
    first, _ = env.reset(seed=11)
    second, _ = env.reset(seed=11)
    np.testing.assert_array_equal(first, second)
    third, _ = env.reset(seed=12)
    assert not np.array_equal(first, third)
    np.testing.assert_allclose(first[OBSERVATION_SLICES["projected_gravity"]], [0, 0, -1], atol=1e-6)
    assert first[OBSERVATION_SLICES["joint_pos"]] == pytest.approx(STANDING_JOINT_ANGLES, abs=0.051)
    assert env.spec.max_episode_steps == 2000


def test_fall_terminates_and_bad_action_rejected():
    env = gym.make("krl/A1-v0")
    env.reset(seed=0)
    limp = np.array([0.0, 4.0, -0.92] * 4, dtype=np.float32)  # legs folded up over the back
    terminated = False
    for _ in range(600):
        _, reward, terminated, _, info = env.step(limp)
        if terminated:
            break
    assert terminated and info["fallen"] and reward == 0.0
    # stepped on after the fall, the same simulation goes on (the episode loop starts a new episode)
    _, reward, terminated, _, after = env.step(limp)
    assert after["time"] == pytest.approx(info["time"] + CONTROL_DT) and terminated and reward == 0.0
    with pytest.raises(ValueError, match=r"shape \(12,\)"):
        env.step(np.zeros(3))


def test_unknown_terrain_is_a_clear_error():
    with pytest.raises(ValueError, match="moon"):
        gym.make("krl/A1-v0", terrain="moon")
