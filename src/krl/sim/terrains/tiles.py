"""A field of square tiles, each a stack of concentric square levels: the layout the stepped pyramids (boxes,
up from the floor) and the stepped pits (a height field, down into it) share.

Draw order (fixed, for reproducibility), tile by tile, rows along y then columns along x: the riser
height ~ U(step_height_low, step_height_high), the tread ~ U(tread_low, tread_high), the number of levels
~ uniform on 1 ... max_levels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from krl.sim.terrains.params import PyramidsParams

__all__ = ["StepTiles"]


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
        col = np.clip(np.floor((x + self.half) / self.tile).astype(np.int64), 0, self.per_side - 1)
        row = np.clip(np.floor((y + self.half) / self.tile).astype(np.int64), 0, self.per_side - 1)
        # Chebyshev distance from the tile's centre, then the levels whose square still covers the point.
        inset = 0.5 * self.base - np.maximum(np.abs(x - self.centres[col]), np.abs(y - self.centres[row]))
        level = np.where(inset >= 0.0, np.floor(inset / self.tread[row, col]) + 1, 0)
        level = np.minimum(level, self.levels[row, col])
        inside = np.maximum(np.abs(x), np.abs(y)) <= self.half
        return np.where(inside, level * self.riser[row, col], 0.0)
