"""Fakes for the agent's tests: a policy of a config's shape with chosen weights, the training log's columns,
and the settings of tiny real trainings in an agent study."""

from __future__ import annotations

import numpy as np

from krl.agent.config import AgentConfig
from krl.agent.curves import STEPS_COLUMN
from krl.agent.observation import observation_size
from krl.agent.policy import Policy
from krl.kernel.registry import resolve_model
from krl.util.hashing import file_sha256

LOG_COLUMNS: tuple[str, ...] = (
    STEPS_COLUMN,
    "episode/reward",
    "episode/targets_reached",
    "episode/fall_rate",
    "episode/success_rate",
)
"""Columns of a fake training log (``progress.csv``), in the order the fakes write them."""

TINY_STUDY: dict = {
    "ppo": {
        "rollout_steps": 128,
        "batch_size": 64,
        "n_epochs": 1,
        "shared": [16],
        "actor": [16],
        "critic": [8],
    },
    "num_envs": 2,
    "checkpoint_every": 256,
    "env": {"episode_time": 0.5},
}
"""Settings every trial of a tiny real agent study shares (``--config``): a tiny network, and half-second
episodes so that some end within a few hundred steps."""


def make_policy(config: AgentConfig, scale: float = 0.0, seed: int = 0) -> Policy:
    """A policy of the config's shape with weights ~ N(0, scale²) (scale 0: always the zero action)."""
    rng = np.random.default_rng(seed)
    size = observation_size(config.observation.features, config.observation.scan)
    widths = [size, *config.ppo.shared, *config.ppo.actor, config.residual.action_size]
    layers = [
        (scale * rng.standard_normal((widths[i + 1], widths[i])), scale * rng.standard_normal(widths[i + 1]))
        for i in range(len(widths) - 1)
    ]
    metadata = {
        "kernel_sha256": file_sha256(resolve_model(config.residual.kernel)),
        "training": {"env_steps": 0, "wall_seconds": 0.0, "seed": seed},
        "software": {},
    }
    return Policy(config, layers, np.zeros(size), np.ones(size), 10.0, 1e-8, metadata)
