"""Terrains: the ground the A1 walks on, added to an ``MjSpec`` that already holds the robot.

Every terrain is built by :func:`add_terrain` from a name in :data:`TERRAIN_NAMES`, a mapping of parameter
overrides and a ``numpy.random.Generator``. Each terrain has one frozen parameter dataclass whose fields
carry the defaults and units; ``docs/terrains.md`` describes the layouts, the distributions of the random
draws and the reasons for every choice the thesis leaves open.

World conventions: z up, ground at z = 0 for the flat-floored terrains, the robot starts at
:attr:`Terrain.spawn_xy` facing +x (:attr:`Terrain.spawn_yaw` = 0). Every terrain geom collides with the
robot only, with condim 3 and the friction :data:`TERRAIN_FRICTION`, whose sliding μ (1, the feet's) the
``friction`` parameter every terrain has changes (:class:`GroundParams`); the terrain's geoms have the higher
MuJoCo priority (:data:`TERRAIN_PRIORITY`), so μ is the contact's.

Modules, each importing only those listed before it:

- :mod:`~krl.sim.terrains.grid`: height-field grids: the vertex axis of a square field, the cost guard
  :data:`MAX_HFIELD_SIDE`, and :class:`HeightGrid` (vertex heights in world z, the surface as MuJoCo
  triangulates it, slopes).
- :mod:`~krl.sim.terrains.params`: :data:`TERRAIN_NAMES`, :class:`TerrainError`, the parameter dataclasses
  (:class:`GroundParams`, what every terrain has, and ``FlatParams`` ... ``SeesawParams``, with
  :data:`HEIGHTFIELD_MAX_HEIGHT_RANGE` and :data:`PYRAMIDS_STEP_HEIGHT_RANGE`) and their resolution and
  bound checks.
- :mod:`~krl.sim.terrains.tiles`: :class:`StepTiles`, the field of stepped tiles the pyramids and the pits
  share (drawn once, read as heights).
- :mod:`~krl.sim.terrains.surface`: a terrain's fixed ground as a :class:`Surface` (the floor, a height field
  and its floor, stepped tiles) that stacks with others of its kind, so many terrains are read in one pass.
- :mod:`~krl.sim.terrains.terrain`: :class:`Terrain`, what a build returns (spawn, landmarks, height query).
- :mod:`~krl.sim.terrains.geoms`: the geom every terrain adds (collision settings, :data:`TERRAIN_FRICTION`,
  :data:`TERRAIN_PRIORITY`), the floor plane and setting the ground's friction.
- :mod:`~krl.sim.terrains.heightfields`: the height-field terrains: random height field, Perlin hills,
  sinusoid (and :func:`sinusoid_amplitude`).
- :mod:`~krl.sim.terrains.primitives`: the terrains built from planes and boxes: flat, stairs, pyramids,
  and the moving props table-top and seesaw.
- :mod:`~krl.sim.terrains.scene`: :func:`add_terrain` (the registry of builders and the scene every terrain
  shares: sky, textures, materials, lights) and :func:`terrain_param_defaults`.
"""

from krl.sim.terrains.geoms import TERRAIN_FRICTION, TERRAIN_PRIORITY
from krl.sim.terrains.grid import MAX_HFIELD_SIDE, HeightGrid
from krl.sim.terrains.heightfields import sinusoid_amplitude
from krl.sim.terrains.params import (
    HEIGHTFIELD_MAX_HEIGHT_RANGE,
    HEIGHTFIELD_MILD_MAX_HEIGHT,
    MAX_GROUND_FRICTION,
    PYRAMIDS_STEP_HEIGHT_RANGE,
    TERRAIN_NAMES,
    FlatParams,
    GroundParams,
    HeightfieldParams,
    PerlinParams,
    PitsParams,
    PyramidsParams,
    SeesawParams,
    SinusoidParams,
    SlopeParams,
    StairsParams,
    TabletopParams,
    TerrainError,
)
from krl.sim.terrains.scene import add_terrain, terrain_param_defaults
from krl.sim.terrains.terrain import Terrain

__all__ = [
    "HEIGHTFIELD_MAX_HEIGHT_RANGE",
    "HEIGHTFIELD_MILD_MAX_HEIGHT",
    "MAX_GROUND_FRICTION",
    "MAX_HFIELD_SIDE",
    "PYRAMIDS_STEP_HEIGHT_RANGE",
    "TERRAIN_FRICTION",
    "TERRAIN_NAMES",
    "TERRAIN_PRIORITY",
    "FlatParams",
    "GroundParams",
    "HeightGrid",
    "HeightfieldParams",
    "PerlinParams",
    "PitsParams",
    "PyramidsParams",
    "SeesawParams",
    "SinusoidParams",
    "SlopeParams",
    "StairsParams",
    "TabletopParams",
    "Terrain",
    "TerrainError",
    "add_terrain",
    "sinusoid_amplitude",
    "terrain_param_defaults",
]
