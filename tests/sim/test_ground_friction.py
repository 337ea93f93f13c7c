"""The terrains' ground friction: it reaches MuJoCo's contacts, and μ = 1 changes nothing."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from krl.robots.a1 import MJCF_PATH
from krl.robots.a1 import constants as C
from krl.sim.terrains import (
    TERRAIN_FRICTION,
    TERRAIN_NAMES,
    TERRAIN_PRIORITY,
    TerrainError,
    add_terrain,
)

INCLINE = 0.3
"""Angle of the test's slope [rad]: tan 0.3 = 0.309."""


def block_on_slope(friction: float, tilted_gravity: bool = False) -> float:
    """How far [m] a 10 cm cube of 1 kg, set at rest on a slope of :data:`INCLINE` whose ground has the
    friction ``friction``, moves in 1 s. The slope is the ``slope`` terrain's ramp (a height field), or with
    ``tilted_gravity`` the ``flat`` terrain's plane under gravity tilted by the incline (the same slope in
    the plane's frame, with the exact contacts of a box on a plane). The cube's own friction is the robot's
    (1), so it is the terrain's μ that must decide."""
    spec = mujoco.MjSpec()
    half = 0.05
    if tilted_gravity:
        add_terrain(spec, "flat", {"friction": friction})
        spec.option.gravity = [-9.81 * math.sin(INCLINE), 0.0, -9.81 * math.cos(INCLINE)]
        body = spec.worldbody.add_body(pos=[0.0, 0.0, half])
    else:
        terrain = add_terrain(spec, "slope", {"incline": INCLINE, "friction": friction})
        x = 2.5  # the ramp rises from x = 1 to 1 + run = 4 m
        body = spec.worldbody.add_body(
            pos=[x, 0.0, float(terrain.height(x, 0.0)) + half / math.cos(INCLINE)],
            quat=[math.cos(-INCLINE / 2), 0.0, math.sin(-INCLINE / 2), 0.0],  # its bottom along the ramp
        )
    body.add_freejoint()
    body.add_geom(
        type=mujoco.mjtGeom.mjGEOM_BOX,
        size=[half] * 3,
        mass=1.0,
        contype=1,
        conaffinity=0,
        friction=[1.0, 0.005, 0.0001],
    )
    model = spec.compile()
    data = mujoco.MjData(model)
    start = data.qpos[:3].copy()
    mujoco.mj_step(model, data, round(1.0 / model.opt.timestep))
    return float(np.linalg.norm(data.qpos[:3] - start))


@pytest.mark.parametrize("tilted_gravity", [False, True])
def test_a_block_slides_on_a_slope_below_tan_theta_and_holds_above(tilted_gravity):
    tan = math.tan(INCLINE)
    assert block_on_slope(tan - 0.05, tilted_gravity) > 0.1
    assert block_on_slope(tan + 0.05, tilted_gravity) < 0.005  # holds (a soft contact creeps by millimetres)
    assert block_on_slope(1.0, tilted_gravity) < 0.005


@pytest.mark.parametrize("friction", [0.1, 0.2])
def test_a_sliding_block_slows_by_the_grounds_friction(friction):
    expected = 0.5 * 9.81 * (math.sin(INCLINE) - friction * math.cos(INCLINE))  # s = a t² / 2 at t = 1 s
    assert block_on_slope(friction, tilted_gravity=True) == pytest.approx(expected, rel=0.02)


def robot_on(name: str, priority: int | None = None) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The A1 standing on terrain ``name`` (default friction); ``priority`` overrides the terrain geoms'
    (0: the model as krl built it before the friction parameter)."""
    spec = mujoco.MjSpec.from_file(str(MJCF_PATH))
    terrain = add_terrain(spec, name, None, np.random.default_rng(0))
    if priority is not None:
        for geom in terrain.geom_names:
            spec.geom(geom).priority = priority
    model = spec.compile()
    data = mujoco.MjData(model)
    x, y = terrain.spawn_xy
    data.qpos[0:3] = [x, y, float(terrain.height(x, y)) + C.STANDING_HEIGHT + 0.02]
    data.qpos[7:19] = C.STANDING_JOINT_ANGLES
    data.ctrl[:] = C.KP * C.STANDING_JOINT_ANGLES
    return model, data


@pytest.mark.parametrize("name", ["flat", "heightfield"])
def test_the_default_friction_makes_the_contacts_of_equal_priorities(name):
    model, data = robot_on(name)
    before, data_before = robot_on(name, priority=0)
    for m, d in ((model, data), (before, data_before)):
        mujoco.mj_step(m, d, 300)  # land and stand
    assert data.ncon > 0
    contacts = data.contact[: data.ncon]
    assert np.array_equal(contacts.friction, np.tile([1.0, 1.0, 0.005, 0.0001, 0.0001], (data.ncon, 1)))
    old = data_before.contact[: data_before.ncon]
    for key in ("friction", "solref", "solimp", "dim", "includemargin"):
        assert np.array_equal(getattr(contacts, key), getattr(old, key)), key
    assert np.array_equal(data.qpos, data_before.qpos)  # bit for bit


@pytest.mark.parametrize("name", TERRAIN_NAMES)
def test_every_terrain_geom_takes_the_friction(name):
    spec = mujoco.MjSpec.from_file(str(MJCF_PATH))
    terrain = add_terrain(spec, name, {"friction": 0.4})
    model = spec.compile()
    ground = [i for i in range(model.ngeom) if model.geom_contype[i] == 0 and model.geom_conaffinity[i] == 1]
    assert sorted(model.geom(i).name for i in ground) == sorted(terrain.geom_names)
    for i in ground:
        assert model.geom_friction[i].tolist() == [0.4, *TERRAIN_FRICTION[1:]]
        assert model.geom_priority[i] == TERRAIN_PRIORITY
    robot = [i for i in range(model.ngeom) if i not in ground]
    assert robot and all(model.geom_priority[i] < TERRAIN_PRIORITY for i in robot)
    assert terrain.params["friction"] == 0.4
    assert "friction" not in add_terrain(mujoco.MjSpec(), name).params  # the default is not listed


@pytest.mark.parametrize("value", [0, -0.5, float("nan"), 6.0, True, "1"])
def test_a_bad_friction_is_one_line_naming_the_parameter(value):
    with pytest.raises(TerrainError) as error:
        add_terrain(mujoco.MjSpec(), "flat", {"friction": value})
    message = str(error.value)
    assert "'friction'" in message and "terrain 'flat'" in message and "\n" not in message
