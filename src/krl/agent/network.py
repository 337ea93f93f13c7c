"""The agent's network in SB3's PPO: the layers the actor and the critic share (Fig. A.1: "feature
extractor 128x2"), or, for a critic that sees more than the actor (``observation.critic_features``), an
actor and a critic of their own (:class:`PrivilegedCriticPolicy`); and the actor taken out of a trained
model as a policy file (:func:`export_policy`)."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor

from krl.agent.config import AgentConfig
from krl.agent.observation import observation_size
from krl.agent.policy import Policy
from krl.agent.sb3_adapter import OwnHeadsPolicy, actor_layers


def _tanh_layers(width: int, hidden: list[int]) -> torch.nn.Sequential:
    """Linear + tanh layers of the widths ``hidden`` from an input of ``width`` numbers."""
    layers: list[torch.nn.Module] = []
    for size in hidden:
        layers += [torch.nn.Linear(width, size), torch.nn.Tanh()]
        width = size
    return torch.nn.Sequential(*layers)


class SharedExtractor(BaseFeaturesExtractor):
    """Linear + tanh layers of the given widths from the observation; their output feeds both heads."""

    def __init__(self, observation_space: gym.spaces.Box, hidden: list[int]) -> None:
        super().__init__(observation_space, features_dim=hidden[-1])
        self.net = _tanh_layers(int(observation_space.shape[0]), hidden)

    def forward(self, observations: torch.Tensor) -> torch.Tensor:
        return self.net(observations)


class SplitExtractor(BaseFeaturesExtractor):
    """Two towers of the same widths: the actor's on the observation's first ``actor_size`` numbers (what
    a robot measures), the critic's on all of it (its privileged features too); their outputs side by side,
    the actor's first. Shape: (B, D) -> (B, 2 hidden[-1])."""

    def __init__(self, observation_space: gym.spaces.Box, hidden: list[int], actor_size: int) -> None:
        super().__init__(observation_space, features_dim=2 * hidden[-1])
        self.actor_size = actor_size
        self.actor = _tanh_layers(actor_size, hidden)
        self.critic = _tanh_layers(int(observation_space.shape[0]), hidden)

    def forward(self, observations: torch.Tensor) -> torch.Tensor:
        return torch.cat([self.actor(observations[:, : self.actor_size]), self.critic(observations)], dim=1)


class SplitHeads(torch.nn.Module):
    """SB3's ``mlp_extractor`` for :class:`SplitExtractor`'s features: the actor's layers on the first half,
    the critic's on the second, so no gradient of the value reaches the actor's tower."""

    def __init__(self, features_dim: int, pi: list[int], vf: list[int]) -> None:
        super().__init__()
        self.half = features_dim // 2
        self.policy_net = _tanh_layers(self.half, pi)
        self.value_net = _tanh_layers(self.half, vf)
        self.latent_dim_pi = pi[-1] if pi else self.half
        self.latent_dim_vf = vf[-1] if vf else self.half

    def forward(self, features: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return self.forward_actor(features), self.forward_critic(features)

    def forward_actor(self, features: torch.Tensor) -> torch.Tensor:
        return self.policy_net(features[:, : self.half])

    def forward_critic(self, features: torch.Tensor) -> torch.Tensor:
        return self.value_net(features[:, self.half :])


class PrivilegedCriticPolicy(OwnHeadsPolicy):
    """SB3's actor-critic whose critic sees privileged features the actor does not: built with
    :class:`SplitExtractor` (``features_extractor_kwargs`` give ``hidden`` and ``actor_size``) and
    :class:`SplitHeads` (``net_arch = {"pi": [...], "vf": [...]}``)."""

    heads = SplitHeads


def actor_modules(policy) -> list[torch.nn.Module]:
    """The actor's modules of an SB3 policy built here, input to action: the (actor's) extractor layers,
    its own layers, the action layer."""
    extractor, own_layers, action_layer = actor_layers(policy)
    tower = extractor.actor if isinstance(extractor, SplitExtractor) else extractor.net
    return [*tower, *own_layers, action_layer]


def export_policy(model, normaliser, config: AgentConfig, metadata: dict[str, Any]) -> Policy:
    """The actor of a PPO model built here as a :class:`Policy` (the critic and its privileged inputs stay
    behind).

    Args:
        model: SB3 PPO; its actor is :func:`actor_modules`, tanh between the linear layers.
        normaliser: the model's ``VecNormalize`` (or None): its observation mean, variance, clip and
            epsilon go into the policy when ``config.ppo.normalize_observations``.
        config: the agent's configuration, saved in the policy.
        metadata: the policy header's ``kernel_sha256``, ``training`` and ``software``.
    """
    layers = [
        (m.weight.detach().cpu().double().numpy(), m.bias.detach().cpu().double().numpy())
        for m in actor_modules(model.policy)
        if isinstance(m, torch.nn.Linear)
    ]
    size = observation_size(config.observation.features, config.observation.scan)
    if normaliser is not None and config.ppo.normalize_observations:  # the actor's features come first
        mean = normaliser.obs_rms.mean[:size].astype(np.float64)
        var = normaliser.obs_rms.var[:size].astype(np.float64)
        clip, epsilon = float(normaliser.clip_obs), float(normaliser.epsilon)
    else:
        mean, var, clip, epsilon = np.zeros(size), np.ones(size), 1e9, 0.0
    return Policy(config, layers, mean, var, clip, epsilon, metadata)
