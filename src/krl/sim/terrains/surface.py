"""The fixed ground of a terrain as a *surface*: a height function that many terrains of one kind can
answer at once.

A :class:`Surface` gives the height of the fixed ground at world points (:meth:`Surface.height`) and
stacks with surfaces of its own class (:meth:`Surface.stack`) into a :class:`SurfaceStack`, whose one call
reads N terrains at P points each, bit for bit what each surface gives alone: the same arithmetic, each
terrain's parameters a column. The height scan (:mod:`krl.sim.scan`) reads the training ground of every
robot of a batch this way, one NumPy pass per kind of ground instead of one per robot.

Surfaces: :class:`FlatSurface` (a level floor), :class:`GridSurface` (a height field and the floor
beyond it), :class:`krl.sim.terrains.tiles.StepTiles` (the stepped pyramids' boxes).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from krl.sim.terrains.grid import HeightGrid, HeightGridStack

__all__ = ["FlatSurface", "GridSurface", "Surface", "SurfaceStack"]


class SurfaceStack(Protocol):
    """N surfaces of one kind, read at once."""

    def height(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Height of surface n at (x[n], y[n]) [m], shapes (N, P). Shape: (N, P)."""
        ...


class Surface(Protocol):
    """The fixed ground of a terrain."""

    def height(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Height of the ground at world (x, y) [m], x and y broadcast [m]."""
        ...

    @staticmethod
    def stack(surfaces: Sequence[Surface]) -> SurfaceStack:
        """Surfaces of this class read at once."""
        ...


@dataclass(frozen=True)
class FlatSurface:
    """A level floor at height ``z`` [m]."""

    z: float = 0.0

    def height(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """``z`` everywhere [m]; the shape of x."""
        return np.full(np.shape(x), self.z)

    @staticmethod
    def stack(surfaces: Sequence[FlatSurface]) -> _FlatStack:
        """The floors read at once."""
        return _FlatStack(np.array([[s.z] for s in surfaces]))


@dataclass(frozen=True)
class _FlatStack:
    z: np.ndarray
    """Each floor's height [m]. Shape: (N, 1)."""

    def height(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        return np.broadcast_to(self.z, np.shape(x)).copy()


@dataclass(frozen=True, eq=False)
class GridSurface:
    """A height field (:class:`HeightGrid`) and, beyond its edges, the floor at ``floor_z`` [m]."""

    grid: HeightGrid
    floor_z: float

    def height(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """The field's triangles where (x, y) [m] lies over it, the floor elsewhere [m]."""
        z = self.grid.height(x, y)
        return np.where(np.isnan(z), self.floor_z, z)

    @staticmethod
    def stack(surfaces: Sequence[GridSurface]) -> _GridStack:
        """The fields read at once."""
        return _GridStack(
            HeightGridStack([s.grid for s in surfaces]), np.array([[s.floor_z] for s in surfaces])
        )


@dataclass(frozen=True, eq=False)
class _GridStack:
    grids: HeightGridStack
    floor_z: np.ndarray
    """Each floor's height [m]. Shape: (N, 1)."""

    def height(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        z = self.grids.height(x, y)
        return np.where(np.isnan(z), self.floor_z, z)
