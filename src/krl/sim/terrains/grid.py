"""Height-field grids: the vertex axis of a square field and :class:`HeightGrid`, its surface in world z.

Height fields follow MuJoCo's convention: ``data[r, c]`` is the vertex at ``x = x0 + c * dx``,
``y = y0 + r * dy`` (rows along y) and each grid cell is split into the two triangles on either side of its
``(r, c) - (r + 1, c + 1)`` diagonal; :meth:`HeightGrid.height` interpolates exactly the same triangles.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

__all__ = [
    "MAX_HFIELD_SIDE",
    "HeightGrid",
    "HeightGridStack",
    "grid_axis",
    "grid_count",
    "triangle_gradients",
    "triangulated_height",
]

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

    def height(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Surface height at (x, y) [m] as MuJoCo triangulates it [m]; NaN outside the field. x and y
        broadcast."""
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        nrow, ncol = self.heights.shape
        return triangulated_height(
            self.heights.ravel(), 0, nrow, ncol, self.x0, self.y0, self.dx, self.dy, x, y
        )

    def slopes(self) -> np.ndarray:
        """Slope angle of every triangle [rad]. Shape: (2, nrow - 1, ncol - 1)."""
        return np.arctan(triangle_gradients(self.heights, self.dx, self.dy))

    def max_slope(self) -> float:
        """Steepest triangle of the surface [rad]."""
        return float(np.arctan(triangle_gradients(self.heights, self.dx, self.dy).max()))


class HeightGridStack:
    """Several :class:`HeightGrid` s read at once: :meth:`height` of N grids at P points each, bit for bit
    what each grid's own :meth:`HeightGrid.height` gives (the same arithmetic, its parameters as columns).

    Args:
        grids: the N grids (any sizes and spacings).
    """

    def __init__(self, grids: Sequence[HeightGrid]) -> None:
        shapes = np.array([grid.heights.shape for grid in grids], dtype=np.intp)
        sizes = shapes[:, 0] * shapes[:, 1]
        self.vertices = np.concatenate([grid.heights.ravel() for grid in grids])
        """Every grid's vertex heights, one after the other [m]. Shape: (sum of nrow * ncol,)."""
        self.start = (np.cumsum(sizes) - sizes)[:, None]
        """Where each grid's vertices begin in :attr:`vertices`. Shape: (N, 1)."""
        self.nrow, self.ncol = shapes[:, :1], shapes[:, 1:]
        column = np.array([[grid.x0, grid.y0, grid.dx, grid.dy] for grid in grids])
        self.x0, self.y0, self.dx, self.dy = (column[:, i : i + 1] for i in range(4))

    def height(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Surface height of grid n at (x[n], y[n]) [m], shapes (N, P); NaN outside it. Shape: (N, P)."""
        return triangulated_height(
            self.vertices, self.start, self.nrow, self.ncol, self.x0, self.y0, self.dx, self.dy, x, y
        )


def triangulated_height(
    vertices: np.ndarray,
    start: ArrayLike,
    nrow: ArrayLike,
    ncol: ArrayLike,
    x0: ArrayLike,
    y0: ArrayLike,
    dx: ArrayLike,
    dy: ArrayLike,
    x: np.ndarray,
    y: np.ndarray,
) -> np.ndarray:
    """Height [m] at (x, y) [m] of the grid whose vertex heights are ``vertices[start:start + nrow * ncol]``
    (row-major, rows along y) with column 0 at ``x0``, row 0 at ``y0`` and spacings ``dx``, ``dy`` [m], on
    MuJoCo's triangles; NaN outside the grid. The grid's parameters broadcast against x and y, so one call
    reads one grid (scalars) or a stack of them (columns of shape (N, 1) against points of shape (N, P))."""
    u = (x - x0) / dx
    v = (y - y0) / dy
    c = np.clip(np.floor(u), 0, ncol - 2).astype(np.intp)
    r = np.clip(np.floor(v), 0, nrow - 2).astype(np.intp)
    fu = u - c
    fv = v - r
    corner = start + r * ncol + c
    z00, z10 = vertices[corner], vertices[corner + 1]
    z01, z11 = vertices[corner + ncol], vertices[corner + ncol + 1]
    lower = fu >= fv  # triangle (00, 10, 11)
    z = np.where(
        lower,
        z00 + fu * (z10 - z00) + fv * (z11 - z10),
        z00 + fu * (z11 - z01) + fv * (z01 - z00),
    )
    x1 = x0 + (ncol - 1) * dx
    y1 = y0 + (nrow - 1) * dy
    inside = (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)
    return np.where(inside, z, np.nan)


def triangle_gradients(h: np.ndarray, dx: float, dy: float) -> np.ndarray:
    """Gradient magnitude of both triangles of every cell [-] of vertex heights ``h`` [m], shape (nrow, ncol),
    at column and row spacings ``dx``, ``dy`` [m]. Shape: (2, nrow - 1, ncol - 1)."""
    z00, z10, z01, z11 = h[:-1, :-1], h[:-1, 1:], h[1:, :-1], h[1:, 1:]
    lower = np.hypot((z10 - z00) / dx, (z11 - z10) / dy)
    upper = np.hypot((z11 - z01) / dx, (z01 - z00) / dy)
    return np.stack([lower, upper])
