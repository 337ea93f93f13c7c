"""Policy files: NumPy inference equals SB3's, and damaged or mismatched files are one-line errors."""

from __future__ import annotations

import json
import zipfile

import numpy as np
import pytest
from agent_fakes import make_policy

from krl.agent.config import AgentConfig, ResidualConfig
from krl.agent.network import export_policy
from krl.agent.policy import PolicyFileError, load_policy, policy_artifacts, shipped_policy_dir
from krl.kernel.registry import shipped_model_path


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
    assert load_policy(shipped_policy_dir() / "agent-rp.npz").config.env.reward == EVALUATION_REWARD
    assert load_policy(shipped_policy_dir() / "agent-base.npz").config.env.reward == AGENT_BASE_REWARD
