"""Fixtures shared by tests of several packages: a small agent configuration (tests/agent and
tests/analysis/agent).

pytest's default (prepend) import mode puts this folder on ``sys.path`` when it imports this file, so the
shared fakes beside it (``agent_fakes``, ``eval_fakes``) import by name from a test in any folder."""

from __future__ import annotations

import pytest

from krl.agent.config import AgentConfig, PPOConfig


@pytest.fixture(scope="session")  # frozen: one instance serves every test
def small_config() -> AgentConfig:
    """Thesis defaults with a small PPO (for speed) and few environments."""
    return AgentConfig(
        ppo=PPOConfig(rollout_steps=256, batch_size=128, n_epochs=1, shared=(16,), actor=(16,), critic=(8,)),
        num_envs=2,
        workers=1,
        total_steps=512,
        checkpoint_every=256,
    )
