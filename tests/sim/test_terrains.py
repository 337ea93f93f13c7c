"""Terrains: every terrain builds with the robot and holds it up; heights, slopes, seeds and errors."""

from __future__ import annotations

import math
import os
from pathlib import Path

import mujoco
import numpy as np
import pytest

from krl.robots.a1 import MJCF_PATH
from krl.robots.a1 import constants as C
from krl.sim.terrains import (
    HEIGHTFIELD_MAX_HEIGHT_RANGE,
    TERRAIN_NAMES,
    Terrain,
    TerrainError,
    add_terrain,
    sinusoid_amplitude,
    terrain_param_defaults,
)

HFIELD_TERRAINS = ("heightfield", "heightfield_mild", "perlin", "sinusoid")
RANDOM_TERRAINS = ("heightfield", "heightfield_mild", "perlin")
ROBOT_QPOS = 19  # free joint (7) + 12 leg joints


def build(name: str, params=None, seed: int = 0, robot: bool = True):
    """Compile the named terrain, with the A1 (default) or alone."""
    spec = mujoco.MjSpec.from_file(str(MJCF_PATH)) if robot else mujoco.MjSpec()
    terrain = add_terrain(spec, name, params, np.random.default_rng(seed))
    return spec, spec.compile(), terrain


def standing_data(model: mujoco.MjModel, terrain: Terrain) -> mujoco.MjData:
    """The robot standing 2 cm above the spawn point, PD-holding the standing pose."""
    data = mujoco.MjData(model)
    x, y = terrain.spawn_xy
    data.qpos[0:3] = [x, y, float(terrain.height(x, y)) + C.STANDING_HEIGHT + 0.02]
    data.qpos[3:7] = [math.cos(terrain.spawn_yaw / 2), 0.0, 0.0, math.sin(terrain.spawn_yaw / 2)]
    data.qpos[7:19] = C.STANDING_JOINT_ANGLES
    data.ctrl[:] = C.KP * C.STANDING_JOINT_ANGLES  # the actuators compute ctrl - kp q - kd qdot
    mujoco.mj_forward(model, data)
    return data


def ray_heights(model: mujoco.MjModel, xy: np.ndarray) -> np.ndarray:
    """Height of the first surface hit by a ray cast straight down from z = 5 m at each (x, y)."""
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    geomid = np.zeros(1, np.int32)
    out = []
    for x, y in xy:
        dist = mujoco.mj_ray(
            model, data, np.array([x, y, 5.0]), np.array([0.0, 0.0, -1.0]), None, 1, -1, geomid
        )
        out.append(5.0 - dist if dist >= 0 else np.nan)
    return np.array(out)


# --- building and standing ------------------------------------------------------------------------


def test_names_and_defaults():
    assert set(TERRAIN_NAMES) == {
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
    }
    assert terrain_param_defaults("heightfield")["max_height"] is None  # drawn U(3, 4.5) cm
    assert HEIGHTFIELD_MAX_HEIGHT_RANGE == (0.03, 0.045)  # thesis 4.2.9
    for name in ("heightfield", "heightfield_mild"):
        defaults = terrain_param_defaults(name)
        assert (defaults["max_height_low"], defaults["max_height_high"]) == HEIGHTFIELD_MAX_HEIGHT_RANGE
    assert terrain_param_defaults("heightfield_mild")["max_height"] == 0.02
    assert terrain_param_defaults("sinusoid")["max_incline"] == 0.2
    assert terrain_param_defaults("stairs")["step_height"] == 0.04
    assert terrain_param_defaults("tabletop")["max_tilt"] == 0.087
    assert terrain_param_defaults("seesaw")["max_tilt"] == 0.1


@pytest.mark.parametrize("name", TERRAIN_NAMES)
def test_robot_stands_two_seconds(name):
    _, model, terrain = build(name, seed=150)
    assert model.nq >= ROBOT_QPOS
    for joint in terrain.moving_joints:  # props come after the robot
        assert model.jnt_qposadr[model.joint(joint).id] >= ROBOT_QPOS
    data = standing_data(model, terrain)
    mujoco.mj_step(model, data, nstep=2000)
    assert np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))
    x, y = terrain.spawn_xy
    assert data.qpos[2] > float(terrain.height(x, y)) + 0.15
    assert np.linalg.norm(data.qpos[0:2] - terrain.spawn_xy) < 0.1  # it stayed where it was put


@pytest.mark.parametrize("name", TERRAIN_NAMES)
def test_terrain_geoms_contact_settings(name):
    _, model, terrain = build(name)
    assert terrain.geom_names
    for geom in terrain.geom_names:
        g = model.geom(geom)
        assert (g.contype[0], g.conaffinity[0], g.condim[0]) == (0, 1, 3)
        assert g.friction[0] == C.FOOT_FRICTION
        assert g.matid[0] >= 0
    # The terrain reaches at least 10 m in every direction from the origin.
    assert np.all(np.isfinite(terrain.height([-10, 10, 0, 0], [0, 0, -10, 10])))
    if terrain.grid is not None:
        assert terrain.grid.x0 <= -10 and terrain.grid.x1 >= 10
        assert terrain.grid.y0 <= -10 and terrain.grid.y1 >= 10


# --- heights against MuJoCo -----------------------------------------------------------------------


@pytest.mark.parametrize("name", [*HFIELD_TERRAINS, "flat", "stairs", "pyramids"])
def test_height_matches_ray_cast(name):
    _, model, terrain = build(name, seed=215, robot=False)
    rng = np.random.default_rng(1)
    if name == "stairs":
        xy = rng.uniform([-1.0, -2.5], [7.0, 2.5], size=(300, 2))
    elif name == "pyramids":  # dense: each pyramid has up to 4 treads of 25-33 cm
        xy = np.concatenate([rng.uniform(-11.9, 11.9, size=(2000, 2)), rng.uniform(-1, 1, size=(50, 2))])
    else:
        xy = np.concatenate([rng.uniform(-11.5, 11.5, size=(300, 2)), rng.uniform(-1, 1, size=(50, 2))])
    np.testing.assert_allclose(terrain.height(xy[:, 0], xy[:, 1]), ray_heights(model, xy), atol=1e-3)


@pytest.mark.parametrize("name", ["tabletop", "seesaw"])
def test_prop_height_at_rest_matches_ray_cast(name):
    _, model, terrain = build(name, robot=False)
    rng = np.random.default_rng(2)
    xy = rng.uniform([-2.2, -1.0], [1.9, 1.0], size=(200, 2))  # clear of the seesaw's high end face
    np.testing.assert_allclose(terrain.height(xy[:, 0], xy[:, 1]), ray_heights(model, xy), atol=1e-3)


def test_height_is_vectorised():
    _, _, terrain = build("perlin", robot=False)
    x = np.linspace(-3, 3, 12).reshape(3, 4)
    assert terrain.height(x, 0.5).shape == (3, 4)
    assert terrain.height(0.0, 0.0).shape == ()


# --- random draws ---------------------------------------------------------------------------------


@pytest.mark.parametrize("name", RANDOM_TERRAINS)
def test_same_seed_same_model_different_seed_different(name):
    _, a, ta = build(name, seed=345, robot=False)
    _, b, tb = build(name, seed=345, robot=False)
    _, c, _ = build(name, seed=556, robot=False)
    np.testing.assert_array_equal(a.hfield_data, b.hfield_data)
    np.testing.assert_array_equal(a.hfield_size, b.hfield_size)
    np.testing.assert_array_equal(a.geom_pos, b.geom_pos)
    assert ta.params == tb.params
    assert not np.array_equal(a.hfield_data, c.hfield_data)


@pytest.mark.parametrize("name", RANDOM_TERRAINS)
def test_resolved_params_rebuild_the_same_terrain(name):
    _, _, first = build(name, seed=7, robot=False)
    _, _, again = build(name, params=first.params, seed=7, robot=False)
    assert again.params == first.params
    np.testing.assert_array_equal(again.grid.heights, first.grid.heights)


def test_heightfield_blocks_and_spawn_patch():
    _, _, terrain = build("heightfield", seed=150, robot=False)
    h = terrain.params["max_height"]
    assert 0.03 <= h <= 0.045  # drawn U(3, 4.5) cm
    grid = terrain.grid
    heights = grid.heights
    assert np.isclose(grid.dx, 0.05) and np.isclose(grid.dy, 0.05)
    assert heights.min() >= -1e-9 and heights.max() <= h + 1e-6
    # 2 x 2 vertex blocks share one height (away from the spawn patch).
    corner = heights[:40, :40]
    np.testing.assert_allclose(corner[0::2, 0::2], corner[1::2, 1::2], atol=1e-7)
    np.testing.assert_allclose(corner[0::2, 0::2], corner[0::2, 1::2], atol=1e-7)
    # Level spawn patch at h / 2.
    r = np.linspace(0, 0.45, 10)
    np.testing.assert_allclose(terrain.height(r, 0.0), h / 2, atol=1e-6)
    np.testing.assert_allclose(terrain.height(0.0, -r), h / 2, atol=1e-6)
    # A given max_height skips the draw; the mild terrain uses 2 cm.
    _, _, fixed = build("heightfield", params={"max_height": 0.04}, robot=False)
    assert fixed.params["max_height"] == 0.04
    _, _, mild = build("heightfield_mild", robot=False)
    assert mild.params["max_height"] == 0.02 and mild.grid.heights.max() <= 0.02 + 1e-6


# --- slopes ---------------------------------------------------------------------------------------


@pytest.mark.parametrize(("incline", "wavelength"), [(0.2, 2.5), (0.35, 3.0), (0.1, 2.0)])
def test_sinusoid_max_slope_is_max_incline(incline, wavelength):
    # Analytic surface, fine central differences: the steepest slope equals max_incline.
    amplitude = sinusoid_amplitude(incline, wavelength)
    k = 2 * math.pi / wavelength
    s = np.linspace(-wavelength, wavelength, 801)
    x, y = np.meshgrid(s, s)
    gx = amplitude * k * np.cos(k * x) * np.sin(k * y)
    gy = amplitude * k * np.sin(k * x) * np.cos(k * y)
    assert math.isclose(float(np.arctan(np.hypot(gx, gy).max())), incline, rel_tol=1e-4)
    # The built (triangulated) height field: within 1 % below it, and its height() likewise.
    _, _, terrain = build("sinusoid", params={"max_incline": incline, "wavelength": wavelength}, robot=False)
    assert incline * 0.99 <= terrain.max_slope <= incline * (1 + 1e-6)
    d = 1e-3
    z = terrain.height(x, y)
    slope = np.hypot(terrain.height(x + d, y) - z, terrain.height(x, y + d) - z) / d
    assert incline * 0.99 <= float(np.arctan(slope.max())) <= incline * 1.01
    # The spawn point is a saddle at z = 0 and the field ends at z = 0.
    assert abs(float(terrain.height(0, 0))) < 1e-6
    half = terrain.params["half_size"]
    assert np.abs(terrain.height(half, s)).max() < 1e-6


@pytest.mark.parametrize("seed", [150, 215, 345, 556])
def test_perlin_slopes_walkable(seed):
    _, _, terrain = build("perlin", seed=seed, robot=False)
    assert terrain.max_slope <= 0.25 + 1e-9
    heights = terrain.grid.heights
    assert heights.max() - heights.min() > 0.15  # real hills, not a flat field
    # Level spawn patch.
    r = np.linspace(0, 0.45, 10)
    np.testing.assert_allclose(terrain.height(r, 0.0), terrain.height(0.0, 0.0), atol=1e-6)


def test_perlin_steep_request_is_scaled_to_max_slope():
    _, _, terrain = build("perlin", params={"amplitude": 2.0, "max_slope": 0.2}, robot=False)
    assert math.isclose(terrain.max_slope, 0.2, rel_tol=1e-6)
    assert terrain.params["amplitude"] < 2.0


# --- stairs and props -----------------------------------------------------------------------------


def test_stairs_layout():
    _, _, terrain = build("stairs", robot=False)
    x = np.array([0.0, 0.99, 1.01, 1.31, 2.19, 2.21, 3.0, 3.69, 3.71, 4.89, 4.91, 6.0])
    expected = [0, 0, 0.04, 0.08, 0.16, 0.2, 0.2, 0.2, 0.16, 0.04, 0, 0]
    np.testing.assert_allclose(terrain.height(x, 0.0), expected, atol=1e-9)
    np.testing.assert_allclose(terrain.height(3.0, [-1.49, 1.49, -1.51, 1.51]), [0.2, 0.2, 0, 0])
    assert terrain.spawn_xy == (0.0, 0.0)
    assert terrain.landmarks["first_riser"] == (1.0, 0.0)


def test_pyramids_layout_and_draws():
    _, _, terrain = build("pyramids", seed=150, robot=False)
    p = terrain.params
    assert terrain.spawn_xy == (0.0, 0.0) and terrain.height(0.0, 0.0) == 0.0
    # Lanes: flat wherever a point is within lane / 2 of a tile border.
    border = np.arange(-12.0, 12.01, p["tile"])
    x, y = np.meshgrid(border + 0.29, np.linspace(-11.9, 11.9, 50))
    np.testing.assert_array_equal(terrain.height(x, y), 0.0)
    # Each tile: a riser in [4, 8] cm, 1-4 levels, the top at levels x riser at the tile's centre.
    centres = np.arange(-10.5, 10.51, 3.0)
    cx, cy = np.meshgrid(centres, centres)
    tops = terrain.height(cx, cy)
    risers = terrain.height(cx + 1.19, cy)  # on the lowest tread (base half side 1.2 m)
    assert np.all((risers >= 0.04) & (risers <= 0.08))
    levels = np.round(tops / risers).astype(int)
    np.testing.assert_allclose(tops, levels * risers, atol=1e-12)
    assert set(levels.ravel()) == {1, 2, 3, 4}  # 64 tiles draw every count of levels
    assert terrain.height(20.0, 0.0) == 0.0  # the floor beyond the field


def test_pyramids_same_seed_same_model_and_params_rebuild():
    _, a, ta = build("pyramids", seed=345, robot=False)
    _, b, _ = build("pyramids", seed=345, robot=False)
    _, c, _ = build("pyramids", seed=556, robot=False)
    _, again, _ = build("pyramids", params=ta.params, seed=345, robot=False)
    for other in (b, again):
        np.testing.assert_array_equal(a.geom_pos, other.geom_pos)
        np.testing.assert_array_equal(a.geom_size, other.geom_size)
    assert a.ngeom != c.ngeom or not np.array_equal(a.geom_size, c.geom_size)


def _corner_min_z(model: mujoco.MjModel, data: mujoco.MjData, geom: str) -> float:
    g = model.geom(geom)
    signs = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T
    corners = data.geom(geom).xpos + (signs * g.size) @ data.geom(geom).xmat.reshape(3, 3).T
    return float(corners[:, 2].min())


def test_props_clear_the_floor_at_full_tilt():
    _, model, terrain = build("tabletop", robot=False)
    data = mujoco.MjData(model)
    tilt = terrain.params["max_tilt"]
    for angle in np.linspace(0, 2 * math.pi, 17):  # tilt axis all round, incl. perpendicular to diagonals
        axis = np.array([math.cos(angle), math.sin(angle), 0.0])
        data.qpos[0:4] = [math.cos(tilt / 2), *(math.sin(tilt / 2) * axis)]
        mujoco.mj_kinematics(model, data)
        assert _corner_min_z(model, data, "tabletop_plate") > 0.0
    _, model, terrain = build("seesaw", robot=False)
    data = mujoco.MjData(model)
    tilt = terrain.params["max_tilt"]
    assert math.isclose(model.qpos0[0], -tilt)  # rests on its limit, -x end down
    for q in (-tilt, tilt):
        data.qpos[0] = q
        mujoco.mj_kinematics(model, data)
        low = _corner_min_z(model, data, "seesaw_plank")
        assert 0.0 < low <= terrain.params["clearance"] + 1e-6


def _tilt_with_box(name: str, box_x: float) -> tuple[Terrain, np.ndarray]:
    """Put a 12.5 kg box (the robot's mass) on the prop at x = box_x; return the tilt angle over 1.5 s."""
    spec = mujoco.MjSpec.from_file(str(MJCF_PATH))
    terrain = add_terrain(spec, name, None, np.random.default_rng(0))
    body = spec.worldbody.add_body()
    body.pos = [box_x, 0.0, float(terrain.height(box_x, 0.0)) + 0.055]
    body.add_freejoint()
    box = body.add_geom()
    box.type = mujoco.mjtGeom.mjGEOM_BOX
    box.size = [0.15, 0.1, 0.05]
    box.mass = C.TOTAL_MASS
    box.contype, box.conaffinity = 1, 0
    model = spec.compile()
    data = mujoco.MjData(model)
    data.qpos[0:3] = [-8.0, 8.0, 0.3]  # the robot stands far away
    data.qpos[7:19] = C.STANDING_JOINT_ANGLES
    data.ctrl[:] = C.KP * C.STANDING_JOINT_ANGLES
    adr = model.jnt_qposadr[model.joint(terrain.moving_joints[0]).id]
    angles = []
    for _ in range(150):
        mujoco.mj_step(model, data, nstep=10)
        if name == "tabletop":
            angles.append(2 * math.acos(min(1.0, abs(data.qpos[adr]))))
        else:
            angles.append(data.qpos[adr])
    return terrain, np.array(angles)


def test_tabletop_tilts_under_an_off_centre_load():
    terrain, angles = _tilt_with_box("tabletop", 0.75)
    tilt = terrain.params["max_tilt"]
    assert terrain.moving_joints == ("tabletop_pivot",)
    assert angles[0] < 0.5 * tilt  # smooth, not instantaneous (damping)
    assert 0.9 * tilt < angles[-1] < 1.05 * tilt


def test_seesaw_tips_when_the_load_passes_the_pivot():
    terrain, angles = _tilt_with_box("seesaw", 1.0)
    tilt = terrain.params["max_tilt"]
    assert terrain.moving_joints == ("seesaw_pivot",)
    assert angles[0] < 0  # starts on its rest limit (-x end down)
    assert 0.9 * tilt < angles[-1] < 1.05 * tilt
    _, angles = _tilt_with_box("seesaw", -1.0)  # load on the low side: stays down
    assert np.all(angles < -0.9 * tilt)


def test_seesaw_spawn_faces_the_low_end():
    _, _, terrain = build("seesaw", robot=False)
    low_x = terrain.landmarks["low_end"][0]
    assert terrain.spawn_xy[0] < low_x and math.isclose(low_x - terrain.spawn_xy[0], 0.7)
    assert float(terrain.height(*terrain.spawn_xy)) == 0.0
    assert 0.0 < float(terrain.height(low_x + 0.05, 0.0)) < 0.06  # a low step up onto the plank


# --- errors ---------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("name", "params", "words"),
    [
        ("stairs", {"step_height": -0.04}, ["stairs", "step_height"]),
        ("sinusoid", {"max_incline": math.pi / 2}, ["sinusoid", "max_incline"]),
        ("sinusoid", {"max_incline": 2.0}, ["sinusoid", "max_incline"]),
        ("flat", {"size": 3}, ["flat", "size"]),
        ("heightfield", {"max_hieght": 0.03}, ["heightfield", "max_hieght", "max_height"]),
        ("heightfield", {"block": 1.5}, ["heightfield", "block", "integer"]),
        ("heightfield", {"cell": "5cm"}, ["heightfield", "cell"]),
        ("heightfield", {"cell": 0.001}, ["heightfield", "cell", "vertices"]),
        ("heightfield", {"max_height_low": 0.05}, ["heightfield", "max_height_high"]),
        ("perlin", {"amplitude": float("nan")}, ["perlin", "amplitude", "finite"]),
        ("tabletop", {"height": 0.15}, ["tabletop", "height", "floor"]),
        ("seesaw", {"max_tilt": 0.0}, ["seesaw", "max_tilt"]),
        ("pyramids", {"tread_low": 0.4}, ["pyramids", "tread_high"]),
        ("pyramids", {"max_levels": 6}, ["pyramids", "top", "tread"]),
    ],
)
def test_bad_parameter_is_named(name, params, words):
    with pytest.raises(TerrainError) as info:
        add_terrain(mujoco.MjSpec(), name, params)
    message = str(info.value)
    assert "\n" not in message
    for word in words:
        assert word in message


def test_unknown_terrain_lists_valid_names():
    with pytest.raises(TerrainError, match="unknown terrain 'lava'") as info:
        add_terrain(mujoco.MjSpec(), "lava")
    assert all(name in str(info.value) for name in TERRAIN_NAMES)
    with pytest.raises(TerrainError):
        terrain_param_defaults("lava")
    assert issubclass(TerrainError, ValueError)


def test_second_terrain_on_one_spec_is_refused():
    spec = mujoco.MjSpec()
    add_terrain(spec, "flat")
    with pytest.raises(TerrainError, match="already"):
        add_terrain(spec, "stairs")


# --- pictures -------------------------------------------------------------------------------------


@pytest.mark.skipif(
    os.environ.get("MUJOCO_GL") not in ("osmesa", "egl"),
    reason="offscreen rendering needs MUJOCO_GL=osmesa or egl",
)
def test_render_each_terrain(tmp_path):
    """Writes /tmp/terrains/<name>.png (the robot standing at spawn) for a person to look at."""
    out = Path("/tmp/terrains")
    out.mkdir(exist_ok=True)
    import imageio.v2 as imageio

    for name in TERRAIN_NAMES:
        _, model, terrain = build(name, seed=150)
        data = standing_data(model, terrain)
        mujoco.mj_step(model, data, nstep=300)
        camera = mujoco.MjvCamera()
        camera.distance, camera.azimuth, camera.elevation = 3.0, 135.0, -25.0
        camera.lookat[:] = data.qpos[0:3]
        if name == "stairs":
            camera.distance, camera.azimuth, camera.lookat[:] = 5.0, 60.0, [2.2, 0.0, 0.1]
        elif name == "seesaw":
            camera.distance, camera.azimuth, camera.lookat[:] = 5.0, 60.0, [-1.0, 0.0, 0.1]
        with mujoco.Renderer(model, 480, 640) as renderer:
            renderer.update_scene(data, camera)
            image = renderer.render()
        assert image.shape == (480, 640, 3) and image.std() > 10
        imageio.imwrite(out / f"{name}.png", image)
