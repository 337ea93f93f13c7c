"""Model assembly: the A1 MJCF plus one terrain, compiled into an ``MjModel``."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from krl.robots.a1 import MJCF_PATH
from krl.sim.terrains import Terrain, add_terrain


@dataclass(frozen=True)
class BuiltModel:
    """A compiled model and the terrain it contains."""

    model: mujoco.MjModel
    """The compiled model: robot first (qpos[0:19], qvel[0:18]), then any terrain props."""
    terrain: Terrain
    """The terrain, with every random draw resolved into ``terrain.params``."""


def build_model(
    terrain: str = "flat",
    terrain_params: Mapping[str, Any] | None = None,
    seed: int | None = 0,
) -> BuiltModel:
    """Compile the A1 on the named terrain.

    Args:
        terrain: a name from :data:`krl.sim.terrains.TERRAIN_NAMES`.
        terrain_params: overrides of that terrain's parameters (``docs/terrains.md``).
        seed: seed of the terrain's random draws (height fields, noise); same seed, same model.

    Raises:
        krl.sim.terrains.TerrainError: unknown terrain name or bad parameter.
    """
    spec = mujoco.MjSpec.from_file(str(MJCF_PATH))
    built_terrain = add_terrain(spec, terrain, terrain_params, np.random.default_rng(seed))
    return BuiltModel(model=spec.compile(), terrain=built_terrain)
