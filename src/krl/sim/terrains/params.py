"""Terrain names and parameters: one frozen dataclass per terrain, and their resolution and checks.

Every terrain's dataclass extends :class:`GroundParams`, the parameters every terrain has (the ground's
friction). Each field's metadata (set by :func:`_p`) gives its bounds (gt/ge/lt/le), used by
:func:`resolve_params`; the kind (int, float, float-or-None) is taken from the default. A dataclass's
``_problem`` method checks what spans fields (a range's ends in order, a height field's vertex count).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from krl.robots.a1.constants import FOOT_FRICTION
from krl.sim.terrains.grid import MAX_HFIELD_SIDE, grid_count

__all__ = [
    "HEIGHTFIELD_MAX_HEIGHT_RANGE",
    "HEIGHTFIELD_MILD_MAX_HEIGHT",
    "MAX_GROUND_FRICTION",
    "PYRAMIDS_STEP_HEIGHT_RANGE",
    "TERRAIN_NAMES",
    "FlatParams",
    "GroundParams",
    "HeightfieldParams",
    "PerlinParams",
    "PitsParams",
    "PyramidsParams",
    "SeesawParams",
    "SinusoidParams",
    "SlopeParams",
    "StairsParams",
    "TabletopParams",
    "TerrainError",
    "resolve_params",
    "sinusoid_half_size",
]

TERRAIN_NAMES: tuple[str, ...] = (
    "flat",
    "heightfield",
    "heightfield_mild",
    "perlin",
    "sinusoid",
    "slope",
    "stairs",
    "pyramids",
    "pits",
    "tabletop",
    "seesaw",
)
"""Names accepted by :func:`krl.sim.terrains.add_terrain`."""

HEIGHTFIELD_MAX_HEIGHT_RANGE: tuple[float, float] = (0.03, 0.045)
"""(low, high) of the draw h ~ U(low, high) [m] of the random height field's perturbation bound (its blocks
are U(0, h) high): thesis 4.2.9, U(3, 4.5) cm. The defaults of ``HeightfieldParams.max_height_low`` and
``max_height_high``."""


HEIGHTFIELD_MILD_MAX_HEIGHT: float = 0.02
"""The perturbation bound h [m] of ``heightfield_mild``, our reading of the thesis's optimisation terrain
(4.2.1, Fig. 4.2b: "a moderately difficult height-field terrain with perturbations 0.35cm"; see
docs/terrains.md)."""


PYRAMIDS_STEP_HEIGHT_RANGE: tuple[float, float] = (0.04, 0.08)
"""(low, high) of each stepped pyramid's riser height draw U(low, high) [m] (ours, docs/terrains.md): from
the thesis's 4 cm stairs to twice them, within what the A1's legs lift (the kernel-ext's step heights reach
0.18 m). The defaults of ``PyramidsParams.step_height_low`` and ``step_height_high``."""


MAX_GROUND_FRICTION: float = 5.0
"""Largest ground friction μ a terrain accepts [-]: rubber feet on dry ground have about 1 (the thesis's),
so a bound well above it catches typing slips only."""


class TerrainError(ValueError):
    """An unknown terrain name or an invalid terrain parameter (the message names both)."""


def _p(default: float | int | None, *, gt=None, ge=None, lt=None, le=None, optional: bool = False) -> Any:
    """A parameter field: its default and bounds (``gt``/``ge``/``lt``/``le``, None: unbounded) in the
    field's unit; ``optional`` lets it be None. The kind is int for an int default, float otherwise."""
    kind = "int" if isinstance(default, int) and not isinstance(default, bool) else "float"
    return field(
        default=default,
        metadata={"gt": gt, "ge": ge, "lt": lt, "le": le, "kind": kind, "optional": optional},
    )


@dataclass(frozen=True)
class GroundParams:
    """What every terrain has: the friction of its ground."""

    friction: float = _p(FOOT_FRICTION, gt=0.0, le=MAX_GROUND_FRICTION)
    """Sliding friction coefficient μ of every geom of the terrain [-] (thesis 4.2.1: 1). It is the contact's
    μ whatever the robot's geoms say: the terrain's geoms have the higher MuJoCo ``priority``
    (:data:`krl.sim.terrains.geoms.TERRAIN_PRIORITY`)."""


@dataclass(frozen=True)
class FlatParams(GroundParams):
    """Flat ground: an infinite plane at z = 0. No parameters but the ground's friction."""

    def _problem(self) -> str | None:
        return None


@dataclass(frozen=True)
class HeightfieldParams(GroundParams):
    """PyBullet-style random height field (thesis 4.2.1 and 4.2.9, Fig. 4.2b-c)."""

    max_height: float | None = _p(None, gt=0.0, le=1.0, optional=True)
    """Upper bound h of the per-block height draw U(0, h) [m]. ``None``: h is itself drawn
    U(max_height_low, max_height_high) (thesis 4.2.9: U(3, 4.5) cm)."""
    max_height_low: float = _p(HEIGHTFIELD_MAX_HEIGHT_RANGE[0], gt=0.0, le=1.0)
    """Lower end of the draw of h when ``max_height`` is None [m]."""
    max_height_high: float = _p(HEIGHTFIELD_MAX_HEIGHT_RANGE[1], gt=0.0, le=1.0)
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
        return _order_problem(self, "max_height_low", "max_height_high") or _grid_problem(
            self.half_size, self.cell
        )


@dataclass(frozen=True)
class PerlinParams(GroundParams):
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
        return _order_problem(self, "spawn_radius", "blend_radius") or _grid_problem(
            self.half_size, self.cell
        )


@dataclass(frozen=True)
class SinusoidParams(GroundParams):
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
        half = sinusoid_half_size(self.half_size, self.wavelength)
        return _grid_problem(half, self.cell)


@dataclass(frozen=True)
class SlopeParams(GroundParams):
    """A ramp up along +x, a plateau and a ramp down, as a height field: the slopes of Fig. 4.22."""

    incline: float = _p(0.15, gt=0.0, lt=0.6)
    """Angle of both ramps [rad] (ours: between the sinusoid's steepest 0.2 and the table-top's 0.087)."""
    run: float = _p(3.0, gt=0.0, le=20.0)
    """Horizontal length of each ramp [m]."""
    plateau: float = _p(2.0, ge=0.0, le=20.0)
    """Length of the level top [m]."""
    start_x: float = _p(1.0, ge=0.0, le=20.0)
    """Where the ramp up starts [m]."""
    cell: float = _p(0.05, gt=0.0, le=1.0)
    """Vertex spacing of the height field [m]."""
    half_size: float = _p(12.0, gt=0.0, le=100.0)
    """Half extent of the field [m]."""

    def _problem(self) -> str | None:
        if self.start_x + 2 * self.run + self.plateau > self.half_size:
            return (
                "the ramps and the plateau must end inside the field (start_x + 2 run + plateau <= half_size)"
            )
        return _grid_problem(self.half_size, self.cell)


@dataclass(frozen=True)
class StairsParams(GroundParams):
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
class PyramidsParams(GroundParams):
    """A field of stepped pyramids, a training ground of ours (docs/terrains.md): square tiles, each a
    pyramid of concentric square levels of its own riser height, tread and number of levels, with flat
    lanes between them."""

    step_height_low: float = _p(PYRAMIDS_STEP_HEIGHT_RANGE[0], gt=0.0, le=0.5)
    """Lower end of each pyramid's riser height draw U(low, high) [m]."""
    step_height_high: float = _p(PYRAMIDS_STEP_HEIGHT_RANGE[1], gt=0.0, le=0.5)
    """Upper end of each pyramid's riser height draw [m]."""
    tread_low: float = _p(0.25, gt=0.0, le=5.0)
    """Lower end of each pyramid's tread depth draw U(low, high) [m]."""
    tread_high: float = _p(0.33, gt=0.0, le=5.0)
    """Upper end of each pyramid's tread depth draw [m]."""
    max_levels: int = _p(4, ge=1, le=20)
    """Each pyramid has 1 ... max_levels levels (uniform) [-]; its top is at levels · riser height."""
    tile: float = _p(3.0, gt=0.0, le=20.0)
    """Side of the square tile of each pyramid [m]; tiles are centred on odd multiples of tile / 2."""
    lane: float = _p(0.6, gt=0.0, le=20.0)
    """Width of the flat lane between neighbouring pyramids [m]; the spawn point, the origin, is a
    crossing of lanes."""
    half_size: float = _p(12.0, gt=0.0, le=100.0)
    """The field covers [-half_size, half_size]² [m], rounded up to whole tiles."""

    def _problem(self) -> str | None:
        for name in ("step_height", "tread"):
            problem = _order_problem(self, f"{name}_low", f"{name}_high")
            if problem:
                return problem
        top = self.tile - self.lane - 2 * (self.max_levels - 1) * self.tread_high
        if top < self.tread_high:
            return (
                "the top of the highest pyramid must be at least a tread wide "
                "(tile - lane - 2 (max_levels - 1) tread_high >= tread_high)"
            )
        return None


@dataclass(frozen=True)
class PitsParams(PyramidsParams):
    """A field of stepped pits, a training ground of ours (docs/terrains.md): the pyramids' tiles, each a
    pit of concentric square levels going down (a pyramid upside down), as a height field."""

    cell: float = _p(0.04, gt=0.0, le=1.0)
    """Vertex spacing of the height field [m]: a riser is a wall one cell wide."""

    def _problem(self) -> str | None:
        return super()._problem() or _grid_problem(self.half_size, self.cell)


@dataclass(frozen=True)
class TabletopParams(GroundParams):
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
class SeesawParams(GroundParams):
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


def _order_problem(p: Any, smaller: str, larger: str) -> str | None:
    """Why parameter ``larger`` of ``p`` (a parameter dataclass) is below parameter ``smaller``, or None."""
    low, high = getattr(p, smaller), getattr(p, larger)
    if high < low:
        return f"parameter '{larger}' = {high} must be >= '{smaller}' = {low}"
    return None


def _grid_problem(half_size: float, cell: float) -> str | None:
    """Why a field of half extent ``half_size`` [m] at spacing ``cell`` [m] is too large, or None."""
    n = grid_count(half_size, cell)
    if n > MAX_HFIELD_SIDE:
        return (
            f"parameters 'half_size' = {half_size} and 'cell' = {cell} give {n} height-field vertices "
            f"per side (max {MAX_HFIELD_SIDE})"
        )
    return None


def sinusoid_half_size(half_size: float, wavelength: float) -> float:
    """The sinusoid field's half extent [m]: ``half_size`` [m] rounded up to a multiple of ``wavelength`` / 2
    [m], so the field's border lies on zero lines of the surface."""
    half_wave = 0.5 * wavelength
    return math.ceil(half_size / half_wave - 1e-9) * half_wave


def _tabletop_clearance(p: TabletopParams) -> float:
    """Lowest point of the plate above the floor at full tilt [m] (a corner, tilted about the axis
    perpendicular to its diagonal)."""
    centre_z = p.height - 0.5 * p.thickness
    half_diag = p.size / math.sqrt(2.0)
    return centre_z - half_diag * math.sin(p.max_tilt) - 0.5 * p.thickness * math.cos(p.max_tilt)


def resolve_params(name: str, cls: type, overrides: Mapping[str, Any], params: Mapping[str, Any] | None):
    """An instance of the parameter dataclass ``cls`` of terrain ``name``: its defaults, then the registry's
    ``overrides``, then the caller's ``params``, each value checked against its field's bounds.

    Raises:
        TerrainError: an unknown key, a value of the wrong kind or out of bounds, or an inconsistent pair.
    """
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
    """``value`` for field ``f`` of ``terrain``'s parameters, as int or float (None if optional).

    Raises:
        TerrainError: not a number (bools included), not an integer for an int field, not finite, or out
            of the field's bounds.
    """
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
