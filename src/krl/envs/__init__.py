"""Gymnasium environments. Importing :mod:`krl` registers them."""

import gymnasium as gym

A1_ENV_ID = "krl/A1-v0"
"""Joint-space A1 environment (:class:`krl.envs.a1.A1Env`)."""

RESIDUAL_ENV_ID = "krl/A1Residual-v0"
"""The residual agent's environment (:class:`krl.envs.residual.A1ResidualEnv`): kernel + filtered foot
residuals on rough terrain with pushes; it truncates its own episodes at the configured 60 s."""


def register_envs() -> None:
    """Register krl's environments with Gymnasium (idempotent)."""
    if A1_ENV_ID not in gym.registry:
        gym.register(id=A1_ENV_ID, entry_point="krl.envs.a1:A1Env", max_episode_steps=2000)
    if RESIDUAL_ENV_ID not in gym.registry:
        gym.register(id=RESIDUAL_ENV_ID, entry_point="krl.envs.residual:A1ResidualEnv")
