"""The agent's network in SB3's PPO: the layers the actor and the critic share (Fig. A.1: "feature
extractor 128x2"), and the actor taken out of a trained model as a policy file (:func:`export_policy`)."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor

from krl.agent.config import AgentConfig
from krl.agent.policy import Policy


class SharedExtractor(BaseFeaturesExtractor):
    """Linear + tanh layers of the given widths from the observation; their output feeds both heads."""

    def __init__(self, observation_space: gym.spaces.Box, hidden: list[int]) -> None:
        super().__init__(observation_space, features_dim=hidden[-1])
        layers: list[torch.nn.Module] = []
        width = int(observation_space.shape[0])
        for size in hidden:
            layers += [torch.nn.Linear(width, size), torch.nn.Tanh()]
            width = size
        self.net = torch.nn.Sequential(*layers)

    def forward(self, observations: torch.Tensor) -> torch.Tensor:
        return self.net(observations)


def export_policy(model, normaliser, config: AgentConfig, metadata: dict[str, Any]) -> Policy:
    """The actor of a PPO model built with :class:`SharedExtractor` as a :class:`Policy`.

    Args:
        model: SB3 PPO; its actor is the shared layers (``features_extractor.net``), the actor's own
            layers (``mlp_extractor.policy_net``) and the action layer (``action_net``), tanh between.
        normaliser: the model's ``VecNormalize`` (or None): its observation mean, variance, clip and
            epsilon go into the policy when ``config.ppo.normalize_observations``.
        config: the agent's configuration, saved in the policy.
        metadata: the policy header's ``kernel_sha256``, ``training`` and ``software``.
    """
    policy = model.policy
    modules = [*policy.features_extractor.net, *policy.mlp_extractor.policy_net, policy.action_net]
    layers = [
        (m.weight.detach().cpu().double().numpy(), m.bias.detach().cpu().double().numpy())
        for m in modules
        if isinstance(m, torch.nn.Linear)
    ]
    size = layers[0][0].shape[1]
    if normaliser is not None and config.ppo.normalize_observations:
        mean, var = normaliser.obs_rms.mean.astype(np.float64), normaliser.obs_rms.var.astype(np.float64)
        clip, epsilon = float(normaliser.clip_obs), float(normaliser.epsilon)
    else:
        mean, var, clip, epsilon = np.zeros(size), np.ones(size), 1e9, 0.0
    return Policy(config, layers, mean, var, clip, epsilon, metadata)
