"""A small agent configuration for the agent's tests."""

from __future__ import annotations

import pytest

from krl.agent.config import AgentConfig, PPOConfig


@pytest.fixture
def small_config() -> AgentConfig:
    """Thesis defaults with a small PPO (for speed) and few environments."""
    return AgentConfig(
        ppo=PPOConfig(rollout_steps=256, batch_size=128, n_epochs=1, shared=(16,), actor=(16,), critic=(8,)),
        num_envs=2,
        workers=1,
        total_steps=512,
        checkpoint_every=256,
    )
