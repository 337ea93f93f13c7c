"""The residual environment: Gymnasium's checks, the reward's terms, batched = single environments."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from krl.agent.config import AgentConfig, AgentConfigError, EnvConfig, ObservationConfig
from krl.agent.env import A1ResidualEnv, ResidualVecEnv
from krl.agent.observation import FEATURES, layout, observation_size


def test_registered_env_passes_check_env():
    env = gym.make("krl/A1Residual-v0")
    check_env(env.unwrapped, skip_render_check=True)
    observation, info = env.reset(seed=3)
    assert observation.shape == (observation_size(AgentConfig().observation.features),)
    assert info["terrain"].startswith(("heightfield", "perlin"))
    env.close()


def test_reward_is_the_sum_of_its_logged_terms():
    env = A1ResidualEnv()
    env.reset(seed=5)
    rng = np.random.default_rng(0)
    for _ in range(40):
        _, reward, terminated, truncated, info = env.step(rng.uniform(-1, 1, 12))
        assert reward == pytest.approx(sum(info["reward_terms"].values()), abs=1e-12)
        assert set(info["reward_terms"]) >= {"linear_velocity", "gravity", "roll_pitch", "fall"}
        if terminated or truncated:
            break


def test_vectorised_env_makes_the_transitions_of_single_envs():
    config = AgentConfig(env=EnvConfig(push_interval=(0.05, 0.1)))  # pushes within the test's steps
    count, seed, steps = 3, 11, 60
    vec = ResidualVecEnv(config, count, seed=seed)
    singles = [A1ResidualEnv(config) for _ in range(count)]
    obs_vec = vec.reset()
    obs_single = np.array([env.reset(seed=seed + i)[0] for i, env in enumerate(singles)])
    np.testing.assert_allclose(obs_vec, obs_single, rtol=1e-12, atol=1e-12)
    rng = np.random.default_rng(1)
    for _ in range(steps):
        actions = rng.uniform(-1, 1, (count, 12))
        vec.step_async(actions)
        obs_vec, rewards, dones, _ = vec.step_wait()
        results = [env.step(a) for env, a in zip(singles, actions, strict=True)]
        np.testing.assert_allclose(obs_vec, [r[0] for r in results], rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(rewards, [r[1] for r in results], rtol=1e-6, atol=1e-9)
        assert not dones.any()


def test_observation_layout_is_documented_and_selectable():
    rows = layout(("base_lin_vel", "phase", "kernel_targets", "contact_force"))
    assert [(r["name"], r["start"], r["stop"]) for r in rows] == [
        ("base_lin_vel", 0, 3),
        ("phase", 3, 7),
        ("kernel_targets", 7, 19),
        ("contact_force", 19, 23),
    ]
    config = AgentConfig(observation=ObservationConfig(features=tuple(FEATURES)))
    env = A1ResidualEnv(config)
    observation, _ = env.reset(seed=0)
    assert observation.shape == (sum(f.size for f in FEATURES.values()),)


def test_unknown_feature_and_malformed_config_are_one_line_errors(tmp_path):
    with pytest.raises(AgentConfigError, match="unknown observation feature 'phases'"):
        ObservationConfig(features=("phases",))
    path = tmp_path / "agent.json"
    path.write_text('{"ppo": {"learning_rate": "fast"}}')
    with pytest.raises(AgentConfigError, match="learning_rate must be a finite number"):
        AgentConfig.load(path)
    path.write_text('{"ppo": {"lr": 0.1}}')
    with pytest.raises(AgentConfigError, match="unknown setting 'lr'"):
        AgentConfig.load(path)
    path.write_text("{not json")
    with pytest.raises(AgentConfigError, match="not valid"):
        AgentConfig.load(path)
