"""Terrain geoms: every geom a terrain adds collides with the robot only, with the same friction.

Every terrain geom has ``contype=0, conaffinity=1`` (it collides with the robot, whose geoms have
``contype=1, conaffinity=0``, and with nothing else), ``condim=3``, the friction :data:`TERRAIN_FRICTION`
(sliding μ :data:`krl.robots.a1.constants.FOOT_FRICTION` unless the terrain's ``friction`` parameter says
otherwise, :func:`set_ground_friction`) and priority :data:`TERRAIN_PRIORITY`.
"""

from __future__ import annotations

import math
from typing import Any

import mujoco
import numpy as np

from krl.robots.a1.constants import FOOT_FRICTION

__all__ = [
    "TERRAIN_FRICTION",
    "TERRAIN_PRIORITY",
    "add_floor",
    "add_geom",
    "set_ground_friction",
    "spec_angle",
]

TERRAIN_FRICTION: np.ndarray = np.array([FOOT_FRICTION, 0.005, 0.0001])
"""Sliding, torsional and rolling friction of every terrain geom (sliding as thesis 4.2.1; the other two
are MuJoCo's defaults, as on the robot's feet)."""

TERRAIN_PRIORITY: int = 1
"""MuJoCo ``priority`` of every terrain geom, above the robot's 0: a contact between geoms of different
priority takes its friction (and condim, solref, solimp) from the higher one, where equal priorities take
the elementwise maximum of the two frictions. So the ground's μ is the contact's, also below the robot's 1;
the robot's geoms have the terrain's condim, solref and solimp, so at μ = 1 every contact is as with equal
priorities."""


def add_geom(parent, name: str, gtype: mujoco.mjtGeom, material: str, **attrs: Any):
    """A terrain geom named ``name`` of type ``gtype`` with ``material``, added to body ``parent`` (an
    ``MjsBody``); ``attrs`` set further ``MjsGeom`` attributes (pos [m], size [m], mass [kg]...)."""
    geom = parent.add_geom()
    geom.name = name
    geom.type = gtype
    geom.contype = 0
    geom.conaffinity = 1
    geom.condim = 3
    geom.friction = TERRAIN_FRICTION.copy()
    geom.priority = TERRAIN_PRIORITY
    geom.material = material
    for key, value in attrs.items():
        setattr(geom, key, value)
    return geom


def spec_angle(spec: mujoco.MjSpec, radians: float) -> float:
    """An angle in the spec's unit (``compiler.degree``; MjSpec() defaults to degrees, the A1 MJCF uses
    radians)."""
    return math.degrees(radians) if spec.compiler.degree else radians


def add_floor(spec: mujoco.MjSpec, z: float = 0.0, material: str = "krl_floor") -> str:
    """Add the infinite floor plane at height ``z`` [m]; returns its geom name."""
    add_geom(
        spec.worldbody, "floor", mujoco.mjtGeom.mjGEOM_PLANE, material, pos=[0.0, 0.0, z], size=[0, 0, 1]
    )
    return "floor"


def set_ground_friction(spec: mujoco.MjSpec, names: tuple[str, ...], friction: float) -> None:
    """Set the sliding friction μ [-] of the geoms ``names`` of ``spec`` (a terrain's, as
    :attr:`krl.sim.terrains.Terrain.geom_names`); their torsional and rolling friction stay
    :data:`TERRAIN_FRICTION`'s."""
    for name in names:
        geom = spec.geom(name)
        geom.friction = [friction, *geom.friction[1:]]
