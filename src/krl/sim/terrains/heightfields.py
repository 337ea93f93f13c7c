"""The height-field terrains: the random height field, Perlin hills and the sinusoid.

Each builder makes the vertex heights on a square grid centred on the origin (:func:`grid_axis`), adds them
as one MuJoCo height field named ``terrain`` and puts a floor plane just below its lowest vertex, which
continues the ground beyond the field. The random draws, in order, are documented per builder and in
``docs/terrains.md``.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import mujoco
import numpy as np

from krl.sim.terrains.geoms import add_floor, add_geom
from krl.sim.terrains.grid import HeightGrid, grid_axis, triangle_gradients
from krl.sim.terrains.params import (
    HeightfieldParams,
    PerlinParams,
    PitsParams,
    SinusoidParams,
    SlopeParams,
    sinusoid_half_size,
)
from krl.sim.terrains.surface import GridSurface
from krl.sim.terrains.terrain import Terrain
from krl.sim.terrains.tiles import StepTiles

__all__ = [
    "build_heightfield",
    "build_perlin",
    "build_pits",
    "build_sinusoid",
    "build_slope",
    "sinusoid_amplitude",
]

_FLOOR_BELOW_HFIELD: float = 0.001
"""The floor plane of height-field terrains lies this far below the field's lowest vertex [m], so the two
surfaces never coincide (no duplicate contacts, no z-fighting in renders)."""

_HFIELD_BASE: float = 0.1
"""Depth of the solid base MuJoCo puts under a height field [m]."""


def _add_hfield(spec: mujoco.MjSpec, axis: np.ndarray, heights: np.ndarray) -> HeightGrid:
    """Add a height field (square, centred on the origin) and its geom; returns what MuJoCo will hold.

    ``axis``: vertex coordinates along x and along y [m], shape (n,); ``heights``: world z of every vertex
    [m], shape (n, n), rows along y.
    """
    half = float(axis[-1])
    zmin, zmax = float(heights.min()), float(heights.max())
    span = zmax - zmin
    if span <= 0.0:  # MuJoCo needs a positive elevation range; a constant field is all zeros on it.
        span = 1e-6
    # MuJoCo rescales any elevation data to [0, 1]; giving it [0, 1] data keeps the mapping explicit.
    normalised = (heights - zmin) / span
    hfield = spec.add_hfield()
    hfield.name = "terrain"
    hfield.nrow, hfield.ncol = heights.shape
    hfield.size = [half, half, span, _HFIELD_BASE]
    hfield.userdata = normalised.astype(np.float32).ravel().tolist()
    add_geom(
        spec.worldbody,
        "terrain",
        mujoco.mjtGeom.mjGEOM_HFIELD,
        "krl_ground",
        hfieldname="terrain",
        pos=[0.0, 0.0, zmin],
    )
    # What MuJoCo will hold, in world z (float32 rounding included, so height() matches ray casts).
    stored = zmin + normalised.astype(np.float32).astype(float) * span
    step = float(axis[1] - axis[0])
    return HeightGrid(x0=-half, y0=-half, dx=step, dy=step, heights=stored)


def _grid_terrain(
    spec: mujoco.MjSpec,
    name: str,
    params: Any,
    axis: np.ndarray,
    heights: np.ndarray,
    spawn_xy: tuple[float, float] = (0.0, 0.0),
) -> Terrain:
    """Add the height field (as :func:`_add_hfield`) and the floor under it; the :class:`Terrain` with the
    resolved ``params`` (a parameter dataclass) and ``spawn_xy`` [m]."""
    grid = _add_hfield(spec, axis, heights)
    floor_z = float(grid.heights.min()) - _FLOOR_BELOW_HFIELD
    floor = add_floor(spec, floor_z)

    surface = GridSurface(grid, floor_z)
    return Terrain(
        name=name,
        params=dataclasses.asdict(params),
        spawn_xy=spawn_xy,
        geom_names=("terrain", floor),
        landmarks={"field_min": (grid.x0, grid.y0), "field_max": (-grid.x0, -grid.y0)},
        grid=grid,
        _height_fn=surface.height,
        surface=surface,
    )


def build_heightfield(
    spec: mujoco.MjSpec, name: str, p: HeightfieldParams, rng: np.random.Generator
) -> Terrain:
    """Add the random height field: blocks of ``p.block`` × ``p.block`` vertices of height U(0, h) [m],
    level at h / 2 around the spawn point."""
    # Draw order (fixed, for reproducibility): h ~ U(low, high), always drawn so the block pattern below
    # does not depend on whether max_height was given; then one U(0, 1) per block, row-major, scaled by h.
    drawn_h = rng.uniform(p.max_height_low, p.max_height_high)
    h = drawn_h if p.max_height is None else p.max_height
    axis = grid_axis(p.half_size, p.cell)
    n = axis.size
    nblock = -(-n // p.block)
    blocks = h * rng.random((nblock, nblock))
    heights = np.repeat(np.repeat(blocks, p.block, axis=0), p.block, axis=1)[:n, :n]
    x, y = np.meshgrid(axis, axis)
    heights[np.hypot(x, y) <= p.spawn_radius] = 0.5 * h
    return _grid_terrain(spec, name, dataclasses.replace(p, max_height=float(h)), axis, heights)


def _gradient_noise(x: np.ndarray, y: np.ndarray, period: float, rng: np.random.Generator) -> np.ndarray:
    """One octave of 2-D Perlin gradient noise on a lattice of the given period [m], range about ±0.7.

    Draws (in order): the lattice offset U(0, period)² and one gradient angle U(0, 2π) per lattice point.
    """
    offset = rng.uniform(0.0, period, size=2)
    gx = (x + offset[0]) / period
    gy = (y + offset[1]) / period
    ix = np.floor(gx).astype(np.intp)
    iy = np.floor(gy).astype(np.intp)
    i0, j0 = int(ix.min()), int(iy.min())
    ni, nj = int(ix.max()) - i0 + 2, int(iy.max()) - j0 + 2
    angles = rng.uniform(0.0, 2.0 * np.pi, size=(nj, ni))
    gxs, gys = np.cos(angles), np.sin(angles)
    fx, fy = gx - ix, gy - iy
    i, j = ix - i0, iy - j0

    def corner(di: int, dj: int) -> np.ndarray:
        return gxs[j + dj, i + di] * (fx - di) + gys[j + dj, i + di] * (fy - dj)

    def fade(t: np.ndarray) -> np.ndarray:
        return t * t * t * (t * (t * 6.0 - 15.0) + 10.0)

    u, v = fade(fx), fade(fy)
    bottom = corner(0, 0) * (1 - u) + corner(1, 0) * u
    top = corner(0, 1) * (1 - u) + corner(1, 1) * u
    return bottom * (1 - v) + top * v


def build_perlin(spec: mujoco.MjSpec, name: str, p: PerlinParams, rng: np.random.Generator) -> Terrain:
    """Add the Perlin hills: fractal gradient noise scaled to ``p.amplitude`` [m], a level spawn patch, and
    the relief lowered if any triangle is steeper than ``p.max_slope`` [rad]."""
    axis = grid_axis(p.half_size, p.cell)
    x, y = np.meshgrid(axis, axis)
    noise = np.zeros_like(x)
    for octave in range(p.octaves):
        period = p.scale / p.lacunarity**octave
        noise += p.persistence**octave * _gradient_noise(x, y, period, rng)
    span = float(noise.max() - noise.min())
    heights = p.amplitude * (noise - noise.min()) / span  # in [0, amplitude]
    # Level spawn patch: flat at the height of the vertex nearest the spawn point inside spawn_radius,
    # blending back to the noise with a smoothstep between spawn_radius and blend_radius.
    r = np.hypot(x, y)
    centre = heights.flat[int(np.argmin(r))]
    if p.blend_radius > p.spawn_radius:
        t = np.clip((r - p.spawn_radius) / (p.blend_radius - p.spawn_radius), 0.0, 1.0)
    else:
        t = (r > p.spawn_radius).astype(float)
    weight = t * t * (3.0 - 2.0 * t)
    heights = centre + weight * (heights - centre)
    # Keep every triangle walkable: scale the relief (about the field's minimum) if it is too steep.
    step = float(axis[1] - axis[0])
    steepest = float(triangle_gradients(heights, step, step).max())
    amplitude = p.amplitude
    if steepest > math.tan(p.max_slope):
        factor = math.tan(p.max_slope) / steepest
        heights = heights.min() + factor * (heights - heights.min())
        amplitude *= factor
    return _grid_terrain(spec, name, dataclasses.replace(p, amplitude=amplitude), axis, heights)


def sinusoid_amplitude(max_incline: float, wavelength: float) -> float:
    """A of z = A sin(kx) sin(ky), k = 2π/λ, whose steepest slope is max_incline [m].

    |∇z|² = A²k²(cos²kx sin²ky + sin²kx cos²ky) peaks at A²k² (e.g. x = 0, y = λ/4), so A = tan(θ)/k.
    """
    return math.tan(max_incline) * wavelength / (2.0 * math.pi)


def build_sinusoid(spec: mujoco.MjSpec, name: str, p: SinusoidParams, rng: np.random.Generator) -> Terrain:
    """Add the sinusoid z = A sin(kx) sin(ky) [m] (no random draws), with ``crest`` and ``trough``
    landmarks."""
    half = sinusoid_half_size(p.half_size, p.wavelength)
    axis = grid_axis(half, p.cell)
    k = 2.0 * math.pi / p.wavelength
    amplitude = sinusoid_amplitude(p.max_incline, p.wavelength)
    sx = np.sin(k * axis)
    heights = amplitude * np.outer(sx, sx)  # rows: y, columns: x (symmetric anyway)
    terrain = _grid_terrain(spec, name, dataclasses.replace(p, half_size=half), axis, heights)
    landmarks = dict(terrain.landmarks)
    landmarks.update(
        {"crest": (p.wavelength / 4, p.wavelength / 4), "trough": (-p.wavelength / 4, p.wavelength / 4)}
    )
    return dataclasses.replace(terrain, landmarks=landmarks)


def build_slope(spec: mujoco.MjSpec, name: str, p: SlopeParams, rng: np.random.Generator) -> Terrain:
    """Add the slope (no random draws): z rises at tan(incline) from ``start_x`` for ``run`` metres, stays
    level for ``plateau`` metres and falls back as steeply, the same at every y; landmarks ``ramp_up``,
    ``plateau`` and ``ramp_down`` (the middle of each, (x, y) [m])."""
    axis = grid_axis(p.half_size, p.cell)
    rise = math.tan(p.incline)
    top = p.start_x + p.run + p.plateau
    profile = rise * np.clip(np.minimum(axis - p.start_x, top + p.run - axis), 0.0, p.run)
    heights = np.tile(profile, (len(axis), 1))  # rows: y, columns: x
    terrain = _grid_terrain(spec, name, p, axis, heights)
    landmarks = dict(terrain.landmarks)
    landmarks.update(
        {
            "ramp_up": (p.start_x + p.run / 2, 0.0),
            "plateau": (p.start_x + p.run + p.plateau / 2, 0.0),
            "ramp_down": (top + p.run / 2, 0.0),
        }
    )
    return dataclasses.replace(terrain, landmarks=landmarks)


def build_pits(spec: mujoco.MjSpec, name: str, p: PitsParams, rng: np.random.Generator) -> Terrain:
    """Add the field of stepped pits: the pyramids' tiles (:class:`krl.sim.terrains.tiles.StepTiles`, the
    same draws) with every level going down instead of up, as one height field at ``p.cell``; the lanes and
    the spawn point (a crossing of lanes at the origin) at z = 0."""
    tiles = StepTiles.draw(p, rng)
    axis = grid_axis(tiles.half, p.cell)
    x, y = np.meshgrid(axis, axis)
    return _grid_terrain(spec, name, dataclasses.replace(p, half_size=tiles.half), axis, -tiles.height(x, y))
