"""Mirror-symmetric PPO (krl.agent.symmetric_ppo) on toy problems: SB3's update when the mirror terms are
off, a symmetric policy when they are on."""

import gymnasium as gym
import numpy as np
import pytest
import torch
from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

from krl.agent.config import AgentConfigError, PPOConfig
from krl.agent.symmetric_ppo import NormalisedMirror
from krl.agent.symmetry import SignedPermutation
from krl.agent.train import SymmetricPPO, ThreadedPPO

OBSERVATION_MIRROR = SignedPermutation(np.array([0, 1, 2]), np.array([1.0, -1.0, 1.0]))
"""The toy's observation (x, y, z) mirrors to (x, -y, z)."""
ACTION_MIRROR = SignedPermutation(np.array([0, 1]), np.array([1.0, -1.0]))
"""The toy's action (a, b) mirrors to (a, -b)."""


OFFSET = np.array([0.0, 0.0, 1.0])
"""The toy's mean state: z is mirror-invariant and not zero, so a normaliser's mean has an odd part."""


class Toy(gym.Env):
    """One-step episodes: observe s ~ N(0, 1)^3 + (0, 0, 1); reward -(a_0 - s_0)^2. The reward ignores a_1,
    so nothing but a mirror term keeps a_1 odd in s_1 (the mirror's requirement)."""

    observation_space = gym.spaces.Box(-np.inf, np.inf, (3,), np.float32)
    action_space = gym.spaces.Box(-1, 1, (2,), np.float32)

    def reset(self, seed=None, options=None):
        super().reset(seed=seed)
        self.state = (self.np_random.normal(size=3) + OFFSET).astype(np.float32)
        return self.state, {}

    def step(self, action):
        reward = -float((action[0] - self.state[0]) ** 2)
        return self.state, reward, True, False, {}


def _model(cls, symmetry=None, coef=1.0, normalise=False, seed=3):
    env = DummyVecEnv([Toy] * 4)
    if normalise:
        env = VecNormalize(env, norm_reward=False)
    model = cls("MlpPolicy", env, n_steps=64, batch_size=64, n_epochs=4, seed=seed, device="cpu")
    if symmetry is not None:
        model.symmetry, model.mirror_loss_coef = symmetry, coef
        model.observation_mirror, model.action_mirror = OBSERVATION_MIRROR, ACTION_MIRROR
    return model


def _mirror_error(model) -> float:
    states = np.random.default_rng(1).normal(size=(256, 3)) + OFFSET
    states = torch.as_tensor(states, dtype=torch.float32)
    with torch.no_grad():
        both = torch.cat([states, OBSERVATION_MIRROR(states)])
        means = model.policy.get_distribution(both).distribution.mean
    return float(torch.mean((means[256:] - ACTION_MIRROR(means[:256])) ** 2))


def test_the_update_without_mirror_terms_is_sb3_s():
    torch.set_num_threads(1)  # as training runs: PyTorch's rounding depends on its thread count
    sb3 = _model(ThreadedPPO).learn(2 * 64 * 4)  # SB3 seeds torch's RNG: build each before it learns
    ours = _model(SymmetricPPO, "loss", coef=0.0).learn(2 * 64 * 4)
    for (name, a), b in zip(sb3.policy.state_dict().items(), ours.policy.state_dict().values(), strict=True):
        assert torch.equal(a, b), name


@pytest.mark.parametrize(("symmetry", "coef"), [("augment", 1.0), ("loss", 10.0)])
def test_a_symmetric_policy_acts_as_its_own_mirror_image(symmetry, coef):
    """After 30 updates: 0.0107 without a mirror term, 0.0008 with augmentation, 0.00006 with the loss."""
    torch.set_num_threads(1)
    plain = _model(ThreadedPPO).learn(30 * 64 * 4)
    symmetric = _model(SymmetricPPO, symmetry, coef).learn(30 * 64 * 4)
    assert _mirror_error(plain) > 1e-3  # the reward alone leaves the policy lopsided
    assert _mirror_error(symmetric) < 0.15 * _mirror_error(plain)


def test_a_normalised_observation_mirrors_as_its_raw_one():
    env = VecNormalize(DummyVecEnv([Toy]), norm_reward=False)
    env.obs_rms.mean, env.obs_rms.var = np.array([0.5, 0.2, 1.0]), np.array([4.0, 0.25, 1.0])
    mirror = NormalisedMirror.of(OBSERVATION_MIRROR, env, "cpu")
    raw = np.array([[1.0, 0.3, 2.0]])
    normalised = torch.as_tensor(env.normalize_obs(raw), dtype=torch.float32)
    expected = env.normalize_obs(OBSERVATION_MIRROR(raw))
    np.testing.assert_allclose(mirror(normalised).numpy(), expected, rtol=1e-5, atol=1e-6)


def test_an_unknown_symmetry_mode_is_refused_in_one_line():
    with pytest.raises(AgentConfigError, match="unknown symmetry mode 'mirror'; known: none, augment, loss"):
        PPOConfig(symmetry="mirror")
    with pytest.raises(AgentConfigError, match="mirror_loss_coef"):
        PPOConfig(symmetry="loss", mirror_loss_coef=float("nan"))


def test_a_symmetric_run_whose_observation_the_mirror_misses_is_refused_before_anything_is_written(
    tmp_path, monkeypatch, small_config
):
    from dataclasses import replace

    import krl.agent.symmetry
    from krl.agent.train import TrainingError, train

    mirrors = dict(krl.agent.symmetry.FEATURE_MIRRORS)
    del mirrors["foot_contact"]  # a feature added to the observation without its mirror
    monkeypatch.setattr(krl.agent.symmetry, "FEATURE_MIRRORS", mirrors)
    config = replace(small_config, ppo=replace(small_config.ppo, symmetry="augment"))
    with pytest.raises(
        TrainingError, match="symmetry 'augment': no mirror for observation feature 'foot_contact'"
    ):
        train(tmp_path / "run", config, seed=1, total_steps=256, progress=False)
    assert not (tmp_path / "run").exists()


def test_a_symmetric_run_trains_logs_its_mirror_error_and_saves_its_mode(tmp_path, small_config):
    import csv
    from dataclasses import replace

    from krl.agent.policy import load_policy
    from krl.agent.train import train

    config = replace(small_config, ppo=replace(small_config.ppo, symmetry="loss"))
    train(tmp_path / "run", config, seed=1, total_steps=512, progress=False, log=lambda _: None)
    rows = list(csv.DictReader((tmp_path / "run" / "progress.csv").open()))
    assert len(rows) == 2 and float(rows[-1]["train/mirror_error"]) >= 0  # logged from the first update
    assert load_policy(tmp_path / "run" / "policy.npz").config.ppo.symmetry == "loss"
