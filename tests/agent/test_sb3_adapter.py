"""Every Stable-Baselines3 private member and internal krl relies on (krl.agent.sb3_adapter), checked on the
installed SB3: an upgrade that renames, removes or reshapes one fails here, with a message naming it.

Each check names the member it guards. The first ones read SB3's classes (signatures, local variables,
fields); the rest use the adapter on a tiny PPO and compare with what SB3's public API computes.
"""

from __future__ import annotations

import inspect
import json
import tomllib
import zipfile
from collections import deque
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import stable_baselines3
import torch
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.buffers import RolloutBuffer
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.distributions import DiagGaussianDistribution
from stable_baselines3.common.logger import Logger
from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm
from stable_baselines3.common.policies import ActorCriticPolicy
from stable_baselines3.common.torch_layers import MlpExtractor
from stable_baselines3.common.type_aliases import RolloutBufferSamples
from stable_baselines3.common.vec_env import DummyVecEnv, VecMonitor

from krl.agent import sb3_adapter as sb3
from krl.agent.checkpoint import restricted_loads
from krl.agent.network import PrivilegedCriticPolicy, SplitExtractor, SplitHeads
from krl.agent.symmetry import SignedPermutation
from krl.agent.train import SymmetricPPO, ThreadedPPO

VERSION = stable_baselines3.__version__
ROOT = Path(__file__).resolve().parents[2]


def _changed(member: str, what: str) -> str:
    """The failure message of a check of ``member``."""
    return (
        f"stable-baselines3 {VERSION} changed {member}: {what}; krl.agent.sb3_adapter relies on it "
        "(docs/dependencies.md)"
    )


def _parameters(function) -> list[str]:
    return list(inspect.signature(function).parameters)


def test_the_installed_sb3_is_the_one_pyproject_pins():
    """The checks below were written against the pinned version; another one installed means they guard
    a version nobody read the adapter against."""
    dependencies = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"]
    pins = [d for d in dependencies if d.startswith("stable-baselines3")]
    assert pins == [f"stable-baselines3=={VERSION}"], f"pyproject pins {pins}, installed is {VERSION}"


SIGNATURES = [
    (BaseAlgorithm, "_update_learning_rate", ["self", "optimizers"]),
    (BaseAlgorithm, "_excluded_save_params", ["self"]),
    (ActorCriticPolicy, "_build_mlp_extractor", ["self"]),
    (ActorCriticPolicy, "extract_features", ["self", "obs", "features_extractor"]),
    (RolloutBuffer, "get", ["self", "batch_size"]),
    (DiagGaussianDistribution, "proba_distribution", ["self", "mean_actions", "log_std"]),
    (MlpExtractor, "forward_actor", ["self", "features"]),
    (MlpExtractor, "forward_critic", ["self", "features"]),
]
"""The methods krl calls or overrides: (class, name, parameters)."""


@pytest.mark.parametrize(("owner", "name", "parameters"), SIGNATURES, ids=[s[1] for s in SIGNATURES])
def test_the_methods_krl_calls_or_overrides_keep_their_signature(owner, name, parameters):
    member = f"{owner.__name__}.{name}"
    function = getattr(owner, name, None)
    assert callable(function), _changed(member, "it is gone")
    found = _parameters(function)
    assert found == parameters, _changed(member, f"its parameters are {found}, not {parameters}")


@pytest.mark.parametrize(
    ("owner", "name", "local"),
    [(OnPolicyAlgorithm, "collect_rollouts", "infos"), (OnPolicyAlgorithm, "learn", "total_timesteps")],
)
def test_the_local_variables_callbacks_read_are_still_there(owner, name, local):
    member = f"{owner.__name__}.{name}"
    function = getattr(owner, name, None)
    assert callable(function), _changed(member, "it is gone")
    assert local in function.__code__.co_varnames, _changed(member, f"it has no local variable {local!r}")


def test_a_minibatch_of_the_rollout_has_the_fields_the_update_reads():
    fields = ("observations", "actions", "old_values", "old_log_prob", "advantages", "returns")
    assert RolloutBufferSamples._fields == fields, _changed(
        "RolloutBufferSamples", str(RolloutBufferSamples._fields)
    )


# --- the adapter on a tiny PPO ---------------------------------------------------------------------


class Toy(gym.Env):
    """One-step episodes with 3 observed numbers and 2 action numbers."""

    observation_space = gym.spaces.Box(-np.inf, np.inf, (3,), np.float32)
    action_space = gym.spaces.Box(-1, 1, (2,), np.float32)

    def reset(self, seed=None, options=None):
        super().reset(seed=seed)
        return self.np_random.normal(size=3).astype(np.float32), {}

    def step(self, action):
        return self.np_random.normal(size=3).astype(np.float32), -float(np.sum(action**2)), True, False, {}


class Recorder(BaseCallback):
    """What the adapter's callback functions return during a ``learn``."""

    def __init__(self) -> None:
        super().__init__()
        self.goal, self.infos, self.logged = None, [], None

    def _on_training_start(self) -> None:
        self.goal = sb3.training_goal(self)

    def _on_step(self) -> bool:
        self.infos.append(sb3.step_infos(self))
        return True

    def _on_rollout_end(self) -> None:
        self.logger.record("check/value", 1.5)
        self.logged = sb3.logged_value(self, "check/value")


ENVS, STEPS = 2, 16
"""The tiny PPO's environments and steps per environment in a rollout."""


@pytest.fixture(scope="module")
def trained():
    """A :class:`SymmetricPPO` (its update runs through the adapter; its settings and ThreadedPPO's stay
    out of ``model.save``) after one rollout and update, and what its callback recorded."""
    env = VecMonitor(DummyVecEnv([Toy] * ENVS))
    model = SymmetricPPO("MlpPolicy", env, n_steps=STEPS, batch_size=8, n_epochs=2, seed=1, device="cpu")
    model.observation_mirror = SignedPermutation(np.arange(3), np.array([1.0, -1.0, 1.0]))
    model.action_mirror = SignedPermutation(np.arange(2), np.array([1.0, -1.0]))
    model.update_threads = 1
    recorder = Recorder()
    model.learn(ENVS * STEPS, callback=recorder)
    return model, recorder


def test_callbacks_see_the_goal_the_step_infos_and_the_logged_values(trained):
    _, recorder = trained
    assert recorder.goal == ENVS * STEPS, _changed(
        "OnPolicyAlgorithm.learn's total_timesteps", f"{recorder.goal}"
    )
    assert len(recorder.infos) == STEPS, _changed(
        "OnPolicyAlgorithm.collect_rollouts's infos", "not per step"
    )
    assert all(len(infos) == ENVS and all(isinstance(i, dict) for i in infos) for infos in recorder.infos), (
        _changed("OnPolicyAlgorithm.collect_rollouts's infos", "not one dict per environment")
    )
    assert recorder.logged == 1.5, _changed("Logger.name_to_value", f"read {recorder.logged}")


def test_the_update_counter_and_the_progress_are_sb3s(trained):
    model, _ = trained
    assert isinstance(model._current_progress_remaining, float), _changed("_current_progress_remaining", "")
    assert sb3.update_count(model) == 2, _changed("BaseAlgorithm._n_updates", "not one per epoch")
    assert sb3.clip_range_now(model) == pytest.approx(0.2), _changed("PPO.clip_range", "not a schedule")
    sb3.count_update(model)
    assert sb3.update_count(model) == 3 == model._n_updates


def test_update_learning_rate_sets_the_optimiser_from_the_schedule_and_logs_it():
    schedule = lambda progress: 0.01 * progress  # noqa: E731
    model = ThreadedPPO("MlpPolicy", DummyVecEnv([Toy]), n_steps=8, batch_size=8, learning_rate=schedule)
    model.set_logger(Logger(folder=None, output_formats=[]))
    model._current_progress_remaining = 0.5
    sb3.update_learning_rate(model)
    rates = [group["lr"] for group in model.policy.optimizer.param_groups]
    assert rates == [pytest.approx(0.005)], _changed("BaseAlgorithm._update_learning_rate", f"rates {rates}")
    logged = model.logger.name_to_value.get("train/learning_rate")
    assert logged == pytest.approx(0.005), _changed("BaseAlgorithm._update_learning_rate", "logs no rate")


def test_restore_counters_sets_what_a_resumed_training_reads(trained):
    model, _ = trained
    model = ThreadedPPO("MlpPolicy", model.env, n_steps=STEPS, batch_size=8, device="cpu")
    episodes = [{"r": float(i), "l": 1, "t": 0.0} for i in range(150)]
    sb3.restore_counters(model, 640, 7, episodes)
    window = model._stats_window_size
    assert isinstance(window, int), _changed("BaseAlgorithm._stats_window_size", f"{window!r}")
    assert (model.num_timesteps, model._n_updates) == (640, 7)
    assert isinstance(model.ep_info_buffer, deque) and list(model.ep_info_buffer) == episodes[-window:]
    assert isinstance(model.ep_success_buffer, deque) and len(model.ep_success_buffer) == 0


def test_the_rollout_buffer_gives_minibatches_values_and_returns(trained):
    model, _ = trained
    batches = list(sb3.rollout_minibatches(model))
    assert [len(b.observations) for b in batches] == [8] * 4, _changed(
        "RolloutBuffer.get", "other batch sizes"
    )
    assert batches[0].actions.shape == (8, 2) and isinstance(batches[0].advantages, torch.Tensor)
    values, returns = sb3.rollout_values_and_returns(model)
    shapes = (values.shape, returns.shape)
    assert shapes == ((ENVS * STEPS,),) * 2, _changed("RolloutBuffer.values/.returns", f"shapes {shapes}")


def test_evaluate_with_means_is_sb3s_evaluate_actions(trained):
    model, _ = trained
    policy = model.policy
    observations = torch.as_tensor(np.random.default_rng(2).normal(size=(5, 3)), dtype=torch.float32)
    actions = torch.zeros((5, 2))
    with torch.no_grad():
        values, log_prob, entropy, means = sb3.evaluate_with_means(policy, observations, actions)
        expected = policy.evaluate_actions(observations, actions)
        expected_means = policy.get_distribution(observations).distribution.mean
    for name, got, want in zip(
        ("values", "log_prob", "entropy"), (values, log_prob, entropy), expected, strict=True
    ):
        assert torch.equal(got, want.flatten()), _changed("ActorCriticPolicy's layers", f"{name} differ")
    assert torch.equal(means, expected_means), _changed("ActorCriticPolicy.action_net", "means differ")
    log_std = sb3.action_log_std(policy)
    assert isinstance(log_std, torch.nn.Parameter) and log_std.shape == (2,), _changed(
        "log_std", f"{log_std}"
    )


def test_the_actor_layers_give_the_mean_action(trained):
    model, _ = trained
    extractor, own_layers, action_layer = sb3.actor_layers(model.policy)
    observations = torch.ones((4, 3))
    with torch.no_grad():
        means = action_layer(own_layers(extractor(observations)))
        expected = model.policy.get_distribution(observations).distribution.mean
    assert torch.equal(means, expected), _changed(
        "features_extractor/mlp_extractor.policy_net/action_net", ""
    )


def test_own_heads_replace_sb3s_mlp_extractor():
    kwargs = {
        "features_extractor_class": SplitExtractor,
        "features_extractor_kwargs": {"hidden": [8], "actor_size": 2},
        "net_arch": {"pi": [4], "vf": [4]},
    }
    model = ThreadedPPO(
        PrivilegedCriticPolicy, DummyVecEnv([Toy]), n_steps=8, batch_size=8, policy_kwargs=kwargs
    )
    heads = model.policy.mlp_extractor
    assert isinstance(heads, SplitHeads), _changed("ActorCriticPolicy._build_mlp_extractor", "not called")
    assert (model.policy.action_net.in_features, model.policy.value_net.in_features) == (4, 4), _changed(
        "MlpExtractor.latent_dim_pi/latent_dim_vf", "not what the action and value layers are built on"
    )


def test_a_saved_model_holds_the_counters_and_episodes_and_not_the_unsaved_settings(trained, tmp_path):
    model, _ = trained
    model.save(tmp_path / "model.zip")
    with zipfile.ZipFile(tmp_path / "model.zip") as archive:
        data = json.loads(archive.read("data"))
    assert set(SymmetricPPO.unsaved_settings) > set(ThreadedPPO.unsaved_settings)
    saved = sorted(set(SymmetricPPO.unsaved_settings) & set(data))
    assert not saved, _changed("BaseAlgorithm._excluded_save_params", f"model.zip holds {saved}")
    assert sb3.saved_update_count(data) == model._n_updates, _changed("model.zip's _n_updates", "")
    episodes = list(restricted_loads(sb3.saved_episodes_pickle(data)))
    assert episodes and episodes == list(model.ep_info_buffer), _changed("model.zip's ep_info_buffer", "")
