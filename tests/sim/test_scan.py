"""The height scan against MuJoCo's own ray casts, on every terrain kind, moving props included."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from krl.sim.model import build_model
from krl.sim.scan import GroundStack, TerrainScanner, box_top, heading_points_to_world
from krl.sim.terrains import TERRAIN_NAMES

TOLERANCE = 1e-6
"""Largest difference from ``mj_ray`` [m]: float rounding (the height fields hold float32 elevations, which
the scanner's grid reads as MuJoCo stores them)."""

RAY_START = 5.0
"""Height the reference rays start from [m], above every terrain."""


def _ray_heights(model, data, xy: np.ndarray, robot_body: int) -> np.ndarray:
    """World z where a ray cast straight down from RAY_START hits anything but the robot."""
    heights = np.empty(len(xy))
    geomid = np.zeros(1, dtype=np.int32)
    for k, (x, y) in enumerate(xy):
        distance = mujoco.mj_ray(
            model, data, np.array([x, y, RAY_START]), np.array([0.0, 0.0, -1.0]), None, 1, robot_body, geomid
        )
        heights[k] = RAY_START - distance if distance >= 0 else np.nan
    return heights


def _scene(terrain: str, tilt: float = 0.0):
    """The terrain's model with the robot lifted far out of the way, its prop (if any) at ``tilt``."""
    built = build_model(terrain, seed=3)
    model, data = built.model, mujoco.MjData(built.model)
    data.qpos[:3] = [0.0, 0.0, 50.0]  # the robot hangs far above every ray's start
    for name in built.terrain.moving_joints:
        joint = model.joint(name)
        address = model.jnt_qposadr[joint.id]
        if joint.type[0] == mujoco.mjtJoint.mjJNT_BALL:
            axis = np.array([0.6, 0.8, 0.0])
            data.qpos[address : address + 4] = [math.cos(tilt / 2), *(math.sin(tilt / 2) * axis)]
        else:
            data.qpos[address] = tilt
    mujoco.mj_forward(model, data)
    return built, model, data


def _points(terrain) -> np.ndarray:
    """A dense patch of world points over the terrain's features (its landmarks and spawn)."""
    centres = [terrain.spawn_xy, *terrain.landmarks.values()]
    rng = np.random.default_rng(0)
    return np.concatenate([np.asarray(c) + rng.uniform(-1.2, 1.2, (150, 2)) for c in centres])


@pytest.mark.parametrize("name", TERRAIN_NAMES)
def test_scan_matches_ray_casts_on_every_terrain(name):
    tilts = (0.0, 0.08, -0.15) if name in ("tabletop", "seesaw") else (0.0,)
    for tilt in tilts:
        built, model, data = _scene(name, tilt)
        xy = _points(built.terrain)
        scanned = TerrainScanner(model, built.terrain).heights(data, xy)
        cast = _ray_heights(model, data, xy, model.body("trunk").id)
        assert np.isfinite(scanned).all()
        np.testing.assert_allclose(scanned, cast, atol=TOLERANCE, err_msg=f"{name} at tilt {tilt}")


def test_scan_follows_a_moving_prop():
    """The seesaw's plank seen where it is now: tilted the other way, its low end is where the high end
    was, and the scan says so (the terrain's rest-pose height does not)."""
    built, model, data = _scene("seesaw", tilt=0.15)
    high_end = np.array([built.terrain.landmarks["high_end"]]) - [[0.1, 0.0]]
    scanned = TerrainScanner(model, built.terrain).heights(data, high_end)
    assert scanned[0] < built.terrain.height(*high_end[0]) - 0.1


def test_box_top_of_an_axis_aligned_box():
    xy = np.array([[0.0, 0.0], [0.9, 0.0], [1.1, 0.0]])
    top = box_top(np.array([0.0, 0.0, 0.5]), np.eye(3), np.array([1.0, 1.0, 0.25]), xy)
    np.testing.assert_allclose(top[:2], [0.75, 0.75])
    assert np.isnan(top[2])


def test_heading_points_turn_with_the_yaw():
    points = np.array([[1.0, 0.0], [0.0, 1.0]])
    world = heading_points_to_world(points, np.array([2.0, 3.0, 0.3]), math.pi / 2)
    np.testing.assert_allclose(world, [[2.0, 4.0], [1.0, 3.0]], atol=1e-12)


def test_heading_points_of_many_robots_are_each_robots_own():
    """N robots at once give, bit for bit, what each gives alone."""
    rng = np.random.default_rng(1)
    points, base, yaw = rng.uniform(-1, 1, (187, 2)), rng.uniform(-5, 5, (16, 3)), rng.uniform(-4, 4, 16)
    together = heading_points_to_world(points, base, yaw)
    assert together.shape == (16, 187, 2)
    for n in range(16):
        assert np.array_equal(together[n], heading_points_to_world(points, base[n], yaw[n]))


def test_the_ground_of_many_terrains_read_at_once_is_each_terrains_own():
    """GroundStack groups the terrains by the class of their surface and reads each group in one pass: the
    heights are bit for bit each terrain's own ground_height, on every terrain kind mixed in one batch (two
    draws of each, points on and beyond the fields), and they follow a robot's terrain when it changes."""
    terrains = [build_model(name, seed=seed).terrain for name in TERRAIN_NAMES for seed in (3, 4)]
    rng = np.random.default_rng(2)
    xy = rng.uniform(-9.0, 9.0, (len(terrains), 187, 2))
    ground = GroundStack()

    def each_alone(terrains):
        return np.stack([t.ground_height(xy[n, :, 0], xy[n, :, 1]) for n, t in enumerate(terrains)])

    assert np.array_equal(ground.heights(terrains, xy), each_alone(terrains))
    assert [t.name for t in terrains if t.surface is None] == ["stairs", "stairs"]  # read one at a time
    changed = [terrains[-1], *terrains[1:-1], terrains[0]]
    assert np.array_equal(ground.heights(changed, xy), each_alone(changed))
