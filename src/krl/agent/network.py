"""The layers the actor and the critic share (Fig. A.1: "feature extractor 128x2"), for SB3's PPO."""

from __future__ import annotations

import gymnasium as gym
import torch
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor


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
