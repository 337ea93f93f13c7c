"""The perceptive agent's parts: the height scan feature and its mirror, the terrain curriculum (promotion,
demotion, resume) and the privileged critic (its inputs never reach the actor); bad settings refused."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from krl.agent.config import AgentConfig, AgentConfigError, ScanConfig, TerrainCurriculumConfig
from krl.agent.env import ResidualVecEnv
from krl.agent.observation import layout, observation_size
from krl.agent.policy import load_policy
from krl.agent.sensing import Sensing
from krl.agent.symmetry import observation_mirror, scan_mirror
from krl.agent.terrain_curriculum import next_level, tile_params
from krl.agent.train import train
from krl.sim.scan import heading_points_to_world
from krl.sim.terrains import Terrain

CRITIC = ("height_scan_clean", "ground_friction", "push_force", "terrain_level")
SMALL_SCAN = ScanConfig(x_range=(-0.2, 0.4), half_width=0.2, spacing=0.2)


def _perceptive(config: AgentConfig, critic: tuple[str, ...] = CRITIC, noise: float = 0.05) -> AgentConfig:
    observation = replace(
        config.observation,
        features=(*config.observation.features, "height_scan"),
        critic_features=critic,
        scan=replace(SMALL_SCAN, noise=noise),
    )
    curriculum = TerrainCurriculumConfig(levels=4, start_levels=2)
    return replace(config, observation=observation, env=replace(config.env, terrain_curriculum=curriculum))


# --- settings ------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("section", "settings", "message"),
    [
        ("observation", {"scan": {"x_range": [0.5, 0.4]}}, "scan x_range must satisfy"),
        ("observation", {"scan": {"half_width": 3.0}}, "reaches beyond the terrain"),
        ("observation", {"scan": {"spacing": 0.0}}, "scan spacing must be a positive number"),
        ("observation", {"scan": {"half_width": 0.27}}, "whole number of spacings"),
        ("observation", {"critic_features": ["x_ray"]}, "unknown critic feature 'x_ray'"),
        ("observation", {"features": ["joint_pos", "push_force"]}, "'push_force' is privileged"),
        ("observation", {"critic_features": ["joint_pos"]}, "not among the actor's features"),
        ("env", {"terrain_curriculum": {"tiles": []}}, "curriculum has no tiles"),
        ("env", {"terrain_curriculum": {"tiles": ["stairs"]}}, "distinct kinds of"),
        ("env", {"terrain_curriculum": {"riser": [0.05, 0.4]}}, "riser must lie in"),
    ],
)
def test_bad_settings_are_refused_in_one_line(section, settings, message):
    with pytest.raises(AgentConfigError, match=message) as caught:
        AgentConfig.from_json({section: settings})
    assert "\n" not in str(caught.value)


def test_a_default_config_reads_back_with_its_new_sections():
    config = _perceptive(AgentConfig())
    assert AgentConfig.from_json(json.loads(json.dumps(config.to_json()))) == config
    assert AgentConfig.from_json({}).observation.critic_features == ()


def test_the_default_grid_is_legged_gyms():
    scan = ScanConfig()
    assert (len(scan.x), len(scan.y), scan.size) == (17, 11, 187)
    np.testing.assert_allclose(scan.y, -np.array(scan.y[::-1]), atol=1e-12)


# --- the scan's mirror ---------------------------------------------------------------------------


def test_scan_mirror_twice_is_the_identity_and_mirrors_a_mirrored_scene():
    scan = ScanConfig()
    mirror = scan_mirror(scan)
    values = np.random.default_rng(0).normal(size=(5, scan.size))
    np.testing.assert_array_equal(mirror(mirror(values)), values)

    def ground(x, y):  # anything but symmetric in y
        return 0.1 * np.sin(1.3 * x + 0.4) + 0.07 * np.cos(2.1 * y - 0.3) + 0.05 * x * y

    scene = Terrain(name="t", params={}, spawn_xy=(0.0, 0.0), _height_fn=ground)
    mirrored = Terrain(name="t", params={}, spawn_xy=(0.0, 0.0), _height_fn=lambda x, y: ground(x, -y))
    points = np.array(scan.points())
    pose, yaw = np.array([0.7, 0.4, 0.3]), 0.6
    seen = scene.ground_height(*heading_points_to_world(points, pose, yaw).T)
    seen_m = mirrored.ground_height(*heading_points_to_world(points, pose * [1, -1, 1], -yaw).T)
    np.testing.assert_allclose(mirror(seen), seen_m, atol=1e-12)


def test_the_observation_mirror_covers_the_critics_features():
    config = _perceptive(AgentConfig())
    features = config.observation.all_features
    mirror = observation_mirror(features, config.observation.scan)
    assert mirror.size == observation_size(features, config.observation.scan)
    x = np.random.default_rng(1).normal(size=(3, mirror.size))
    np.testing.assert_array_equal(mirror(mirror(x)), x)


# --- the environment -------------------------------------------------------------------------------


def test_the_environment_observes_the_scan_and_the_critics_features(small_config):
    config = _perceptive(small_config)
    env = ResidualVecEnv(config, 2, seed=4)
    observations = env.reset()
    rows = {r["name"]: r for r in layout(config.observation.all_features, config.observation.scan)}
    assert observations.shape == (2, rows["terrain_level"]["stop"])
    for _ in range(3):
        env.step_async(np.zeros((2, config.residual.action_size)))
        observations, *_ = env.step_wait()
    scan = observations[:, rows["height_scan"]["start"] : rows["height_scan"]["stop"]]
    clean = observations[:, rows["height_scan_clean"]["start"] : rows["height_scan_clean"]["stop"]]
    assert 0 < np.abs(scan - clean).max() <= 0.05 + 1e-6  # the actor's scan is noisy, the critic's not
    sensing = Sensing(replace(config.observation, scan=SMALL_SCAN))
    expected = sensing.scan_values(env.batch.sims.terrain_heights(sensing.points), env.batch.states)
    np.testing.assert_allclose(clean, expected, atol=1e-6)
    levels = env.batch.terrain_levels()
    np.testing.assert_allclose(observations[:, rows["terrain_level"]["start"]], levels / 3, atol=1e-7)


# --- the curriculum ----------------------------------------------------------------------------------


def test_promotion_demotion_and_the_top_level():
    curriculum = TerrainCurriculumConfig(levels=3, promote_targets=4, demote_targets=2)
    rng = np.random.default_rng(0)
    assert next_level(curriculum, 0, 4, False, rng) == 1
    assert next_level(curriculum, 1, 3, False, rng) == 1
    assert next_level(curriculum, 1, 1, False, rng) == 0
    assert next_level(curriculum, 0, 0, False, rng) == 0
    assert {next_level(curriculum, 2, 9, False, rng) for _ in range(50)} == {0, 1, 2}
    # a push toppled it: nothing said of the ground, no demotion; a promotion still counts
    assert next_level(curriculum, 1, 1, True, rng) == 1
    assert next_level(curriculum, 1, 4, True, rng) == 2
    assert tile_params(curriculum, "pyramids", 0)["step_height_high"] == curriculum.riser[0]
    assert tile_params(curriculum, "pits", 2)["step_height_low"] == curriculum.riser[1]


def test_levels_follow_episodes_in_the_environment(small_config):
    config = _perceptive(small_config)
    env = ResidualVecEnv(config, 2, seed=4)
    env.reset()
    env.set_terrain_levels([3, 0])
    env.reset()
    assert env.batch.terrain_names[0].split("-")[0] in ("pyramids", "pits", "heightfield", "slope")
    batch = env.batch
    episode = {"targets_reached": 0}
    batch._promote(0, episode, pushed_off=True)
    assert episode["terrain_level"] == 3 and batch.levels[0] == 3 and not batch.needs_terrain[0]
    batch._promote(0, episode, pushed_off=False)
    assert episode["terrain_level"] == 3 and batch.levels[0] == 2 and batch.needs_terrain[0]


def _first_episodes(env: ResidualVecEnv, max_steps: int = 4000) -> dict[int, dict]:
    """Step ``env`` with zero actions until every robot's first episode has ended: each robot's info then."""
    ended: dict[int, dict] = {}
    actions = np.zeros((env.num_envs, *env.action_space.shape))
    for _ in range(max_steps):
        _, _, dones, infos = env.step(actions)
        for index in np.flatnonzero(dones):
            ended.setdefault(int(index), infos[index])
        if len(ended) == env.num_envs:
            return ended
    raise AssertionError(f"only {len(ended)} of {env.num_envs} episodes ended in {max_steps} steps")


@pytest.mark.parametrize("pushes", [True, False])
def test_a_fall_a_push_caused_does_not_demote(small_config, pushes):
    """Pushes of 2 000 N every 0.5-0.6 s topple every robot (its info says push_survived False): its level
    stays. Without pushes a 4 s episode ends (a fall or the time limit) short of 2 waypoints: demoted."""
    config = _perceptive(small_config)
    env_settings = replace(
        config.env,
        episode_time=4.0,
        pushes=pushes,
        push_interval=(0.5, 0.6),
        push_magnitude=(2000.0, 2000.0),
        push_curriculum=False,
    )
    env = ResidualVecEnv(replace(config, env=env_settings), 2, seed=4)
    env.reset()
    env.set_terrain_levels([2, 2])
    env.reset()
    for index, info in _first_episodes(env).items():
        episode = info["episode"]
        assert episode["terrain_level"] == 2 and episode["targets_reached"] < 2
        assert (info.get("push_survived") is False) == pushes, info
        assert env.batch.levels[index] == (2 if pushes else 1)


def test_a_run_saves_its_levels_and_a_resumed_run_continues_on_them(tmp_path, small_config, monkeypatch):
    config = _perceptive(small_config)
    out = tmp_path / "run"
    train(out, config, seed=3, total_steps=256, progress=False, log=lambda _: None)
    state = json.loads((out / "checkpoints" / "00000000256" / "state.json").read_text())
    assert len(state["terrain_levels"]) == config.num_envs and all(
        0 <= v < 4 for v in state["terrain_levels"]
    )
    state["terrain_levels"] = [3, 2]
    (out / "checkpoints" / "00000000256" / "state.json").write_text(json.dumps(state))
    given: list[list[int]] = []
    from krl.agent.process_vec_env import ProcessVecEnv

    original = ProcessVecEnv.set_terrain_levels
    monkeypatch.setattr(
        ProcessVecEnv,
        "set_terrain_levels",
        lambda self, levels: (given.append(list(levels)), original(self, levels)),
    )
    train(out, total_steps=512, progress=False, log=lambda _: None)
    assert given == [[3, 2]]
    assert "curriculum/terrain_level" in (out / "progress.csv").read_text().splitlines()[0]


# --- the privileged critic ---------------------------------------------------------------------------


def test_the_critics_inputs_never_reach_the_actor(tmp_path, small_config):
    from stable_baselines3 import PPO  # noqa: F401  (the saved model is read through krl's checkpoint)

    config = _perceptive(small_config)
    config = replace(config, ppo=replace(config.ppo, symmetry="loss"))
    out = tmp_path / "run"
    train(out, config, seed=5, total_steps=256, progress=False, log=lambda _: None)
    policy = load_policy(out / "policy.npz")
    actor_size = observation_size(config.observation.features, config.observation.scan)
    assert policy.observation_size == actor_size
    assert policy.layers[0][0].shape[1] == actor_size
    from krl.agent.train import _new_model

    env = ResidualVecEnv(config, 2, seed=1)
    model = _new_model(config, env, seed=5, total=256, device="cpu")
    import torch

    full = torch.as_tensor(env.reset())
    changed = full.clone()
    changed[:, actor_size:] += 10.0  # only the critic's features
    with torch.no_grad():
        actions = model.policy.get_distribution(full).distribution.mean
        actions_changed = model.policy.get_distribution(changed).distribution.mean
        values, values_changed = model.policy.predict_values(full), model.policy.predict_values(changed)
    torch.testing.assert_close(actions, actions_changed, rtol=0, atol=0)
    assert not torch.allclose(values, values_changed)


def test_the_exported_policy_takes_the_actors_inputs_and_says_how_to_scan(tmp_path, small_config, capsys):
    import onnx

    from krl.cli import main

    config = _perceptive(small_config)
    out = tmp_path / "run"
    train(out, config, seed=6, total_steps=256, progress=False, log=lambda _: None)
    assert (
        main(["export", "--out", str(tmp_path / "onnx"), "--policy", str(out / "policy.npz"), "--json"]) == 0
    )
    files = json.loads(capsys.readouterr().out)
    graph = onnx.load(files["policy"]).graph
    actor_size = observation_size(config.observation.features, config.observation.scan)
    assert graph.input[0].type.tensor_type.shape.dim[1].dim_value == actor_size
    contract = json.loads((tmp_path / "onnx" / "contract.json").read_text())["policy"]
    names = [row["name"] for row in contract["observation"]]
    assert names == list(config.observation.features) and not set(names) & set(CRITIC)
    assert contract["height_scan"]["points"] == [[round(x, 9), round(y, 9)] for x, y in SMALL_SCAN.points()]


def test_a_checkpoint_on_an_interruption_saves_the_levels_without_asking_the_workers():
    """SIGTERM between a step's actions and its answers: asking the workers for their levels then read a
    step's answer as theirs and the interrupted run failed to save its checkpoint."""
    from types import SimpleNamespace

    from krl.agent.terrain_curriculum import TerrainCurriculumLog

    answers = [np.array([2, 0, 1])]

    def terrain_levels():
        if not answers:
            raise AssertionError("the workers were asked mid-step")
        return answers.pop()

    log = TerrainCurriculumLog()
    recorded = {}
    env = SimpleNamespace(unwrapped=SimpleNamespace(terrain_levels=terrain_levels))
    log.model = SimpleNamespace(get_env=lambda: env, logger=SimpleNamespace(record=recorded.__setitem__))
    log._on_rollout_end()
    assert recorded == {"curriculum/terrain_level": 1.0, "curriculum/terrain_level_max": 2}
    assert log.state() == {"terrain_levels": [2, 0, 1]}  # no second question to the workers
