"""The training terrain options, friction randomisation and stepped pyramids: their checks, their round
trips, and the thesis's draws by default."""

import hashlib
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


DEFAULT_DRAWS_SHA256 = "612adbacc7ae4db57553e25b3fc0c5faa1e12498404e67657691d1484b239a6f"
"""Digest of the terrains the default training draws for seeds 0-7 (names, height-field data, the rng's next
draw), made before the option existed: the option must leave them as they were."""


def test_the_default_draws_are_those_before_the_option():
    digest = hashlib.sha256()
    for seed in range(8):
        built, rng, name = terrain(EnvConfig(), seed)
        digest.update(name.encode())
        digest.update(np.ascontiguousarray(built.model.hfield_data).tobytes())
        digest.update(np.float64(rng.random()).tobytes())
    assert digest.hexdigest() == DEFAULT_DRAWS_SHA256


def test_pyramids_take_their_share_with_the_configured_risers():
    env = EnvConfig(heightfield_probability=0.5, pyramids_probability=0.5, pyramids_step_height=(0.05, 0.06))
    names = []
    for seed in range(12):
        built, _, name = terrain(env, seed)
        names.append(name.split("-")[0])
        if name.startswith("pyramids"):
            params = built.terrain.params
            assert (params["step_height_low"], params["step_height_high"]) == (0.05, 0.06)
            assert 0.05 <= float(built.terrain.height(1.5 + 1.19, 1.5)) <= 0.06  # a lowest tread
    assert set(names) == {"heightfield", "pyramids"}  # no hills: their share is 0


def test_the_option_round_trips_and_old_configs_have_no_pyramids():
    config = AgentConfig(env=EnvConfig(heightfield_probability=0.5, pyramids_probability=0.3))
    assert AgentConfig.from_json(config.to_json()) == config
    old = config.to_json()
    del old["env"]["pyramids_probability"], old["env"]["pyramids_step_height"]  # written before the option
    assert AgentConfig.from_json(old).env.pyramids_probability == 0.0


@pytest.mark.parametrize(
    "settings, message",
    [
        ({"pyramids_probability": 0.3}, "pyramids_probability must be in [0, 1 - heightfield_probability]"),
        ({"pyramids_probability": -0.1}, "pyramids_probability must be in [0, 1 - heightfield_probability]"),
        ({"pyramids_step_height": (0.0, 0.05)}, "pyramids_step_height must be > 0 m"),
        ({"pyramids_step_height": (0.08, 0.04)}, "pyramids_step_height must satisfy"),
    ],
)
def test_a_bad_pyramids_setting_is_one_line(settings, message):
    with pytest.raises(AgentConfigError) as error:
        EnvConfig(**settings)
    assert message in str(error.value) and "\n" not in str(error.value)
