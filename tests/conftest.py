"""Fixtures shared by tests of several packages: a small agent configuration (tests/agent and
tests/analysis/agent); and how many processes run the suite.

pytest's default (prepend) import mode puts this folder on ``sys.path`` when it imports this file, so the
shared fakes beside it (``agent_fakes``, ``eval_fakes``) import by name from a test in any folder."""

from __future__ import annotations

import pytest

from krl.agent.config import AgentConfig, PPOConfig
from krl.util.parallel import usable_cores


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


MAX_TEST_PROCESSES: int = 8
"""The most test processes ``-n auto`` (pyproject.toml) starts: each holds PyTorch and MuJoCo (about 1 GB),
and many tests start processes of their own, so a many-core machine gains little past this."""


def pytest_xdist_auto_num_workers(config) -> int:
    """``-n auto``: one test process per usable core (CPU affinity), at most :data:`MAX_TEST_PROCESSES`."""
    return min(usable_cores(), MAX_TEST_PROCESSES)
