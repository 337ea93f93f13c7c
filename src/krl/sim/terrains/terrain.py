"""The built terrain: :class:`Terrain`, what :func:`krl.sim.terrains.add_terrain` returns.

World conventions: z up, ground at z = 0 for the flat-floored terrains, the robot starts at
:attr:`Terrain.spawn_xy` facing +x (:attr:`Terrain.spawn_yaw` = 0).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from krl.sim.terrains.grid import HeightGrid
from krl.sim.terrains.surface import Surface

__all__ = ["Terrain"]


@dataclass(frozen=True, eq=False)
class Terrain:
    """A terrain added to a spec by :func:`krl.sim.terrains.add_terrain`: what was built and where things
    are."""

    name: str
    """One of :data:`krl.sim.terrains.TERRAIN_NAMES`."""
    params: dict[str, float | int]
    """Fully resolved parameters (defaults filled in, random draws made; ``friction`` only where not 1):
    passing them back to :func:`add_terrain` with an rng of the same seed rebuilds the same terrain."""
    spawn_xy: tuple[float, float]
    """Default start position of the robot's base [m]."""
    spawn_yaw: float = 0.0
    """Default heading of the robot at spawn [rad] (0: facing +x)."""
    moving_joints: tuple[str, ...] = ()
    """Names of the joints of moving props (they follow the robot's joints in qpos/qvel)."""
    geom_names: tuple[str, ...] = ()
    """Names of every geom this terrain added (for contact classification)."""
    landmarks: dict[str, tuple[float, float]] = field(default_factory=dict)
    """Named (x, y) points of the layout [m], e.g. ``first_riser`` or ``pivot``; see docs/terrains.md."""
    grid: HeightGrid | None = field(default=None, repr=False)
    """The height field, for the height-field terrains; None otherwise."""
    _height_fn: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = field(default=None, repr=False)
    surface: Surface | None = field(default=None, repr=False)
    """The fixed ground without the moving props, as a :class:`krl.sim.terrains.surface.Surface` that the
    height scan reads many robots' terrains of at once; set for every terrain with props. None: the ground is
    :attr:`_height_fn` (a terrain without props), read one terrain at a time."""

    def height(self, x: Any, y: Any) -> np.ndarray:
        """Height of the terrain surface at rest at world (x, y) [m], vectorised (x and y broadcast).

        For props (table-top, seesaw) this is the surface in its initial pose (level plate, seesaw on its
        limit); it does not follow the prop once it moves.
        """
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        assert self._height_fn is not None
        return self._height_fn(x, y)

    def ground_height(self, x: Any, y: Any) -> np.ndarray:
        """Height of the fixed ground at world (x, y) [m], without the moving props (the table-top's plate,
        the seesaw's plank), vectorised (x and y broadcast): :attr:`surface`, else :meth:`height`.
        :class:`krl.sim.scan.TerrainScanner` adds the props where they are at each step."""
        if self.surface is None:
            return self.height(x, y)
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        return self.surface.height(x, y)

    @property
    def max_slope(self) -> float | None:
        """Steepest triangle of the height field [rad], or None for terrains without one."""
        return None if self.grid is None else self.grid.max_slope()
