"""The terrains built from MuJoCo primitives: flat (a plane), stairs and pyramids (boxes), and the moving
props table-top (a plate on a ball joint) and seesaw (a plank on a hinge), each on a floor plane at z = 0.

Only the pyramids draw at random (their draw order is in :func:`build_pyramids`); the other builders leave
their ``rng`` argument unused (it keeps one builder signature).
"""

from __future__ import annotations

import dataclasses
import math

import mujoco
import numpy as np

from krl.sim.terrains.geoms import add_floor, add_geom, spec_angle
from krl.sim.terrains.params import FlatParams, PyramidsParams, SeesawParams, StairsParams, TabletopParams
from krl.sim.terrains.surface import FlatSurface
from krl.sim.terrains.terrain import Terrain
from krl.sim.terrains.tiles import StepTiles

__all__ = ["build_flat", "build_pyramids", "build_seesaw", "build_stairs", "build_tabletop"]

FLOOR = FlatSurface(0.0)
"""The floor at z = 0: the flat terrain, and the fixed ground of a prop terrain (the prop's support stands
under the prop at every tilt, so no downward ray reaches it)."""


def build_flat(spec: mujoco.MjSpec, name: str, p: FlatParams, rng: np.random.Generator) -> Terrain:
    """Add the flat ground: the floor plane at z = 0, spawn at the origin."""
    floor = add_floor(spec)
    return Terrain(
        name=name,
        params={},
        spawn_xy=(0.0, 0.0),
        geom_names=(floor,),
        _height_fn=FLOOR.height,
        surface=FLOOR,
    )


def build_stairs(spec: mujoco.MjSpec, name: str, p: StairsParams, rng: np.random.Generator) -> Terrain:
    """Add the stairs: ``p.num_steps`` risers of ``p.step_height`` [m] up from ``p.start_x`` [m], the
    landing, the same risers down; one box per tread, alternating two materials."""
    floor = add_floor(spec)
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
        add_geom(
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


def build_pyramids(spec: mujoco.MjSpec, name: str, p: PyramidsParams, rng: np.random.Generator) -> Terrain:
    """Add the field of stepped pyramids: one per tile, level k (1 ... levels) a box from the floor to
    k · riser, of side (tile - lane) - 2 (k - 1) · tread, centred on the tile; treads alternate two tints.

    Draw order (fixed, for reproducibility), tile by tile, rows along y then columns along x: the riser
    height ~ U(step_height_low, step_height_high), the tread ~ U(tread_low, tread_high), the number of levels
    ~ uniform on 1 ... max_levels.
    """
    floor = add_floor(spec)
    tiles = StepTiles.draw(p, rng)
    names = [floor]
    for row in range(tiles.per_side):
        for col in range(tiles.per_side):
            for k in range(1, tiles.levels[row, col] + 1):
                half_side = 0.5 * tiles.base - (k - 1) * tiles.tread[row, col]
                top = k * tiles.riser[row, col]
                gname = f"pyramid_{row}_{col}_{k}"
                add_geom(
                    spec.worldbody,
                    gname,
                    mujoco.mjtGeom.mjGEOM_BOX,
                    "krl_steps" if k % 2 == 1 else "krl_steps_alt",
                    pos=[tiles.centres[col], tiles.centres[row], 0.5 * top],
                    size=[half_side, half_side, 0.5 * top],
                )
                names.append(gname)
    half = tiles.half

    return Terrain(
        name=name,
        params=dataclasses.asdict(dataclasses.replace(p, half_size=half)),
        spawn_xy=(0.0, 0.0),
        geom_names=tuple(names),
        landmarks={"field_min": (-half, -half), "field_max": (half, half)},
        _height_fn=tiles.height,
        surface=tiles,
    )


def build_tabletop(spec: mujoco.MjSpec, name: str, p: TabletopParams, rng: np.random.Generator) -> Terrain:
    """Add the table-top: a plate on a damped ball joint at its centre, its top ``p.height`` [m] above the
    floor when level, and a post under it for the eye."""
    floor = add_floor(spec)
    centre_z = p.height - 0.5 * p.thickness
    # A post under the pivot, only for the eye (it sits below the plate and cannot touch it).
    post_top = centre_z - 0.5 * p.thickness - 0.01
    add_geom(
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
    joint.range = [0.0, spec_angle(spec, p.max_tilt)]
    joint.damping = [p.damping, 0.0, 0.0]
    half = 0.5 * p.size
    add_geom(
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
        surface=FLOOR,
    )


def build_seesaw(spec: mujoco.MjSpec, name: str, p: SeesawParams, rng: np.random.Generator) -> Terrain:
    """Add the seesaw: a plank on a damped hinge about y, at rest on its limit with the -x end down, a
    support under it for the eye; spawn ``p.approach`` [m] before the low end."""
    floor = add_floor(spec)
    half_l, half_w, half_t = 0.5 * p.length, 0.5 * p.width, 0.5 * p.thickness
    sin_t, cos_t = math.sin(p.max_tilt), math.cos(p.max_tilt)
    pivot_z = half_l * sin_t + half_t * cos_t + p.clearance
    # A support under the hinge, only for the eye; its top stays clear of the plank at any tilt.
    support_top = pivot_z - half_t - 0.05 * sin_t - 0.005
    add_geom(
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
    joint.ref = spec_angle(spec, rest)
    joint.limited = mujoco.mjtLimited.mjLIMITED_TRUE
    joint.range = [spec_angle(spec, -p.max_tilt), spec_angle(spec, p.max_tilt)]
    joint.damping = [p.damping, 0.0, 0.0]
    add_geom(
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
        surface=FLOOR,
    )
