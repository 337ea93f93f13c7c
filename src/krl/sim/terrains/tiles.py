"""A field of square tiles, each a stack of concentric square levels: the layout the stepped pyramids (boxes,
up from the floor) and the stepped pits (a height field, down into it) share.

Draw order (fixed, for reproducibility), tile by tile, rows along y then columns along x: the riser
height ~ U(step_height_low, step_height_high), the tread ~ U(tread_low, tread_high), the number of levels
~ uniform on 1 ... max_levels.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from krl.sim.terrains.params import PyramidsParams

__all__ = ["StepTiles", "StepTilesStack", "tiles_height"]


@dataclass(frozen=True, eq=False)
class StepTiles:
    """The drawn tiles of a stepped field: tile ``(row, col)`` is centred on ``(centres[col],
    centres[row])``; its level k (1 ... ``levels``) is a square of side ``base - 2 (k - 1) tread``."""

    per_side: int
    """Tiles along each side."""
    tile: float
    """Side of a tile [m]."""
    base: float
    """Side of a tile's first level (the tile less its lane) [m]."""
    centres: np.ndarray
    """Tile centres along either axis [m]. Shape: (per_side,)."""
    riser: np.ndarray
    """Riser height of each tile [m]. Shape: (per_side, per_side)."""
    tread: np.ndarray
    """Tread depth of each tile [m]. Shape: (per_side, per_side)."""
    levels: np.ndarray
    """Number of levels of each tile. Shape: (per_side, per_side), int."""

    @property
    def half(self) -> float:
        """The field covers [-half, half]² [m]."""
        return 0.5 * self.per_side * self.tile

    @classmethod
    def draw(cls, p: PyramidsParams, rng: np.random.Generator) -> StepTiles:
        """The tiles of a field of parameters ``p`` (the pyramids' or the pits'), drawn from ``rng``."""
        per_side = 2 * math.ceil(p.half_size / p.tile - 1e-9)
        riser = np.empty((per_side, per_side))
        tread = np.empty((per_side, per_side))
        levels = np.empty((per_side, per_side), dtype=np.int64)
        for row in range(per_side):
            for col in range(per_side):
                riser[row, col] = rng.uniform(p.step_height_low, p.step_height_high)
                tread[row, col] = rng.uniform(p.tread_low, p.tread_high)
                levels[row, col] = rng.integers(1, p.max_levels + 1)
        centres = (np.arange(per_side) - 0.5 * (per_side - 1)) * p.tile
        return cls(per_side, p.tile, p.tile - p.lane, centres, riser, tread, levels)

    def height(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Height of the stacked levels at (x, y) [m] (a pyramid's; a pit is its negative), 0 on the lanes
        and beyond the field. x and y broadcast."""
        return tiles_height(
            self.riser.ravel(), self.tread.ravel(), self.levels.ravel(), self.centres, 0, 0,
            self.per_side, self.tile, self.base, self.half, x, y,
        )  # fmt: skip

    @staticmethod
    def stack(fields: Sequence[StepTiles]) -> StepTilesStack:
        """The fields read at once (:class:`StepTilesStack`)."""
        return StepTilesStack(fields)


class StepTilesStack:
    """Several :class:`StepTiles` read at once: :meth:`height` of N fields at P points each, bit for bit
    what each field's own :meth:`StepTiles.height` gives (the same arithmetic, its parameters as columns).

    Args:
        fields: the N fields.
    """

    def __init__(self, fields: Sequence[StepTiles]) -> None:
        sides = np.array([f.per_side for f in fields], dtype=np.int64)
        self.riser = np.concatenate([f.riser.ravel() for f in fields])
        """Every field's risers, one after the other [m]; likewise :attr:`tread` [m] and :attr:`levels`."""
        self.tread = np.concatenate([f.tread.ravel() for f in fields])
        self.levels = np.concatenate([f.levels.ravel() for f in fields])
        self.centres = np.concatenate([f.centres for f in fields])
        """Every field's tile centres, one after the other [m]."""
        self.tile_start = (np.cumsum(sides**2) - sides**2)[:, None]
        """Where each field's tiles begin in :attr:`riser`. Shape: (N, 1)."""
        self.centre_start = (np.cumsum(sides) - sides)[:, None]
        """Where each field's centres begin in :attr:`centres`. Shape: (N, 1)."""
        self.per_side = sides[:, None]
        column = np.array([[f.tile, f.base, f.half] for f in fields])
        self.tile, self.base, self.half = (column[:, i : i + 1] for i in range(3))

    def height(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Height of field n at (x[n], y[n]) [m], shapes (N, P). Shape: (N, P)."""
        return tiles_height(
            self.riser, self.tread, self.levels, self.centres, self.tile_start, self.centre_start,
            self.per_side, self.tile, self.base, self.half, x, y,
        )  # fmt: skip


def tiles_height(
    riser: np.ndarray,
    tread: np.ndarray,
    levels: np.ndarray,
    centres: np.ndarray,
    tile_start: ArrayLike,
    centre_start: ArrayLike,
    per_side: ArrayLike,
    tile: ArrayLike,
    base: ArrayLike,
    half: ArrayLike,
    x: np.ndarray,
    y: np.ndarray,
) -> np.ndarray:
    """Height [m] at (x, y) [m] of the stepped field whose tiles' ``riser``, ``tread`` and ``levels`` begin at
    ``tile_start`` (row-major, ``per_side`` along each side) and whose centres begin at ``centre_start``;
    tiles of side ``tile``, first levels of side ``base``, the field covering [-half, half]² [m]. The
    field's parameters broadcast against x and y, so one call reads one field (scalars) or a stack of them
    (columns of shape (N, 1) against points of shape (N, P))."""
    col = np.clip(np.floor((x + half) / tile).astype(np.int64), 0, per_side - 1)
    row = np.clip(np.floor((y + half) / tile).astype(np.int64), 0, per_side - 1)
    at = tile_start + row * per_side + col
    # Chebyshev distance from the tile's centre, then the levels whose square still covers the point.
    inset = 0.5 * base - np.maximum(
        np.abs(x - centres[centre_start + col]), np.abs(y - centres[centre_start + row])
    )
    level = np.where(inset >= 0.0, np.floor(inset / tread[at]) + 1, 0)
    level = np.minimum(level, levels[at])
    inside = np.maximum(np.abs(x), np.abs(y)) <= half
    return np.where(inside, level * riser[at], 0.0)
