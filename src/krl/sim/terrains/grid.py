"""Height-field grids: the vertex axis of a square field and :class:`HeightGrid`, its surface in world z.

Height fields follow MuJoCo's convention: ``data[r, c]`` is the vertex at ``x = x0 + c * dx``,
``y = y0 + r * dy`` (rows along y) and each grid cell is split into the two triangles on either side of its
``(r, c) - (r + 1, c + 1)`` diagonal; :meth:`HeightGrid.height` interpolates exactly the same triangles.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["MAX_HFIELD_SIDE", "HeightGrid", "grid_axis", "grid_count", "triangle_gradients"]

MAX_HFIELD_SIDE: int = 1024
"""Largest number of height-field vertices along one side (cost guard: compile time and memory)."""


def grid_count(half_size: float, cell: float) -> int:
    """Vertices along one side of a field spanning [-half_size, half_size] [m] at spacing ``cell`` [m]."""
    return round(2.0 * half_size / cell) + 1


def grid_axis(half_size: float, cell: float) -> np.ndarray:
    """Vertex coordinates along one axis, from -half_size to half_size, spacing as close to cell as fits [m].

    Shape: (:func:`grid_count`,).
    """
    return np.linspace(-half_size, half_size, grid_count(half_size, cell))


@dataclass(frozen=True, eq=False)
class HeightGrid:
    """A MuJoCo height field in world coordinates: vertex heights and the triangles between them."""

    x0: float
    """x of column 0 [m]."""
    y0: float
    """y of row 0 [m]."""
    dx: float
    """Column spacing [m]."""
    dy: float
    """Row spacing [m]."""
    heights: np.ndarray = field(repr=False)
    """World z of every vertex [m]. Shape: (nrow, ncol); rows along y, columns along x."""

    @property
    def shape(self) -> tuple[int, int]:
        """(nrow, ncol) of :attr:`heights`."""
        return self.heights.shape  # type: ignore[return-value]

    @property
    def x1(self) -> float:
        """x of the last column [m]."""
        return self.x0 + (self.heights.shape[1] - 1) * self.dx

    @property
    def y1(self) -> float:
        """y of the last row [m]."""
        return self.y0 + (self.heights.shape[0] - 1) * self.dy

    def contains(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Whether (x, y) [m] lies over the field (boundary included); x and y broadcast."""
        return (x >= self.x0) & (x <= self.x1) & (y >= self.y0) & (y <= self.y1)

    def height(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Surface height at (x, y) [m] as MuJoCo triangulates it [m]; NaN outside the field. x and y
        broadcast."""
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        nrow, ncol = self.heights.shape
        u = (x - self.x0) / self.dx
        v = (y - self.y0) / self.dy
        c = np.clip(np.floor(u), 0, ncol - 2).astype(np.intp)
        r = np.clip(np.floor(v), 0, nrow - 2).astype(np.intp)
        fu = u - c
        fv = v - r
        h = self.heights
        z00, z10 = h[r, c], h[r, c + 1]
        z01, z11 = h[r + 1, c], h[r + 1, c + 1]
        lower = fu >= fv  # triangle (00, 10, 11)
        z = np.where(
            lower,
            z00 + fu * (z10 - z00) + fv * (z11 - z10),
            z00 + fu * (z11 - z01) + fv * (z01 - z00),
        )
        return np.where(self.contains(x, y), z, np.nan)

    def slopes(self) -> np.ndarray:
        """Slope angle of every triangle [rad]. Shape: (2, nrow - 1, ncol - 1)."""
        return np.arctan(triangle_gradients(self.heights, self.dx, self.dy))

    def max_slope(self) -> float:
        """Steepest triangle of the surface [rad]."""
        return float(np.arctan(triangle_gradients(self.heights, self.dx, self.dy).max()))


def triangle_gradients(h: np.ndarray, dx: float, dy: float) -> np.ndarray:
    """Gradient magnitude of both triangles of every cell [-] of vertex heights ``h`` [m], shape (nrow, ncol),
    at column and row spacings ``dx``, ``dy`` [m]. Shape: (2, nrow - 1, ncol - 1)."""
    z00, z10, z01, z11 = h[:-1, :-1], h[:-1, 1:], h[1:, :-1], h[1:, 1:]
    lower = np.hypot((z10 - z00) / dx, (z11 - z10) / dy)
    upper = np.hypot((z11 - z01) / dx, (z01 - z00) / dy)
    return np.stack([lower, upper])
