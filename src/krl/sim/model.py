"""Model assembly: the A1 MJCF plus one terrain, compiled into an ``MjModel``."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from krl.robots.a1 import MJCF_PATH
from krl.sim.terrains import Terrain, add_terrain

MARKER_HALF_HEIGHT: float = 0.15
"""Half height of a marker post [m]."""


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
    markers: Sequence[tuple[float, float]] = (),
) -> BuiltModel:
    """Compile the A1 on the named terrain.

    Args:
        terrain: a name from :data:`krl.sim.terrains.TERRAIN_NAMES`.
        terrain_params: overrides of that terrain's parameters (``docs/terrains.md``).
        seed: seed of the terrain's random draws (height fields, noise); same seed, same model.
        markers: world (x, y) points [m] shown as red posts standing on the terrain (e.g. a course's
            waypoints); they are sites, which never touch anything, so the dynamics are those of the
            model without them.

    Raises:
        krl.sim.terrains.TerrainError: unknown terrain name or bad parameter.
    """
    spec = mujoco.MjSpec.from_file(str(MJCF_PATH))
    built_terrain = add_terrain(spec, terrain, terrain_params, np.random.default_rng(seed))
    for index, (x, y) in enumerate(markers):
        z = float(built_terrain.height(x, y))
        spec.worldbody.add_site(
            name=f"marker{index}",
            type=mujoco.mjtGeom.mjGEOM_CYLINDER,
            pos=[x, y, z + MARKER_HALF_HEIGHT],
            size=[0.04, MARKER_HALF_HEIGHT, 0.0],
            rgba=[0.85, 0.1, 0.1, 0.8],
        )
    return BuiltModel(model=spec.compile(), terrain=built_terrain)
