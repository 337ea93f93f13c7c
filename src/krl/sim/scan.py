"""A height scan: the terrain's surface height under points around each robot, as the scene is now.

:class:`TerrainScanner` answers, for one robot's model, "how high is the topmost terrain surface at world
(x, y)?" for many points at once, the way a downward ray from above would find it, without casting rays:

* the fixed ground (planes, boxes, height fields) from the terrain's own vectorised height function
  (:meth:`krl.sim.terrains.Terrain.ground_height`, exact: it interpolates the height field's triangles as
  MuJoCo does and reads the boxes' tops);
* every box of a moving prop (the table-top's plate, the seesaw's plank) from its pose in ``MjData`` at
  this step: a vertical line through (x, y) crosses an oriented box between two heights (the slab test),
  and the upper one is where a ray from above would hit it.

The scan is the larger of the two, so a tilted plate or a seesaw's raised end is seen where it is now, not
where it was at reset. ``tests/sim/test_scan.py`` checks it against ``mujoco.mj_ray`` on every terrain kind,
moving props included; ``krl bench agent`` measures its cost per robot step. It only reads ``MjData``.

For N robots (:meth:`krl.sim.batch.SimBatch.terrain_heights`), :class:`GroundStack` reads the fixed ground
of all of them at once, one NumPy pass per kind of ground (:mod:`krl.sim.terrains.surface`), bit for bit
what each terrain gives alone; then each robot's props are added by its own :class:`TerrainScanner`.

Points are given in the robot's *heading frame* (yaw-aligned, origin under the trunk): x forward, y left
[m]; :func:`heading_points_to_world` places them in the world.
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np

from krl.sim.terrains import Terrain
from krl.sim.terrains.surface import SurfaceStack

_PARALLEL: float = 1e-12
"""A box axis whose world z component is below this is parallel to the horizontal plane (slab test)."""


def heading_points_to_world(points: np.ndarray, base_pos: np.ndarray, yaw: np.ndarray | float) -> np.ndarray:
    """World (x, y) [m] of heading-frame ``points`` [m], shape (P, 2), of trunks at ``base_pos`` (shape
    (..., 3), [m]) heading ``yaw`` (shape (...), [rad]): one robot (shapes (3,) and ()) or N at once
    (shapes (N, 3) and (N,)), the same arithmetic. Shape: (..., P, 2)."""
    c, s = np.cos(yaw)[..., None], np.sin(yaw)[..., None]
    x = base_pos[..., 0:1] + c * points[:, 0] - s * points[:, 1]
    y = base_pos[..., 1:2] + s * points[:, 0] + c * points[:, 1]
    return np.stack([x, y], axis=-1)


class TerrainScanner:
    """The terrain's surface heights under world points, for one robot's model and terrain.

    Args:
        model: the robot's model (its terrain's moving props are read from it).
        terrain: the terrain built into it.
    """

    def __init__(self, model: mujoco.MjModel, terrain: Terrain) -> None:
        self.terrain = terrain
        boxes = []
        for name in terrain.geom_names:
            geom = model.geom(name)
            if int(model.geom_bodyid[geom.id]) != 0 and int(geom.type[0]) == mujoco.mjtGeom.mjGEOM_BOX:
                boxes.append(geom.id)
        self.moving_boxes = np.array(boxes, dtype=np.int64)
        """Ids of the box geoms on moving bodies (empty for fixed terrains)."""
        self.half_sizes = model.geom_size[self.moving_boxes].copy()
        """Their half extents [m]. Shape: (B, 3)."""

    def heights(self, data: mujoco.MjData, xy: np.ndarray) -> np.ndarray:
        """Height of the topmost terrain surface at world ``xy`` [m], shape (P, 2), as the scene stands in
        ``data`` now [m]. Shape: (P,)."""
        return self.add_props(data, xy, self.terrain.ground_height(xy[:, 0], xy[:, 1]))

    def add_props(self, data: mujoco.MjData, xy: np.ndarray, ground: np.ndarray) -> np.ndarray:
        """The heights ``ground`` [m] of the fixed ground at world ``xy`` [m] (shapes (P,) and (P, 2)), raised
        where a moving prop's box stands above it in ``data`` now [m]. Shape: (P,)."""
        z = ground
        for box, half in zip(self.moving_boxes, self.half_sizes, strict=True):
            top = box_top(data.geom_xpos[box], data.geom_xmat[box].reshape(3, 3), half, xy)
            z = np.fmax(z, top)
        return z


class GroundStack:
    """The fixed ground of N robots' terrains, read at once: the terrains whose ground is a
    :class:`krl.sim.terrains.surface.Surface` grouped by its class, one stacked read per group (bit for bit
    each terrain's own :meth:`krl.sim.terrains.Terrain.ground_height`), the others one at a time. The
    stacks are rebuilt when a robot's terrain changes (a training's new episode on new ground)."""

    def __init__(self) -> None:
        self._terrains: tuple[Terrain, ...] = ()
        self._groups: list[tuple[np.ndarray, SurfaceStack]] = []
        self._alone: list[int] = []

    def heights(self, terrains: Sequence[Terrain], xy: np.ndarray) -> np.ndarray:
        """Height of the fixed ground of robot n's terrain at world ``xy[n]`` [m], shape (N, P, 2). Shape:
        (N, P)."""
        same = len(terrains) == len(self._terrains)
        if not (same and all(a is b for a, b in zip(terrains, self._terrains, strict=True))):
            self._group(terrains)
        z = np.empty(xy.shape[:2])
        for rows, stack in self._groups:
            z[rows] = stack.height(xy[rows, :, 0], xy[rows, :, 1])
        for row in self._alone:
            z[row] = terrains[row].ground_height(xy[row, :, 0], xy[row, :, 1])
        return z

    def _group(self, terrains: Sequence[Terrain]) -> None:
        self._terrains = tuple(terrains)
        kinds: dict[type, list[int]] = {}
        self._alone = []
        for row, terrain in enumerate(terrains):
            if terrain.surface is None:
                self._alone.append(row)
            else:
                kinds.setdefault(type(terrain.surface), []).append(row)
        self._groups = [
            (np.array(rows), kind.stack([terrains[row].surface for row in rows]))
            for kind, rows in kinds.items()
        ]


def box_top(centre: np.ndarray, rotation: np.ndarray, half: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Where vertical lines through world ``xy`` [m] (shape (P, 2)) leave an oriented box at the top [m];
    NaN where a line misses the box. Shape: (P,).

    The box: centre (3,) [m], rotation box-to-world (3, 3), half extents (3,) [m]. A point of the line at
    height z has box coordinates ``a + z b`` with ``a = Rᵀ (x - c, y - c_y, -c_z)`` and ``b = Rᵀ e_z``; it
    is inside where every ``|a_i + z b_i| <= h_i``.
    """
    offset = np.column_stack([xy[:, 0] - centre[0], xy[:, 1] - centre[1], np.full(len(xy), -centre[2])])
    a = offset @ rotation  # (P, 3): Rᵀ offset, row by row
    b = rotation[2]  # Rᵀ e_z
    low = np.full(len(xy), -np.inf)
    high = np.full(len(xy), np.inf)
    for axis in range(3):
        if abs(b[axis]) < _PARALLEL:
            outside = np.abs(a[:, axis]) > half[axis]
            low[outside], high[outside] = np.inf, -np.inf
            continue
        bound1 = (-half[axis] - a[:, axis]) / b[axis]
        bound2 = (half[axis] - a[:, axis]) / b[axis]
        low = np.maximum(low, np.minimum(bound1, bound2))
        high = np.minimum(high, np.maximum(bound1, bound2))
    return np.where(low <= high, high, np.nan)
