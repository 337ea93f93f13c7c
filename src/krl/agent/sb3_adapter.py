"""The one place krl reaches into Stable-Baselines3 past its public API (``stable-baselines3`` pinned in
``pyproject.toml``).

krl's PPO goes further than SB3 promises to keep still: a mirror-symmetric update
(:mod:`krl.agent.symmetric_ppo`) runs the policy's layers itself and counts SB3's updates, a resumed run
(:mod:`krl.agent.train`) sets SB3's counters and episode buffer, a critic with inputs of its own
(:mod:`krl.agent.network`) builds its own heads, callbacks read the local variables SB3 hands them, and a
checkpoint (:mod:`krl.agent.checkpoint`) is read from ``model.zip``'s fields. Each of those private
members and internals is read or written here, by a function or class that names the member and says why;
``tests/agent/test_sb3_adapter.py`` checks every one on the installed SB3, so an upgrade that renames or
reshapes one fails there, naming it. On an upgrade this module and its test are what to change
(``docs/dependencies.md``).

SB3's public API (the ``PPO`` constructor, ``learn``, ``save``, ``set_parameters``,
``get_vec_normalize_env``, a callback's ``num_timesteps``, ``logger`` and ``training_env``,
``VecNormalize``'s statistics) is used where it is needed, not here.
"""

from __future__ import annotations

import base64
from collections import deque
from collections.abc import Iterator
from typing import Any

import numpy as np
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.policies import ActorCriticPolicy

# --- the algorithm: a PPO model ----------------------------------------------------------------------


class UnsavedSettingsPPO(PPO):
    """SB3's PPO whose attributes named in ``unsaved_settings`` stay out of ``model.save`` (krl sets them
    on every build: they are not state to restore). Overrides SB3's private
    ``BaseAlgorithm._excluded_save_params`` (the attribute names ``save`` leaves out)."""

    unsaved_settings: tuple[str, ...] = ()

    def _excluded_save_params(self) -> list[str]:
        return [*super()._excluded_save_params(), *self.unsaved_settings]


def update_learning_rate(model) -> None:
    """Set the policy optimiser's learning rate from ``model``'s schedule at the progress now and log it
    (``train/learning_rate``), as SB3's PPO update does first: SB3's private
    ``BaseAlgorithm._update_learning_rate(optimizers)``."""
    model._update_learning_rate(model.policy.optimizer)


def clip_range_now(model) -> float:
    """PPO's clip range at the progress now: ``model.clip_range`` (a schedule once the model is built) of
    SB3's private ``_current_progress_remaining`` (1 when ``learn`` starts, 0 at its goal)."""
    return float(model.clip_range(model._current_progress_remaining))


def update_count(model) -> int:
    """PPO's updates so far (one per epoch over a rollout): SB3's private ``_n_updates``, which SB3 logs
    as ``train/n_updates`` and saves in ``model.zip``."""
    return int(model._n_updates)


def count_update(model) -> None:
    """Add one to SB3's private ``_n_updates`` (:func:`update_count`) after an epoch of an update krl runs
    itself."""
    model._n_updates += 1


def restore_counters(model, num_timesteps: int, n_updates: int, episodes: list[dict[str, Any]]) -> None:
    """Put a checkpoint's counters into a freshly built ``model`` so that its training goes on from them:
    the env steps (``num_timesteps``), SB3's private ``_n_updates`` (:func:`update_count`), and
    ``ep_info_buffer`` (the recent episodes' ``info["episode"]``, oldest first, behind
    ``rollout/ep_rew_mean``) as long as SB3's private ``_stats_window_size``; ``ep_success_buffer``
    starts empty (krl's envs report no ``is_success``)."""
    model.num_timesteps = num_timesteps
    model._n_updates = n_updates
    model.ep_info_buffer = deque(episodes, maxlen=model._stats_window_size)
    model.ep_success_buffer = deque(maxlen=model._stats_window_size)


# --- the rollout buffer --------------------------------------------------------------------------------


def rollout_minibatches(model) -> Iterator[Any]:
    """The last rollout in shuffled minibatches of ``model.batch_size``: SB3's
    ``rollout_buffer.get(batch_size)``. Each is SB3's ``RolloutBufferSamples`` of Torch tensors:
    ``observations`` (B, D), ``actions`` (B, A), ``old_values``, ``old_log_prob``, ``advantages``,
    ``returns`` (B,)."""
    return model.rollout_buffer.get(model.batch_size)


def rollout_values_and_returns(model) -> tuple[np.ndarray, np.ndarray]:
    """The last rollout's value estimates and returns (what ``train/explained_variance`` compares), both
    flattened to (steps x envs,): SB3's ``rollout_buffer.values`` and ``rollout_buffer.returns``."""
    buffer = model.rollout_buffer
    return buffer.values.flatten(), buffer.returns.flatten()


# --- the policy's layers -------------------------------------------------------------------------------


def evaluate_with_means(
    policy, observations: torch.Tensor, actions: torch.Tensor
) -> tuple[torch.Tensor, ...]:
    """SB3's ``ActorCriticPolicy.evaluate_actions`` of a policy whose actor and critic share their feature
    extractor, with the mean actions it computes on the way: ``(values (B,), log-probabilities (B,),
    entropies (B,), mean actions (B, A))`` of observations (B, D) and actions (B, A). Runs the policy's
    ``extract_features``, ``mlp_extractor``, ``action_net``, ``action_dist.proba_distribution`` with
    ``log_std``, and ``value_net``, as ``evaluate_actions`` does."""
    latent_pi, latent_vf = policy.mlp_extractor(policy.extract_features(observations))
    means = policy.action_net(latent_pi)
    distribution = policy.action_dist.proba_distribution(means, policy.log_std)
    values = policy.value_net(latent_vf).flatten()
    return values, distribution.log_prob(actions), distribution.entropy(), means


def action_log_std(policy) -> torch.Tensor:
    """The log standard deviations of the policy's Gaussian actions (A,) (logged as ``train/std`` after
    ``exp``): SB3's ``ActorCriticPolicy.log_std``, a parameter of a Box action space's policy."""
    return policy.log_std


def actor_layers(policy) -> tuple[torch.nn.Module, torch.nn.Sequential, torch.nn.Module]:
    """The modules an observation passes through to the mean action, in order: the feature extractor
    (shared with the critic), the actor's own layers, the action layer; SB3's ``features_extractor``,
    ``mlp_extractor.policy_net`` and ``action_net``."""
    return policy.features_extractor, policy.mlp_extractor.policy_net, policy.action_net


class OwnHeadsPolicy(ActorCriticPolicy):
    """SB3's actor-critic whose ``mlp_extractor`` (the layers from the features to the action and value
    layers) is ``heads(features_dim, pi, vf)`` with the widths of ``net_arch = {"pi": [...], "vf": [...]}``.

    Overrides SB3's private ``ActorCriticPolicy._build_mlp_extractor``. ``heads`` must be a module with
    SB3's ``MlpExtractor`` interface: ``latent_dim_pi``, ``latent_dim_vf``, ``forward`` (both latents),
    ``forward_actor`` and ``forward_critic``.
    """

    heads: type[torch.nn.Module]

    def _build_mlp_extractor(self) -> None:
        self.mlp_extractor = self.heads(
            self.features_dim, list(self.net_arch["pi"]), list(self.net_arch["vf"])
        )


# --- callbacks ------------------------------------------------------------------------------------------


def step_infos(callback) -> list[dict[str, Any]]:
    """The ``info`` dicts of the env step a callback's ``_on_step`` follows, one per environment: the
    local variable ``infos`` of SB3's ``OnPolicyAlgorithm.collect_rollouts``, which SB3 hands to its
    callbacks as ``callback.locals``."""
    return callback.locals["infos"]


def training_goal(callback) -> int:
    """The env steps the running ``learn`` trains to (the steps already done plus those asked for), in a
    callback's ``_on_training_start``: the local variable ``total_timesteps`` of SB3's
    ``OnPolicyAlgorithm.learn`` after its ``_setup_learn``, handed over as ``callback.locals``."""
    return int(callback.locals["total_timesteps"])


def logged_value(callback, name: str) -> float | None:
    """The value recorded under ``name`` since SB3's logger last wrote its records (None if none): the
    logger's ``name_to_value``."""
    return callback.logger.name_to_value.get(name)


# --- a saved model.zip ----------------------------------------------------------------------------------


def saved_update_count(data: dict[str, Any]) -> int:
    """SB3's private ``_n_updates`` (:func:`update_count`) from ``data``: the JSON of the ``data`` member
    of a ``model.zip`` that ``model.save`` wrote."""
    return int(data["_n_updates"])


def saved_episodes_pickle(data: dict[str, Any]) -> bytes:
    """The pickle of ``ep_info_buffer`` (:func:`restore_counters`) in ``data`` (:func:`saved_update_count`):
    SB3's save keeps a field JSON cannot hold as ``{":serialized:": base64 of its cloudpickle}``. Unpickle
    only with :func:`krl.agent.checkpoint.restricted_loads`."""
    return base64.b64decode(data["ep_info_buffer"][":serialized:"])
