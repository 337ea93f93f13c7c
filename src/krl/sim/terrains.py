"""Terrains: the ground the A1 walks on, added to an ``MjSpec`` that already holds the robot.

Every terrain is built by :func:`add_terrain` from a name in :data:`TERRAIN_NAMES`, a mapping of parameter
overrides and a ``numpy.random.Generator``. Each terrain has one frozen parameter dataclass (below) whose
fields carry the defaults and units; ``docs/terrains.md`` describes the layouts, the distributions of the
random draws and the reasons for every choice the thesis leaves open.

World conventions: z up, ground at z = 0 for the flat-floored terrains, the robot starts at
:attr:`Terrain.spawn_xy` facing +x (:attr:`Terrain.spawn_yaw` = 0). Every terrain geom has ``contype=0,
conaffinity=1`` (it collides with the robot, whose geoms have ``contype=1, conaffinity=0``, and with nothing
else), ``condim=3`` and sliding friction :data:`krl.robots.a1.constants.FOOT_FRICTION`.

Height fields follow MuJoCo's convention: ``data[r, c]`` is the vertex at ``x = x0 + c * dx``,
``y = y0 + r * dy`` (rows along y) and each grid cell is split into the two triangles on either side of its
``(r, c) - (r + 1, c + 1)`` diagonal; :meth:`Terrain.height` interpolates exactly the same triangles.

One module on purpose (over 600 lines): every terrain is a parameter dataclass plus a builder, and the
builders share one registry (parameter resolution and checks), one scene (textures, materials, lights)
and private geometry helpers (floors, height-field grids); split per terrain, those helpers would become
an API that nothing outside the terrains uses.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

from krl.robots.a1.constants import FOOT_FRICTION

__all__ = [
    "MAX_HFIELD_SIDE",
    "TERRAIN_NAMES",
    "FlatParams",
    "HeightGrid",
    "HeightfieldParams",
    "PerlinParams",
    "SeesawParams",
    "SinusoidParams",
    "StairsParams",
    "TabletopParams",
    "Terrain",
    "TerrainError",
    "add_terrain",
    "sinusoid_amplitude",
    "terrain_param_defaults",
]

TERRAIN_NAMES: tuple[str, ...] = (
    "flat",
    "heightfield",
    "heightfield_mild",
    "perlin",
    "sinusoid",
    "stairs",
    "tabletop",
    "seesaw",
)
"""Names accepted by :func:`add_terrain`."""

MAX_HFIELD_SIDE: int = 1024
"""Largest number of height-field vertices along one side (cost guard: compile time and memory)."""

TERRAIN_FRICTION: np.ndarray = np.array([FOOT_FRICTION, 0.005, 0.0001])
"""Sliding, torsional and rolling friction of every terrain geom (sliding as thesis 4.2.1; the other two
are MuJoCo's defaults, as on the robot's feet)."""

_FLOOR_BELOW_HFIELD: float = 0.001
"""The floor plane of height-field terrains lies this far below the field's lowest vertex [m], so the two
surfaces never coincide (no duplicate contacts, no z-fighting in renders)."""

_HFIELD_BASE: float = 0.1
"""Depth of the solid base MuJoCo puts under a height field [m]."""


class TerrainError(ValueError):
    """An unknown terrain name or an invalid terrain parameter (the message names both)."""


# --- parameter dataclasses ------------------------------------------------------------------------
#
# Each field's metadata gives its bounds (gt/ge/lt/le) used by the validation in ``_resolve_params``;
# the kind (int, float, float-or-None) is taken from the default.


def _p(default: float | int | None, *, gt=None, ge=None, lt=None, le=None, optional: bool = False) -> Any:
    kind = "int" if isinstance(default, int) and not isinstance(default, bool) else "float"
    return field(
        default=default,
        metadata={"gt": gt, "ge": ge, "lt": lt, "le": le, "kind": kind, "optional": optional},
    )


@dataclass(frozen=True)
class FlatParams:
    """Flat ground: an infinite plane at z = 0. No parameters."""

    def _problem(self) -> str | None:
        return None


@dataclass(frozen=True)
class HeightfieldParams:
    """PyBullet-style random height field (thesis 4.2.1 and 4.2.9, Fig. 4.2b-c)."""

    max_height: float | None = _p(None, gt=0.0, le=1.0, optional=True)
    """Upper bound h of the per-block height draw U(0, h) [m]. ``None``: h is itself drawn
    U(max_height_low, max_height_high) (thesis 4.2.9: U(3, 4.5) cm)."""
    max_height_low: float = _p(0.03, gt=0.0, le=1.0)
    """Lower end of the draw of h when ``max_height`` is None [m]."""
    max_height_high: float = _p(0.045, gt=0.0, le=1.0)
    """Upper end of the draw of h when ``max_height`` is None [m]."""
    cell: float = _p(0.05, gt=0.0, le=1.0)
    """Vertex spacing of the height field [m] (PyBullet example: 0.05)."""
    block: int = _p(2, ge=1, le=64)
    """Side of the square blocks of vertices that share one height [vertices] (PyBullet example: 2)."""
    half_size: float = _p(12.0, gt=0.0, le=100.0)
    """The field covers [-half_size, half_size]² around the origin [m]."""
    spawn_radius: float = _p(0.5, ge=0.0, le=5.0)
    """Vertices within this distance of the spawn point are set to h / 2 (a level start) [m]."""

    def _problem(self) -> str | None:
        if self.max_height_high < self.max_height_low:
            return (
                f"parameter 'max_height_high' = {self.max_height_high} must be >= "
                f"'max_height_low' = {self.max_height_low}"
            )
        return _grid_problem(self.half_size, self.cell)


@dataclass(frozen=True)
class PerlinParams:
    """Hills and mounds from fractal gradient (Perlin) noise (thesis 4.2.9, Fig. 4.2d)."""

    amplitude: float = _p(0.25, gt=0.0, le=5.0)
    """Peak-to-peak height of the noise over the whole field [m] (reduced if needed to respect
    ``max_slope``; the resolved value is what was built)."""
    scale: float = _p(3.0, gt=0.0, le=100.0)
    """Lattice period of the coarsest octave (about the spacing of the hills) [m]."""
    octaves: int = _p(3, ge=1, le=8)
    """Number of noise octaves summed [-]."""
    persistence: float = _p(0.4, gt=0.0, le=1.0)
    """Amplitude ratio between successive octaves [-]."""
    lacunarity: float = _p(2.0, gt=1.0, le=4.0)
    """Frequency ratio between successive octaves [-]."""
    max_slope: float = _p(0.25, gt=0.0, lt=math.pi / 2)
    """Largest slope angle allowed anywhere on the built surface [rad]; the amplitude is scaled down if the
    drawn noise would exceed it."""
    cell: float = _p(0.05, gt=0.0, le=1.0)
    """Vertex spacing of the height field [m]."""
    half_size: float = _p(12.0, gt=0.0, le=100.0)
    """The field covers [-half_size, half_size]² around the origin [m]."""
    spawn_radius: float = _p(0.5, ge=0.0, le=5.0)
    """Radius of the level patch around the spawn point [m]."""
    blend_radius: float = _p(2.0, ge=0.0, le=10.0)
    """Radius at which the terrain has fully returned from the spawn patch to the noise [m]."""

    def _problem(self) -> str | None:
        if self.blend_radius < self.spawn_radius:
            return (
                f"parameter 'blend_radius' = {self.blend_radius} must be >= "
                f"'spawn_radius' = {self.spawn_radius}"
            )
        return _grid_problem(self.half_size, self.cell)


@dataclass(frozen=True)
class SinusoidParams:
    """Sinusoidal terrain z = A sin(2πx/λ) sin(2πy/λ) (thesis 5.1, Fig. 5.1d)."""

    max_incline: float = _p(0.2, gt=0.0, lt=math.pi / 2)
    """Largest slope angle of the surface [rad] (thesis: 0.2); sets A = tan(max_incline) λ / (2π)."""
    wavelength: float = _p(2.5, gt=0.0, le=100.0)
    """Wavelength λ along x and along y [m]."""
    cell: float = _p(0.05, gt=0.0, le=1.0)
    """Nominal vertex spacing of the height field [m] (adjusted so the field ends on whole vertices)."""
    half_size: float = _p(12.0, gt=0.0, le=100.0)
    """Minimum half extent of the field [m]; rounded up to a multiple of λ / 2 so the border is at z = 0."""

    def _problem(self) -> str | None:
        half = _sinusoid_half_size(self.half_size, self.wavelength)
        return _grid_problem(half, self.cell)


@dataclass(frozen=True)
class StairsParams:
    """A straight flight up, a landing and a flight down, built from boxes (thesis 5.1, Fig. 5.1c)."""

    step_height: float = _p(0.04, gt=0.0, le=0.5)
    """Riser height [m] (thesis: 4 cm)."""
    step_depth: float = _p(0.3, gt=0.0, le=5.0)
    """Tread depth along x [m]."""
    num_steps: int = _p(5, ge=1, le=50)
    """Risers going up (and the same number going down) [-]; the landing is at num_steps · step_height."""
    landing_depth: float = _p(1.5, gt=0.0, le=20.0)
    """Length of the top landing along x [m]."""
    width: float = _p(3.0, gt=0.0, le=20.0)
    """Width of the stairs along y, centred on y = 0 [m]."""
    start_x: float = _p(1.0, gt=0.0, le=20.0)
    """Distance from the spawn point (the origin) to the first riser along +x [m]."""

    def _problem(self) -> str | None:
        return None


@dataclass(frozen=True)
class TabletopParams:
    """A square plate balanced on a ball joint at its centre (thesis 5.1, Fig. 5.1b)."""

    size: float = _p(4.0, gt=0.0, le=20.0)
    """Side of the square plate [m] (the thesis gives none: 4 m keeps the paths its course's commands lead
    along at least 0.5 m inside the edges, ``docs/evaluation.md``)."""
    thickness: float = _p(0.04, gt=0.0, le=1.0)
    """Plate thickness [m]."""
    height: float = _p(0.3, gt=0.0, le=5.0)
    """Height of the plate's top surface above the floor at rest (level) [m]; the lowest that keeps a 4 m
    plate's corners off the floor at 0.087 rad."""
    max_tilt: float = _p(0.087, gt=0.0, lt=math.pi / 2)
    """Largest rotation of the plate about its pivot (ball-joint cone limit) [rad] (thesis: 0.087)."""
    mass: float = _p(5.0, gt=0.0, le=1000.0)
    """Plate mass [kg] (uniform box, centre of mass at the pivot)."""
    damping: float = _p(100.0, ge=0.0, le=1e5)
    """Viscous damping of the pivot, each rotational axis [N·m·s/rad]."""

    def _problem(self) -> str | None:
        clearance = _tabletop_clearance(self)
        if clearance < 0.0:
            return (
                f"parameter 'height' = {self.height} is too low: a plate corner would go "
                f"{-clearance:.3f} m into the floor at max_tilt = {self.max_tilt}"
            )
        return None


@dataclass(frozen=True)
class SeesawParams:
    """A plank on a hinge about y at its centre, resting on its limit with the -x end down (thesis 5.1,
    Fig. 5.1a)."""

    length: float = _p(4.0, gt=0.0, le=20.0)
    """Plank length along x [m]."""
    width: float = _p(1.2, gt=0.0, le=10.0)
    """Plank width along y [m]."""
    thickness: float = _p(0.04, gt=0.0, le=1.0)
    """Plank thickness [m]."""
    max_tilt: float = _p(0.1, gt=0.0, lt=math.pi / 2)
    """Hinge range ±max_tilt [rad] (thesis: incline/decline 0.1)."""
    clearance: float = _p(0.005, ge=0.0, le=1.0)
    """Gap between the low end's bottom edge and the floor at full tilt [m]; sets the pivot height."""
    mass: float = _p(5.0, gt=0.0, le=1000.0)
    """Plank mass [kg] (uniform box, centre of mass on the hinge axis)."""
    damping: float = _p(100.0, ge=0.0, le=1e5)
    """Viscous damping of the hinge [N·m·s/rad]."""
    approach: float = _p(0.7, ge=0.0, le=20.0)
    """Distance from the spawn point to the low end of the plank along x [m]."""

    def _problem(self) -> str | None:
        return None


def _grid_problem(half_size: float, cell: float) -> str | None:
    n = _grid_count(half_size, cell)
    if n > MAX_HFIELD_SIDE:
        return (
            f"parameters 'half_size' = {half_size} and 'cell' = {cell} give {n} height-field vertices "
            f"per side (max {MAX_HFIELD_SIDE})"
        )
    return None


# --- the built terrain ----------------------------------------------------------------------------


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
        """Whether (x, y) lies over the field (boundary included)."""
        return (x >= self.x0) & (x <= self.x1) & (y >= self.y0) & (y <= self.y1)

    def height(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Surface height at (x, y) as MuJoCo triangulates it [m]; NaN outside the field."""
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
        return np.arctan(_triangle_gradients(self.heights, self.dx, self.dy))

    def max_slope(self) -> float:
        """Steepest triangle of the surface [rad]."""
        return float(np.arctan(_triangle_gradients(self.heights, self.dx, self.dy).max()))


def _triangle_gradients(h: np.ndarray, dx: float, dy: float) -> np.ndarray:
    """Gradient magnitude of both triangles of every cell [-]. Shape: (2, nrow - 1, ncol - 1)."""
    z00, z10, z01, z11 = h[:-1, :-1], h[:-1, 1:], h[1:, :-1], h[1:, 1:]
    lower = np.hypot((z10 - z00) / dx, (z11 - z10) / dy)
    upper = np.hypot((z11 - z01) / dx, (z01 - z00) / dy)
    return np.stack([lower, upper])


@dataclass(frozen=True, eq=False)
class Terrain:
    """A terrain added to a spec by :func:`add_terrain`: what was built and where things are."""

    name: str
    """One of :data:`TERRAIN_NAMES`."""
    params: dict[str, float | int]
    """Fully resolved parameters (defaults filled in, random draws made): passing them back to
    :func:`add_terrain` with an rng of the same seed rebuilds the same terrain."""
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

    def height(self, x: Any, y: Any) -> np.ndarray:
        """Height of the terrain surface at rest at world (x, y) [m], vectorised (x and y broadcast).

        For props (table-top, seesaw) this is the surface in its initial pose (level plate, seesaw on its
        limit); it does not follow the prop once it moves.
        """
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        assert self._height_fn is not None
        return self._height_fn(x, y)

    @property
    def max_slope(self) -> float | None:
        """Steepest triangle of the height field [rad], or None for terrains without one."""
        return None if self.grid is None else self.grid.max_slope()


# --- public functions -----------------------------------------------------------------------------


def terrain_param_defaults(name: str) -> dict[str, float | int | None]:
    """Default parameters of a terrain (``None`` marks a value drawn at random when not given)."""
    cls, overrides, _ = _registry(name)
    values = {f.name: f.default for f in dataclasses.fields(cls)}
    values.update(overrides)
    return values


def add_terrain(
    spec: mujoco.MjSpec,
    name: str,
    params: Mapping[str, Any] | None = None,
    rng: np.random.Generator | None = None,
) -> Terrain:
    """Add a terrain (geoms, props, textures, lights) to ``spec``, which already holds the robot.

    Args:
        spec: the spec to extend; call at most once per spec.
        name: one of :data:`TERRAIN_NAMES`.
        params: overrides of the terrain's parameter dataclass fields (unknown keys are rejected).
        rng: source of every random draw; ``None`` means ``np.random.default_rng(0)`` (reproducible).

    Returns:
        The :class:`Terrain`, with ``params`` fully resolved.

    Raises:
        TerrainError: unknown name, unknown parameter, out-of-range value, or a spec that already has a
            terrain.
    """
    cls, overrides, builder = _registry(name)
    resolved = _resolve_params(name, cls, overrides, params)
    if rng is None:
        rng = np.random.default_rng(0)
    if spec.material("krl_floor") is not None:
        raise TerrainError(f"terrain {name!r}: this spec already has a terrain (add_terrain called twice)")
    _add_scene(spec)
    return builder(spec, name, resolved, rng)


# --- parameter resolution -------------------------------------------------------------------------


def _registry(name: str) -> tuple[type, dict[str, Any], Callable[..., Terrain]]:
    table: dict[str, tuple[type, dict[str, Any], Callable[..., Terrain]]] = {
        "flat": (FlatParams, {}, _build_flat),
        "heightfield": (HeightfieldParams, {}, _build_heightfield),
        "heightfield_mild": (HeightfieldParams, {"max_height": 0.02}, _build_heightfield),
        "perlin": (PerlinParams, {}, _build_perlin),
        "sinusoid": (SinusoidParams, {}, _build_sinusoid),
        "stairs": (StairsParams, {}, _build_stairs),
        "tabletop": (TabletopParams, {}, _build_tabletop),
        "seesaw": (SeesawParams, {}, _build_seesaw),
    }
    if not isinstance(name, str) or name not in table:
        raise TerrainError(f"unknown terrain {name!r}; valid names: {', '.join(TERRAIN_NAMES)}")
    return table[name]


def _resolve_params(name: str, cls: type, overrides: Mapping[str, Any], params: Mapping[str, Any] | None):
    fields = {f.name: f for f in dataclasses.fields(cls)}
    merged = dict(overrides)
    for key, value in (params or {}).items():
        if key not in fields:
            valid = ", ".join(fields) if fields else "none"
            raise TerrainError(f"terrain {name!r}: unknown parameter {key!r} (valid: {valid})")
        merged[key] = value
    values = {key: _check_value(name, f, merged.get(key, f.default)) for key, f in fields.items()}
    resolved = cls(**values)
    problem = resolved._problem()
    if problem is not None:
        raise TerrainError(f"terrain {name!r}: {problem}")
    return resolved


def _check_value(terrain: str, f: dataclasses.Field, value: Any) -> float | int | None:
    meta = f.metadata
    where = f"terrain {terrain!r}: parameter {f.name!r}"
    if value is None:
        if meta["optional"]:
            return None
        raise TerrainError(f"{where} must be a number, got None")
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TerrainError(f"{where} must be a number, got {value!r}")
    if meta["kind"] == "int":
        if float(value) != int(value):
            raise TerrainError(f"{where} must be an integer, got {value!r}")
        value = int(value)
    else:
        value = float(value)
        if not math.isfinite(value):
            raise TerrainError(f"{where} must be finite, got {value!r}")
    for key, op, ok in (
        ("gt", ">", lambda a, b: a > b),
        ("ge", ">=", lambda a, b: a >= b),
        ("lt", "<", lambda a, b: a < b),
        ("le", "<=", lambda a, b: a <= b),
    ):
        bound = meta[key]
        if bound is not None and not ok(value, bound):
            raise TerrainError(f"{where} = {value!r} must be {op} {bound:g}")
    return value


# --- scene: textures, materials, lights -----------------------------------------------------------


def _add_scene(spec: mujoco.MjSpec) -> None:
    """Skybox, checker textures, materials and lights shared by every terrain."""
    sky = spec.add_texture()
    sky.name = "krl_sky"
    sky.type = mujoco.mjtTexture.mjTEXTURE_SKYBOX
    sky.builtin = mujoco.mjtBuiltin.mjBUILTIN_GRADIENT
    sky.rgb1 = [0.62, 0.76, 0.92]
    sky.rgb2 = [0.1, 0.14, 0.22]
    sky.width = 512
    sky.height = 3072

    def checker(name: str, rgb1: list[float], rgb2: list[float]) -> None:
        tex = spec.add_texture()
        tex.name = name
        tex.type = mujoco.mjtTexture.mjTEXTURE_2D
        tex.builtin = mujoco.mjtBuiltin.mjBUILTIN_CHECKER
        tex.rgb1 = rgb1
        tex.rgb2 = rgb2
        tex.mark = mujoco.mjtMark.mjMARK_EDGE
        tex.markrgb = [0.85, 0.85, 0.85]
        tex.width = 512
        tex.height = 512

    checker("krl_grid", [0.32, 0.36, 0.42], [0.22, 0.26, 0.32])
    checker("krl_grid_warm", [0.55, 0.47, 0.36], [0.45, 0.38, 0.28])

    def material(name: str, texture: str | None, rgba: list[float], repeat: float = 1.0) -> None:
        mat = spec.add_material()
        mat.name = name
        if texture is not None:
            textures = [""] * int(mujoco.mjtTextureRole.mjNTEXROLE)
            textures[int(mujoco.mjtTextureRole.mjTEXROLE_RGB)] = texture
            mat.textures = textures
            mat.texuniform = True
            mat.texrepeat = [repeat, repeat]
        mat.rgba = rgba
        mat.reflectance = 0.0

    # texuniform: texrepeat counts textures per metre; one checker texture is 2 x 2 squares -> 0.5 m squares.
    material("krl_floor", "krl_grid", [1, 1, 1, 1], 1.0)
    material("krl_ground", "krl_grid_warm", [1, 1, 1, 1], 1.0)
    material("krl_steps", "krl_grid", [0.85, 0.9, 1.0, 1], 2.0)
    material("krl_steps_alt", "krl_grid", [0.62, 0.7, 0.85, 1], 2.0)
    material("krl_prop", "krl_grid_warm", [1.0, 0.75, 0.45, 1], 2.0)
    material("krl_support", None, [0.45, 0.45, 0.5, 1])

    spec.visual.headlight.ambient = [0.35, 0.35, 0.35]
    spec.visual.headlight.diffuse = [0.45, 0.45, 0.45]
    spec.visual.headlight.specular = [0.1, 0.1, 0.1]
    spec.visual.global_.offwidth = max(int(spec.visual.global_.offwidth), 1280)
    spec.visual.global_.offheight = max(int(spec.visual.global_.offheight), 960)
    spec.visual.global_.azimuth = 135.0
    spec.visual.global_.elevation = -20.0

    # The sun follows the robot's trunk (position only): a directional light's shadow map covers a region
    # around the light, and a fixed far-away sun gave heavy shadow acne in offscreen (OSMesa) renders.
    trunk = spec.body("trunk")
    sun = (trunk if trunk is not None else spec.worldbody).add_light()
    sun.name = "krl_sun"
    sun.type = mujoco.mjtLightType.mjLIGHT_DIRECTIONAL
    if trunk is not None:
        sun.mode = mujoco.mjtCamLight.mjCAMLIGHT_TRACK
    sun.pos = [0.0, 0.0, 1.5]
    sun.dir = list(np.array([0.3, 0.4, -1.0]) / np.linalg.norm([0.3, 0.4, -1.0]))
    sun.diffuse = [0.6, 0.6, 0.6]
    sun.specular = [0.2, 0.2, 0.2]
    sun.castshadow = True


def _geom(parent, name: str, gtype: mujoco.mjtGeom, material: str, **attrs: Any):
    """A terrain geom: collides with the robot only, friction FOOT_FRICTION, condim 3."""
    geom = parent.add_geom()
    geom.name = name
    geom.type = gtype
    geom.contype = 0
    geom.conaffinity = 1
    geom.condim = 3
    geom.friction = TERRAIN_FRICTION.copy()
    geom.material = material
    for key, value in attrs.items():
        setattr(geom, key, value)
    return geom


def _angle(spec: mujoco.MjSpec, radians: float) -> float:
    """An angle in the spec's unit (``compiler.degree``; MjSpec() defaults to degrees, the A1 MJCF uses
    radians)."""
    return math.degrees(radians) if spec.compiler.degree else radians


def _floor(spec: mujoco.MjSpec, z: float = 0.0, material: str = "krl_floor") -> str:
    _geom(spec.worldbody, "floor", mujoco.mjtGeom.mjGEOM_PLANE, material, pos=[0.0, 0.0, z], size=[0, 0, 1])
    return "floor"


# --- flat -----------------------------------------------------------------------------------------


def _build_flat(spec: mujoco.MjSpec, name: str, p: FlatParams, rng: np.random.Generator) -> Terrain:
    floor = _floor(spec)
    return Terrain(
        name=name,
        params={},
        spawn_xy=(0.0, 0.0),
        geom_names=(floor,),
        _height_fn=lambda x, y: np.zeros(np.shape(x)),
    )


# --- height fields --------------------------------------------------------------------------------


def _grid_count(half_size: float, cell: float) -> int:
    return round(2.0 * half_size / cell) + 1


def _grid_axis(half_size: float, cell: float) -> np.ndarray:
    """Vertex coordinates along one axis, from -half_size to half_size, spacing as close to cell as fits."""
    return np.linspace(-half_size, half_size, _grid_count(half_size, cell))


def _add_hfield(spec: mujoco.MjSpec, axis: np.ndarray, heights: np.ndarray) -> HeightGrid:
    """Add a height field (square, centred on the origin) and a floor plane just below its lowest point."""
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
    _geom(
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
    grid = _add_hfield(spec, axis, heights)
    floor_z = float(grid.heights.min()) - _FLOOR_BELOW_HFIELD
    floor = _floor(spec, floor_z)

    def height(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        z = grid.height(x, y)
        return np.where(np.isnan(z), floor_z, z)

    return Terrain(
        name=name,
        params=dataclasses.asdict(params),
        spawn_xy=spawn_xy,
        geom_names=("terrain", floor),
        landmarks={"field_min": (grid.x0, grid.y0), "field_max": (-grid.x0, -grid.y0)},
        grid=grid,
        _height_fn=height,
    )


def _build_heightfield(
    spec: mujoco.MjSpec, name: str, p: HeightfieldParams, rng: np.random.Generator
) -> Terrain:
    # Draw order (fixed, for reproducibility): h ~ U(low, high), always drawn so the block pattern below
    # does not depend on whether max_height was given; then one U(0, 1) per block, row-major, scaled by h.
    drawn_h = rng.uniform(p.max_height_low, p.max_height_high)
    h = drawn_h if p.max_height is None else p.max_height
    axis = _grid_axis(p.half_size, p.cell)
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


def _build_perlin(spec: mujoco.MjSpec, name: str, p: PerlinParams, rng: np.random.Generator) -> Terrain:
    axis = _grid_axis(p.half_size, p.cell)
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
    steepest = float(_triangle_gradients(heights, step, step).max())
    amplitude = p.amplitude
    if steepest > math.tan(p.max_slope):
        factor = math.tan(p.max_slope) / steepest
        heights = heights.min() + factor * (heights - heights.min())
        amplitude *= factor
    return _grid_terrain(spec, name, dataclasses.replace(p, amplitude=amplitude), axis, heights)


def _sinusoid_half_size(half_size: float, wavelength: float) -> float:
    half_wave = 0.5 * wavelength
    return math.ceil(half_size / half_wave - 1e-9) * half_wave


def sinusoid_amplitude(max_incline: float, wavelength: float) -> float:
    """A of z = A sin(kx) sin(ky), k = 2π/λ, whose steepest slope is max_incline [m].

    |∇z|² = A²k²(cos²kx sin²ky + sin²kx cos²ky) peaks at A²k² (e.g. x = 0, y = λ/4), so A = tan(θ)/k.
    """
    return math.tan(max_incline) * wavelength / (2.0 * math.pi)


def _build_sinusoid(spec: mujoco.MjSpec, name: str, p: SinusoidParams, rng: np.random.Generator) -> Terrain:
    half = _sinusoid_half_size(p.half_size, p.wavelength)
    axis = _grid_axis(half, p.cell)
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


# --- stairs ---------------------------------------------------------------------------------------


def _build_stairs(spec: mujoco.MjSpec, name: str, p: StairsParams, rng: np.random.Generator) -> Terrain:
    floor = _floor(spec)
    n = p.num_steps
    half_w = 0.5 * p.width
    # Blocks (x_start, x_end, top): n - 1 treads up, the landing, n - 1 treads down.
    blocks: list[tuple[str, float, float, float]] = []
    x = p.start_x
    for i in range(1, n):
        blocks.append((f"stairs_up_{i}", x, x + p.step_depth, i * p.step_height))
        x += p.step_depth
    blocks.append(("stairs_landing", x, x + p.landing_depth, n * p.step_height))
    x += p.landing_depth
    for i in range(n - 1, 0, -1):
        blocks.append((f"stairs_down_{n - i}", x, x + p.step_depth, i * p.step_height))
        x += p.step_depth
    end_x = x
    blocks = [(g, round(x0, 12), round(x1, 12), top) for g, x0, x1, top in blocks]
    end_x = round(end_x, 12)
    names = [floor]
    for i, (gname, x0, x1, top) in enumerate(blocks):
        _geom(
            spec.worldbody,
            gname,
            mujoco.mjtGeom.mjGEOM_BOX,
            "krl_steps" if i % 2 == 0 else "krl_steps_alt",
            pos=[0.5 * (x0 + x1), 0.0, 0.5 * top],
            size=[0.5 * (x1 - x0), half_w, 0.5 * top],
        )
        names.append(gname)
    edges = np.array([b[1] for b in blocks] + [end_x])
    tops = np.array([0.0] + [b[3] for b in blocks] + [0.0])

    def height(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        z = tops[np.searchsorted(edges, x, side="right")]
        return np.where(np.abs(y) <= half_w, z, 0.0)

    _, landing_x0, landing_x1, _ = blocks[n - 1]
    return Terrain(
        name=name,
        params=dataclasses.asdict(p),
        spawn_xy=(0.0, 0.0),
        geom_names=tuple(names),
        landmarks={
            "first_riser": (p.start_x, 0.0),
            "landing_start": (landing_x0, 0.0),
            "landing_centre": (0.5 * (landing_x0 + landing_x1), 0.0),
            "landing_end": (landing_x1, 0.0),
            "stairs_end": (end_x, 0.0),
        },
        _height_fn=height,
    )


# --- props ----------------------------------------------------------------------------------------


def _tabletop_clearance(p: TabletopParams) -> float:
    """Lowest point of the plate above the floor at full tilt [m] (a corner, tilted about the axis
    perpendicular to its diagonal)."""
    centre_z = p.height - 0.5 * p.thickness
    half_diag = p.size / math.sqrt(2.0)
    return centre_z - half_diag * math.sin(p.max_tilt) - 0.5 * p.thickness * math.cos(p.max_tilt)


def _build_tabletop(spec: mujoco.MjSpec, name: str, p: TabletopParams, rng: np.random.Generator) -> Terrain:
    floor = _floor(spec)
    centre_z = p.height - 0.5 * p.thickness
    # A post under the pivot, only for the eye (it sits below the plate and cannot touch it).
    post_top = centre_z - 0.5 * p.thickness - 0.01
    _geom(
        spec.worldbody,
        "tabletop_post",
        mujoco.mjtGeom.mjGEOM_CYLINDER,
        "krl_support",
        pos=[0.0, 0.0, 0.5 * post_top],
        size=[0.06, 0.5 * post_top, 0],
    )
    body = spec.worldbody.add_body()
    body.name = "tabletop"
    body.pos = [0.0, 0.0, centre_z]
    joint = body.add_joint()
    joint.name = "tabletop_pivot"
    joint.type = mujoco.mjtJoint.mjJNT_BALL
    joint.limited = mujoco.mjtLimited.mjLIMITED_TRUE
    joint.range = [0.0, _angle(spec, p.max_tilt)]
    joint.damping = [p.damping, 0.0, 0.0]
    half = 0.5 * p.size
    _geom(
        body,
        "tabletop_plate",
        mujoco.mjtGeom.mjGEOM_BOX,
        "krl_prop",
        size=[half, half, 0.5 * p.thickness],
        mass=p.mass,
    )

    def height(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        on = (np.abs(x) <= half) & (np.abs(y) <= half)
        return np.where(on, p.height, 0.0)

    return Terrain(
        name=name,
        params=dataclasses.asdict(p),
        spawn_xy=(0.0, 0.0),
        moving_joints=("tabletop_pivot",),
        geom_names=(floor, "tabletop_post", "tabletop_plate"),
        landmarks={"pivot": (0.0, 0.0), "corner_min": (-half, -half), "corner_max": (half, half)},
        _height_fn=height,
    )


def _build_seesaw(spec: mujoco.MjSpec, name: str, p: SeesawParams, rng: np.random.Generator) -> Terrain:
    floor = _floor(spec)
    half_l, half_w, half_t = 0.5 * p.length, 0.5 * p.width, 0.5 * p.thickness
    sin_t, cos_t = math.sin(p.max_tilt), math.cos(p.max_tilt)
    pivot_z = half_l * sin_t + half_t * cos_t + p.clearance
    # A support under the hinge, only for the eye; its top stays clear of the plank at any tilt.
    support_top = pivot_z - half_t - 0.05 * sin_t - 0.005
    _geom(
        spec.worldbody,
        "seesaw_support",
        mujoco.mjtGeom.mjGEOM_BOX,
        "krl_support",
        pos=[0.0, 0.0, 0.5 * support_top],
        size=[0.05, half_w, 0.5 * support_top],
    )
    # The rest pose (joint value -max_tilt: -x end down) is the body's pose in the model; ref makes qpos0
    # equal -max_tilt so the joint value reads the absolute tilt (positive: +x end down).
    rest = -p.max_tilt
    body = spec.worldbody.add_body()
    body.name = "seesaw"
    body.pos = [0.0, 0.0, pivot_z]
    body.quat = [math.cos(0.5 * rest), 0.0, math.sin(0.5 * rest), 0.0]
    joint = body.add_joint()
    joint.name = "seesaw_pivot"
    joint.type = mujoco.mjtJoint.mjJNT_HINGE
    joint.axis = [0.0, 1.0, 0.0]
    joint.ref = _angle(spec, rest)
    joint.limited = mujoco.mjtLimited.mjLIMITED_TRUE
    joint.range = [_angle(spec, -p.max_tilt), _angle(spec, p.max_tilt)]
    joint.damping = [p.damping, 0.0, 0.0]
    _geom(
        body,
        "seesaw_plank",
        mujoco.mjtGeom.mjGEOM_BOX,
        "krl_prop",
        size=[half_l, half_w, half_t],
        mass=p.mass,
    )
    low_end_x = -(half_l * cos_t + half_t * sin_t)  # top edge of the low end
    high_end_x = half_l * cos_t - half_t * sin_t  # top edge of the high end

    def height(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        # Top surface in the rest pose: plank point (u, ±, half_t) -> x = u cos - half_t sin, z = pivot_z
        # + u sin + half_t cos (rotation by -max_tilt about y).
        u = (x + half_t * sin_t) / cos_t
        on = (np.abs(u) <= half_l) & (np.abs(y) <= half_w)
        return np.where(on, pivot_z + u * sin_t + half_t * cos_t, 0.0)

    return Terrain(
        name=name,
        params=dataclasses.asdict(p),
        spawn_xy=(low_end_x - p.approach, 0.0),
        moving_joints=("seesaw_pivot",),
        geom_names=(floor, "seesaw_support", "seesaw_plank"),
        landmarks={"pivot": (0.0, 0.0), "low_end": (low_end_x, 0.0), "high_end": (high_end_x, 0.0)},
        _height_fn=height,
    )
