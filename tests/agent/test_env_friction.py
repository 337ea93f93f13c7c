"""Friction randomisation, a training option: its checks, its round trip, and no change by default."""

import types

import numpy as np
import pytest

from krl.agent.config import AgentConfig, AgentConfigError, EnvConfig
from krl.agent.env import ResidualEnvBatch


@pytest.mark.parametrize(
    "friction, message",
    [
        ((0.0, 1.0), "friction must satisfy 0 < low <= high <= 5"),
        ((0.8, 0.5), "friction must satisfy 0.0 <= low <= high"),
        ((0.5, 6.0), "friction must satisfy 0 < low <= high <= 5"),
        ((0.5,), "friction must be a (low, high) pair"),
        ((0.5, float("nan")), "friction must be a (low, high) pair"),
    ],
)
def test_a_bad_friction_range_is_one_line(friction, message):
    with pytest.raises(AgentConfigError) as error:
        EnvConfig(friction=friction)
    assert message in str(error.value) and "\n" not in str(error.value)


def test_the_friction_range_round_trips_and_old_configs_keep_the_thesiss_ground():
    config = AgentConfig(env=EnvConfig(friction=(0.4, 1.2)))
    assert config.to_json()["env"]["friction"] == [0.4, 1.2]
    assert AgentConfig.from_json(config.to_json()) == config
    old = config.to_json()
    del old["env"]["friction"]  # a config or policy file written before the option
    assert AgentConfig.from_json(old).env.friction == (1.0, 1.0)
    with pytest.raises(AgentConfigError, match=r"config.env.friction must be a list"):
        AgentConfig.from_json({"env": {"friction": 0.5}})


def terrain(env: EnvConfig, seed: int):
    """``ResidualEnvBatch._terrain`` of one environment seeded ``seed`` (without the kernel and robots
    a whole batch would load): the model built and the environment's rng after the draws."""
    holder = types.SimpleNamespace(
        rngs=[np.random.default_rng(seed)], config=AgentConfig(env=env), terrain_names=[""]
    )
    built = ResidualEnvBatch._terrain(holder, 0)
    return built, holder.rngs[0], holder.terrain_names[0]


def test_the_default_draws_no_friction_and_a_range_draws_one_per_terrain():
    for seed in range(4):
        built, rng, name = terrain(EnvConfig(), seed)
        expected = np.random.default_rng(seed)
        terrain_seed = int(expected.integers(2**31))
        expected.random()  # height field or hills: the draws of runs before the option
        assert rng.random() == expected.random() and name.endswith(f"-{terrain_seed}")
        assert built.model.geom("floor").friction[0] == 1.0
    frictions = set()
    for seed in range(4):
        built, _, name = terrain(EnvConfig(friction=(0.3, 0.9)), seed)
        mu = float(built.model.geom("floor").friction[0])
        assert 0.3 <= mu <= 0.9 and built.model.geom("terrain").friction[0] == mu
        assert name.endswith(f"-mu{mu:.3f}")
        frictions.add(mu)
    assert len(frictions) == 4
    built, _, _ = terrain(EnvConfig(friction=(0.6, 0.6)), 0)  # one value: set, not drawn
    assert built.model.geom("floor").friction[0] == 0.6
