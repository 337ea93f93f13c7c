"""The residual environment: Gymnasium's checks, the reward's terms, batched = single environments."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from krl.agent.config import AgentConfig, AgentConfigError, EnvConfig, ObservationConfig
from krl.agent.env import ResidualVecEnv
from krl.agent.observation import FEATURES, layout, observation_size
from krl.envs.residual import A1ResidualEnv


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
    actor = tuple(name for name, feature in FEATURES.items() if not feature.privileged)
    critic = tuple(name for name, feature in FEATURES.items() if feature.privileged)
    config = AgentConfig(observation=ObservationConfig(features=actor, critic_features=critic))
    env = A1ResidualEnv(config)
    observation, _ = env.reset(seed=0)
    assert observation.shape == (observation_size(tuple(FEATURES), config.observation.scan),)
    assert np.isfinite(observation).all()


def test_unknown_feature_and_malformed_config_are_one_line_errors(tmp_path):
    with pytest.raises(AgentConfigError, match="unknown observation feature 'phases'"):
        ObservationConfig(features=("phases",))
    path = tmp_path / "agent.json"
    path.write_text('{"ppo": {"learning_rate": "fast"}}')
    with pytest.raises(AgentConfigError, match="learning_rate must be a number, got 'fast'"):
        AgentConfig.load(path)
    path.write_text('{"ppo": {"lr": 0.1}}')
    with pytest.raises(AgentConfigError, match="unknown setting 'lr'"):
        AgentConfig.load(path)
    path.write_text("{not json")
    with pytest.raises(AgentConfigError, match="not valid"):
        AgentConfig.load(path)


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"env": {"pushes": "no"}}, "config.env.pushes must be true or false, got 'no'"),
        ({"ppo": {"normalize_observations": "false"}}, "normalize_observations must be true or false"),
        ({"ppo": {"normalize_rewards": 1}}, "normalize_rewards must be true or false, got 1"),
        ({"num_envs": 16.0}, "config.num_envs must be an integer, got 16.0"),
        ({"workers": True}, "config.workers must be an integer, got True"),
        ({"env": {"d_min": "0.5"}}, "config.env.d_min must be a number, got '0.5'"),
        ({"residual": {"kernel": 3}}, "config.residual.kernel must be a text, got 3"),
        ({"residual": {"residual_bound": [0.1, "x", 0.1]}}, "residual_bound must be a number, got 'x'"),
        ({"ppo": {"shared": 128}}, "config.ppo.shared must be a list, got 128"),
        ({"observation": {"features": ["phase", 3]}}, "features must be a text, got 3"),
        ({"env": {"reward": "rpp"}}, "config.env.reward: unknown reward 'rpp'; known: rp, base, initial"),
    ],
)
def test_every_config_field_is_type_checked(data, message):
    with pytest.raises(AgentConfigError, match=message.replace("(", r"\(").replace(")", r"\)")):
        AgentConfig.from_json(data)


def test_a_config_round_trips_with_its_whole_reward():
    config = AgentConfig.from_json({"env": {"reward": "base"}, "ppo": {"normalize_rewards": False}})
    assert AgentConfig.from_json(config.to_json()) == config
    assert config.to_json()["env"]["reward"]["terms"][0]["name"] == "linear_velocity"


@pytest.mark.parametrize("shape", [(3, 4), (2, 6), (12, 1), (1, 12), (11,)])
def test_an_action_of_another_shape_is_refused(shape):
    env = A1ResidualEnv()
    env.reset(seed=1)
    with pytest.raises(ValueError, match=r"an action has shape \(12,\)"):
        env.step(np.zeros(shape))


def test_an_ended_episode_reports_exactly_the_documented_keys():
    from krl.agent.env import EPISODE_INFO_KEYS

    config = AgentConfig(env=EnvConfig(episode_time=0.05, pushes=False))  # ends after 10 control steps
    env = A1ResidualEnv(config)
    env.reset(seed=2)
    for _ in range(20):
        _, _, terminated, truncated, info = env.step(np.zeros(12))
        if terminated or truncated:
            break
    assert tuple(info["episode"]) == EPISODE_INFO_KEYS


def test_the_env_docstring_shows_every_feature_of_the_registry():
    from krl.agent.observation import observation_table

    assert observation_table().replace("\n", "\n    ") in A1ResidualEnv.__doc__
    assert all(
        f"``{name}`` | {feature.size if feature.size > 0 else 'grid'} |" in A1ResidualEnv.__doc__
        for name, feature in FEATURES.items()
    )
    assert "gives D = 54" in A1ResidualEnv.__doc__
    assert observation_size(AgentConfig().observation.features) == 54
