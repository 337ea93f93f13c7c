"""Mirror-symmetric PPO: the thesis's PPO update with the A1's left-right mirror (ours, docs/agent-robust.md).

A residual agent on a symmetric robot should act as the mirror image of itself in the mirrored state:
``π(M_o s) = M_a π(s)`` and ``V(M_o s) = V(s)`` (:mod:`krl.agent.symmetry` gives M_o and M_a). Two standard
ways to ask PPO for it (rsl_rl's symmetry configuration; Mittal et al., ICRA 2024; Su et al., IROS 2024):

``augment``
    every minibatch of B samples ``(s, a, A, R, log π_old(a|s), V_old)`` is joined by its mirror
    ``(M_o s, M_a a, A, R, log π_old(a|s), V_old)``: 2B samples, the advantage and return unchanged (the
    MDP is symmetric), the old log-probability the original's (the mirrored action's behaviour probability
    under a symmetric policy);
``loss``
    the PPO loss of the B samples plus ``mirror_loss_coef`` × (the mean squared difference between the
    policy's mean action in the mirrored states and the mirror of its mean action, plus the same of the
    value function, times ``vf_coef``).

Both log ``train/mirror_error`` (the first of those two squared differences, before the step), so every
symmetric run can say how symmetric its policy is. Both cost the network's forward and backward passes
over twice the samples of SB3's update. With ``symmetry = "none"`` krl trains
with SB3's own update (:class:`krl.agent.train.ThreadedPPO`); this update without mirror terms is SB3's
step for step (``tests/agent/test_symmetric_ppo.py`` checks equal weights after an update).

The stored observations are normalised by the run's ``VecNormalize``; a stored observation is mirrored as
the raw one would be: un-normalised with the current statistics, mirrored, normalised and clipped again.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch.nn import functional

from krl.agent.sb3_adapter import (
    action_log_std,
    clip_range_now,
    count_update,
    evaluate_with_means,
    rollout_minibatches,
    rollout_values_and_returns,
    update_count,
    update_learning_rate,
)
from krl.agent.symmetry import SignedPermutation


@dataclass(frozen=True)
class NormalisedMirror:
    """The mirror of observations normalised as ``clip((x - mean) / std, -clip, clip)``. Torch, (B, D)."""

    mirror: SignedPermutation
    mean: torch.Tensor
    std: torch.Tensor
    clip: float

    @classmethod
    def of(cls, mirror: SignedPermutation, normaliser, device) -> NormalisedMirror:
        """For the observations ``normaliser`` (SB3's ``VecNormalize`` or None: raw) produces now."""
        size = mirror.size
        if normaliser is None or not normaliser.norm_obs:
            mean, std, clip = np.zeros(size), np.ones(size), np.inf
        else:
            rms = normaliser.obs_rms
            mean, std, clip = rms.mean, np.sqrt(rms.var + normaliser.epsilon), float(normaliser.clip_obs)
        as_tensor = lambda a: torch.as_tensor(np.asarray(a, dtype=np.float32), device=device)  # noqa: E731
        return cls(mirror, as_tensor(mean), as_tensor(std), clip)

    def __call__(self, observations: torch.Tensor) -> torch.Tensor:
        raw = observations * self.std + self.mean
        return torch.clamp((self.mirror(raw) - self.mean) / self.std, -self.clip, self.clip)


def ppo_update(model, observation_mirror: SignedPermutation, action_mirror: SignedPermutation) -> None:
    """One PPO update of ``model`` (SB3's PPO after a rollout) with ``model.symmetry``'s mirror terms.

    The update reads as SB3's: ``n_epochs`` passes over the rollout in minibatches of ``batch_size``,
    per-minibatch advantage normalisation, the clipped surrogate, the value loss, the entropy bonus,
    gradient-norm clipping. Logs SB3's ``train/*`` values and ``train/mirror_error``, ``train/mirror_loss``.
    """
    policy = model.policy
    policy.set_training_mode(True)
    update_learning_rate(model)
    clip_range = clip_range_now(model)
    mirror_obs = NormalisedMirror.of(observation_mirror, model.get_vec_normalize_env(), model.device)
    logs: dict[str, list[float]] = {}
    for _ in range(model.n_epochs):
        logs["approx_kl"] = []  # SB3 logs the last epoch's
        for batch in rollout_minibatches(model):
            loss, values = _minibatch_loss(model, batch, clip_range, mirror_obs, action_mirror)
            for name, value in values.items():
                logs.setdefault(name, []).append(value)
            policy.optimizer.zero_grad()
            loss.backward()
            torch.nn.utils.clip_grad_norm_(policy.parameters(), model.max_grad_norm)
            policy.optimizer.step()
        count_update(model)
    _log(model, logs, clip_range)


def _minibatch_loss(model, batch, clip_range: float, mirror_obs: NormalisedMirror, mirror_act):
    """The loss of one minibatch and its logged parts (floats). Both modes run the network once over the
    B samples and once over their mirrors (what SB3's ``evaluate_actions`` computes, with the mean action),
    and take the mirror error from those passes."""
    advantages, returns, old_log_prob = batch.advantages, batch.returns, batch.old_log_prob
    mirrored_obs, mirrored_actions = mirror_obs(batch.observations), mirror_act(batch.actions)
    values, log_prob, entropy, means = evaluate_with_means(model.policy, batch.observations, batch.actions)
    mirror = evaluate_with_means(model.policy, mirrored_obs, mirrored_actions)
    action_error = functional.mse_loss(mirror[3], mirror_act(means))
    if model.symmetry == "augment":
        values, log_prob, entropy = (
            torch.cat([x, y]) for x, y in zip((values, log_prob, entropy), mirror[:3], strict=True)
        )
        advantages, returns, old_log_prob = (torch.cat([x, x]) for x in (advantages, returns, old_log_prob))
    if model.normalize_advantage and len(advantages) > 1:
        advantages = (advantages - advantages.mean()) / (advantages.std() + 1e-8)
    ratio = torch.exp(log_prob - old_log_prob)
    surrogate = torch.min(advantages * ratio, advantages * torch.clamp(ratio, 1 - clip_range, 1 + clip_range))
    policy_loss = -surrogate.mean()
    value_loss = functional.mse_loss(returns, values)
    entropy_loss = -torch.mean(entropy)
    loss = policy_loss + model.ent_coef * entropy_loss + model.vf_coef * value_loss
    if model.symmetry == "loss":
        value_error = functional.mse_loss(mirror[0], values)
        loss = loss + model.mirror_loss_coef * (action_error + model.vf_coef * value_error)
    with torch.no_grad():
        log_ratio = log_prob - old_log_prob
        logged = {
            "policy_gradient_loss": policy_loss.item(),
            "value_loss": value_loss.item(),
            "entropy_loss": entropy_loss.item(),
            "clip_fraction": torch.mean((torch.abs(ratio - 1) > clip_range).float()).item(),
            "approx_kl": torch.mean(torch.exp(log_ratio) - 1 - log_ratio).item(),
            "mirror_error": action_error.item(),
            "loss": loss.item(),
        }
    return loss, logged


def _log(model, logs: dict[str, list[float]], clip_range: float) -> None:
    """SB3's ``train/*`` records of an update (the last minibatch's loss, the others' means)."""
    from stable_baselines3.common.utils import explained_variance

    record = model.logger.record
    for name, values in logs.items():
        record(f"train/{name}", values[-1] if name == "loss" else float(np.mean(values)))
    record("train/explained_variance", explained_variance(*rollout_values_and_returns(model)))
    record("train/std", torch.exp(action_log_std(model.policy)).mean().item())
    record("train/n_updates", update_count(model), exclude="tensorboard")
    record("train/clip_range", clip_range)
