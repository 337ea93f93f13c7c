"""Policy files: NumPy inference equals SB3's, and damaged or mismatched files are one-line errors."""

from __future__ import annotations

import json
import zipfile

import numpy as np
import pytest
from agent_fakes import make_policy

from krl.agent.config import AgentConfig, ResidualConfig
from krl.agent.network import export_policy
from krl.agent.policy import PolicyFileError, load_policy, one_policy, policy_artifacts, shipped_policy_dir
from krl.kernel.registry import shipped_model_path
from krl.util.thesis import THESIS_SEEDS


def test_numpy_inference_matches_sb3_with_its_normaliser(small_config):
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    from krl.agent.env import ResidualVecEnv
    from krl.agent.train import _policy_kwargs

    env = VecNormalize(ResidualVecEnv(small_config, 2, seed=0))
    model = PPO(
        "MlpPolicy", env, n_steps=64, batch_size=64, policy_kwargs=_policy_kwargs(small_config), seed=0
    )
    raw = env.reset()
    for _ in range(30):
        env.step_async(np.zeros((2, 12)))
        raw = env.step_wait()[0]
    raw = env.get_original_obs()
    policy = export_policy(model, env, small_config, {"kernel_sha256": "x", "training": {}, "software": {}})
    expected, _ = model.predict(env.normalize_obs(raw), deterministic=True)
    np.testing.assert_allclose(policy.act(raw), np.clip(expected, -1, 1), atol=1e-5)


def test_save_load_round_trip(tmp_path):
    policy = make_policy(AgentConfig(), scale=0.1, seed=2)
    path = policy.save(tmp_path / "agent-x.npz")
    loaded = load_policy(path)
    observation = np.random.default_rng(0).standard_normal((3, policy.observation_size))
    np.testing.assert_allclose(loaded.act(observation), policy.act(observation), atol=1e-6)
    assert loaded.metadata["training"]["seed"] == 2
    name, files = policy_artifacts(str(path))
    assert name == "x" and files == [(None, path)]


def test_corrupt_and_truncated_files_are_one_line_errors(tmp_path):
    path = make_policy(AgentConfig()).save(tmp_path / "p.npz")
    data = path.read_bytes()
    (tmp_path / "cut.npz").write_bytes(data[: len(data) // 2])
    (tmp_path / "text.npz").write_text("hello")
    for name in ("cut.npz", "text.npz", "missing.npz"):
        with pytest.raises(PolicyFileError) as caught:
            load_policy(tmp_path / name)
        assert "\n" not in str(caught.value)


def _rewrite_header(path, change) -> None:
    with np.load(path, allow_pickle=False) as archive:
        arrays = {name: archive[name] for name in archive.files}
    header = json.loads(str(arrays["header"]))
    change(header)
    arrays["header"] = np.array(json.dumps(header))
    with open(path, "wb") as handle:
        np.savez(handle, **arrays)


def test_another_observation_layout_or_kernel_is_refused(tmp_path):
    path = make_policy(AgentConfig()).save(tmp_path / "p.npz")
    _rewrite_header(path, lambda h: h["config"]["observation"].update(features=["base_lin_vel", "phase"]))
    with pytest.raises(PolicyFileError, match="observation layout"):
        load_policy(path)
    path = make_policy(AgentConfig()).save(tmp_path / "q.npz")
    with pytest.raises(PolicyFileError, match="not the kernel this policy corrects"):
        load_policy(path, kernel_path=shipped_model_path("ext"))
    ext = AgentConfig(residual=ResidualConfig(kernel="ext"))
    path = make_policy(AgentConfig()).save(tmp_path / "r.npz")
    _rewrite_header(path, lambda h: h["config"].update(residual=ext.to_json()["residual"]))
    with pytest.raises(PolicyFileError, match="SHA-256"):
        load_policy(path)


def test_per_seed_folders(tmp_path):
    folder = tmp_path / "agent-mine"
    for seed in (150, 215):
        make_policy(AgentConfig(), seed=seed).save(folder / f"seed{seed}.npz")
    name, files = policy_artifacts(str(folder))
    assert name == "mine" and [seed for seed, _ in files] == [150, 215]
    make_policy(AgentConfig(), seed=150).save(folder / "again.npz")
    with pytest.raises(PolicyFileError, match="share seed 150"):
        policy_artifacts(str(folder))
    assert zipfile.is_zipfile(folder / "again.npz")


def test_a_folder_of_run_folders_is_a_seed_group_and_at_picks_one_seed(tmp_path):
    group = tmp_path / "agent-rp"
    paths = {
        seed: make_policy(AgentConfig(), seed=seed).save(group / f"seed{seed}" / "policy.npz")
        for seed in THESIS_SEEDS
    }
    name, files = policy_artifacts(str(group))
    assert name == "rp" and files == sorted(paths.items())
    assert policy_artifacts(f"{group}@345") == ("rp-seed345", [(None, paths[345])])
    assert one_policy(str(group)) == ("rp-seed150", paths[150])
    with pytest.raises(PolicyFileError, match=r"has no policy for seed 7 \(seeds: 150, 215, 345, 556\)"):
        policy_artifacts(f"{group}@7")
    with pytest.raises(PolicyFileError, match="one policy file, not a seed group"):
        policy_artifacts(f"{paths[150]}@150")


def test_a_seed_group_is_one_recipe(tmp_path):
    group = tmp_path / "mixed"
    make_policy(AgentConfig(), seed=1).save(group / "seed1.npz")
    make_policy(AgentConfig(num_envs=50), seed=2).save(group / "seed2.npz")
    with pytest.raises(PolicyFileError, match=r"mixes recipes: .* differ in num_envs"):
        policy_artifacts(str(group))


def test_the_shipped_agent_rp_is_a_group_of_thesis_seeds():
    name, files = policy_artifacts("")
    assert name == "rp" and [seed for seed, _ in files] == list(THESIS_SEEDS)
    for seed, path in files:
        assert path.name == f"seed{seed}.npz"
        policy = load_policy(path)
        assert policy.metadata["training"]["seed"] == seed
        assert policy.metadata["training"]["env_steps"] >= 20_000_000 and policy.config.num_envs == 16


def test_a_pattern_of_run_folders_is_a_seed_group_named_before_its_seeds(tmp_path):
    trials = tmp_path / "trials" / "list"
    for variant, scale in (("heights", 0.1), ("rhythm", 0.2)):
        for seed in (215, 150):
            config = AgentConfig.from_json(
                {"ppo": {"ent_coef": scale}}
            )  # the variants differ in a recipe field
            make_policy(config, seed=seed).save(trials / f"{variant}-seed{seed}" / "policy.npz")
    name, files = policy_artifacts(str(trials / "heights-seed*"))
    assert name == "heights" and [(seed, path.parent.name) for seed, path in files] == [
        (150, "heights-seed150"),
        (215, "heights-seed215"),
    ]
    assert policy_artifacts(str(trials / "rhythm-seed*@215"))[0] == "rhythm-seed215"
    with pytest.raises(PolicyFileError, match="share seed 150"):
        policy_artifacts(str(trials / "*"))
    with pytest.raises(PolicyFileError, match="matches no policy file"):
        policy_artifacts(str(trials / "both-seed*"))


def test_a_runs_policy_npz_takes_its_folders_name(tmp_path):
    path = make_policy(AgentConfig()).save(tmp_path / "agent-mine-seed7" / "policy.npz")
    name, files = policy_artifacts(str(path))
    assert name == "mine-seed7" and files == [(None, path)]


def test_a_policy_file_records_its_whole_reward_and_shipped_names_still_load(tmp_path):
    from krl.task.reward import AGENT_BASE_REWARD, EVALUATION_REWARD, RBFTerm, RewardConfig

    custom = RewardConfig(terms=(RBFTerm("upright", "gravity", (0.0, 0.0, -1.0), 5.0, 0.02),))
    config = AgentConfig.from_json({"env": {"reward": custom.to_json()}})
    path = make_policy(config, scale=0.1, seed=2).save(tmp_path / "agent-custom.npz")
    with np.load(path, allow_pickle=False) as data:
        recorded = json.loads(str(data["header"]))["config"]["env"]["reward"]
    assert recorded == json.loads(json.dumps(custom.to_json()))
    assert load_policy(path).config.env.reward == custom
    # the shipped files recorded a name ("rp", "base"); it maps to the same reward
    assert (
        load_policy(shipped_policy_dir() / "agent-rp" / "seed150.npz").config.env.reward == EVALUATION_REWARD
    )
    base = load_policy(shipped_policy_dir() / "agent-base" / "seed150.npz")
    assert base.config.env.reward == AGENT_BASE_REWARD


@pytest.mark.parametrize(
    "content", [b"hello, a text file\n", bytes(range(256)) * 4, b"\x93NUMPY\x01\x00garbage"]
)
def test_a_text_or_garbage_file_is_not_a_policy_file_without_numpys_pickle_advice(tmp_path, content):
    """Issue 47: NumPy told a user to load a text file with ``allow_pickle``; krl says what it is not."""
    path = tmp_path / "notes.npz"
    path.write_bytes(content)
    with pytest.raises(PolicyFileError) as caught:
        load_policy(path)
    assert str(caught.value) == f"{path} is not a krl policy (.npz) file"


def test_an_npz_of_pickled_objects_is_not_a_policy_file(tmp_path):
    path = tmp_path / "objects.npz"
    np.savez(path, header=np.array([{"format": "krl-policy"}], dtype=object))
    with pytest.raises(PolicyFileError) as caught:
        load_policy(path)
    assert str(caught.value) == f"{path} is not a krl policy (.npz) file"
