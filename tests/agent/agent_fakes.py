"""A policy of a config's shape with chosen weights, for the agent's tests."""

from __future__ import annotations

import numpy as np

from krl.agent.config import AgentConfig
from krl.agent.observation import observation_size
from krl.agent.policy import Policy
from krl.kernel.registry import resolve_model
from krl.util.hashing import file_sha256


def make_policy(config: AgentConfig, scale: float = 0.0, seed: int = 0) -> Policy:
    """A policy of the config's shape with weights ~ N(0, scale²) (scale 0: always the zero action)."""
    rng = np.random.default_rng(seed)
    size = observation_size(config.observation.features)
    widths = [size, *config.ppo.shared, *config.ppo.actor, 12]
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
