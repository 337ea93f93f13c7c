"""How symmetric is the A1 model? Every right body, joint and geom of the compiled ``MjModel`` against the
mirror image of its left partner (FR <-> FL, RR <-> RL), and the trunk against its own mirror image: the
model half of issue 45's mirror check (:mod:`krl.analysis.agent.mirror` holds the physics and whole-loop
halves and the tables).

The only asymmetry is the trunk's inertial frame, taken from Unitree's URDF: its centre of mass lies
2.186 mm to the left (y = +0.002186 m) and its inertia has the products I_xy = 8.39e-5 and
I_yz = 2.51e-5 kg·m², which a mirror-symmetric body has at 0. :func:`symmetric_trunk_model` is the model
with those three numbers zeroed.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from krl.agent.symmetry import JOINT
from krl.robots.a1 import MJCF_PATH
from krl.robots.a1.constants import JOINT_KINDS
from krl.sim.model import BuiltModel
from krl.sim.terrains import add_terrain

REFLECTION: np.ndarray = np.diag([1.0, -1.0, 1.0])
"""S: the reflection through the world's (and the base frame's) x-z plane."""

MODEL_TOLERANCE: float = 1e-9
"""Largest difference between a model number and its mirror partner's that counts as equal [SI units]."""

MIRROR_LEGS: dict[str, str] = {"FR": "FL", "RR": "RL"}
"""Each right leg's name prefix and its left partner's."""


@dataclass(frozen=True)
class Asymmetry:
    """One number of the model that differs from its mirror partner's mirror image."""

    element: str
    """The body, joint or geom (``trunk``, ``FR_thigh``, ``FR_hip geom 0``)."""
    quantity: str
    """What differs: ``centre of mass``, ``inertia``, ``position``, ``axis``, ..."""
    difference: float
    """Largest absolute difference from the mirror image [SI units of the quantity]; for the trunk, its own
    partner, twice its asymmetric part (a centre of mass at y differs from its mirror by 2|y|)."""


def _inertia_matrix(model: mujoco.MjModel, body: int) -> np.ndarray:
    """Body ``body``'s inertia about its centre of mass in its body frame [kg·m²]. Shape: (3, 3)."""
    rot = np.empty(9)
    mujoco.mju_quat2Mat(rot, model.body_iquat[body])
    rot = rot.reshape(3, 3)
    return rot @ np.diag(model.body_inertia[body]) @ rot.T


def _rotation(quat: np.ndarray) -> np.ndarray:
    """The rotation matrix of a quaternion (w, x, y, z). Shape: (4,) -> (3, 3)."""
    rot = np.empty(9)
    mujoco.mju_quat2Mat(rot, np.asarray(quat, dtype=float))
    return rot.reshape(3, 3)


def _axes_difference(rot: np.ndarray, other: np.ndarray) -> float:
    """How far two geom frames differ up to the sign of each axis (every primitive shape is symmetric under
    flipping a local axis): the largest absolute difference of the columns, each matched up to its sign."""
    return float(
        max(
            min(np.abs(rot[:, k] - other[:, k]).max(), np.abs(rot[:, k] + other[:, k]).max())
            for k in range(3)
        )
    )


def _geom_differences(model: mujoco.MjModel, body: int, partner: int) -> list[tuple[str, str, float]]:
    """(element, quantity, difference) for each geom of ``body`` against the mirror of ``partner``'s geom of
    the same rank (for a body that is its own partner: against its own mirror)."""
    geoms = range(model.body_geomadr[body], model.body_geomadr[body] + model.body_geomnum[body])
    partners = range(model.body_geomadr[partner], model.body_geomadr[partner] + model.body_geomnum[partner])
    name = model.body(body).name
    if len(geoms) != len(partners):
        return [(name, "number of geoms", float(abs(len(geoms) - len(partners))))]
    rows = []
    for rank, (geom, other) in enumerate(zip(geoms, partners, strict=True)):
        element = f"{name} geom {rank}"
        for quantity in (
            "type",
            "size",
            "friction",
            "contype",
            "conaffinity",
            "condim",
            "solref",
            "solimp",
            "margin",
        ):
            field = getattr(model, f"geom_{quantity}")
            rows.append(
                (element, quantity, float(np.abs(np.asarray(field[geom], float) - field[other]).max()))
            )
        rows.append(
            (
                element,
                "position",
                float(np.abs(model.geom_pos[geom] - REFLECTION @ model.geom_pos[other]).max()),
            )
        )
        mirrored = REFLECTION @ _rotation(model.geom_quat[other]) @ REFLECTION
        rows.append((element, "orientation", _axes_difference(_rotation(model.geom_quat[geom]), mirrored)))
    return rows


def _body_differences(model: mujoco.MjModel, body: int, partner: int) -> list[tuple[str, str, float]]:
    """(element, quantity, difference) of ``body`` against the mirror image of ``partner``."""
    name = model.body(body).name
    mirrored_rot = REFLECTION @ _rotation(model.body_quat[partner]) @ REFLECTION
    rows = [
        (name, "position", float(np.abs(model.body_pos[body] - REFLECTION @ model.body_pos[partner]).max())),
        (name, "orientation", float(np.abs(_rotation(model.body_quat[body]) - mirrored_rot).max())),
        (name, "mass", float(abs(model.body_mass[body] - model.body_mass[partner]))),
        (
            name,
            "centre of mass",
            float(np.abs(model.body_ipos[body] - REFLECTION @ model.body_ipos[partner]).max()),
        ),
    ]
    mirrored_inertia = REFLECTION @ _inertia_matrix(model, partner) @ REFLECTION
    rows.append((name, "inertia", float(np.abs(_inertia_matrix(model, body) - mirrored_inertia).max())))
    return rows + _geom_differences(model, body, partner)


def _joint_differences(
    model: mujoco.MjModel, joint: str, partner: str, sign: float
) -> list[tuple[str, str, float]]:
    """(element, quantity, difference) of hinge ``joint`` against the mirror of ``partner``, whose angle is
    ``sign`` times ``joint``'s: the mirror of a hinge about axis a is a hinge about -sign S a, its range
    ``sign`` times the partner's; gains, limits and joint properties equal."""
    j, p = model.joint(joint).id, model.joint(partner).id
    dof, pdof = model.jnt_dofadr[j], model.jnt_dofadr[p]
    a, pa = model.actuator(joint).id, model.actuator(partner).id
    mirrored_range = np.sort(sign * model.jnt_range[p])
    mirrored_force = np.sort(sign * model.actuator_forcerange[pa])
    rows = [
        (joint, "axis", float(np.abs(model.jnt_axis[j] + sign * REFLECTION @ model.jnt_axis[p]).max())),
        (joint, "anchor", float(np.abs(model.jnt_pos[j] - REFLECTION @ model.jnt_pos[p]).max())),
        (joint, "range", float(np.abs(model.jnt_range[j] - mirrored_range).max())),
        (
            joint,
            "zero angle",
            float(abs(model.qpos0[model.jnt_qposadr[j]] - sign * model.qpos0[model.jnt_qposadr[p]])),
        ),
        (joint, "force range", float(np.abs(model.actuator_forcerange[a] - mirrored_force).max())),
    ]
    for quantity, field in (
        ("armature", model.dof_armature),
        ("damping", model.dof_damping),
        ("friction loss", model.dof_frictionloss),
    ):
        rows.append((joint, quantity, float(abs(field[dof] - field[pdof]))))
    rows.append((joint, "stiffness", float(abs(model.jnt_stiffness[j] - model.jnt_stiffness[p]))))
    for quantity in ("gainprm", "biasprm", "gear"):
        field = getattr(model, f"actuator_{quantity}")
        rows.append((joint, f"actuator {quantity}", float(np.abs(field[a] - field[pa]).max())))
    return rows


def model_asymmetries(model: mujoco.MjModel, tolerance: float = MODEL_TOLERANCE) -> list[Asymmetry]:
    """Every number of the A1 in ``model`` that differs from the mirror image of its partner's by more than
    ``tolerance``: each right leg's bodies (hip, thigh, calf, foot) and their geoms against the left leg's,
    each right joint and its actuator against the left one's, and the trunk and its geoms against their own
    mirror. Sensors and sites (which exert no force) and the terrain are not compared.

    Returns the asymmetries, largest difference first; an empty list for a mirror-symmetric robot.
    """
    rows = _body_differences(model, model.body("trunk").id, model.body("trunk").id)
    for right, left in MIRROR_LEGS.items():
        for part in ("hip", "thigh", "calf", "foot"):
            rows += _body_differences(
                model, model.body(f"{right}_{part}").id, model.body(f"{left}_{part}").id
            )
        for kind, sign in zip(JOINT_KINDS, JOINT, strict=True):
            rows += _joint_differences(model, f"{right}_{kind}", f"{left}_{kind}", sign)
    found = [Asymmetry(element, quantity, value) for element, quantity, value in rows if value > tolerance]
    return sorted(found, key=lambda a: -a.difference)


def symmetric_trunk_model(terrain: str = "flat", seed: int = 0) -> BuiltModel:
    """:func:`krl.sim.model.build_model`'s model with the trunk made mirror-symmetric: its centre of mass's
    y and its inertia's products I_xy and I_yz set to 0 (the only asymmetries :func:`model_asymmetries`
    finds). For measurements only; krl's robot keeps Unitree's numbers."""
    spec = mujoco.MjSpec.from_file(str(MJCF_PATH))
    trunk = spec.body("trunk")
    centre = np.array(trunk.ipos)
    centre[1] = 0.0
    trunk.ipos = centre
    inertia = np.array(trunk.fullinertia)  # (I_xx, I_yy, I_zz, I_xy, I_xz, I_yz)
    inertia[[3, 5]] = 0.0
    trunk.fullinertia = inertia
    built_terrain = add_terrain(spec, terrain, None, np.random.default_rng(seed))
    return BuiltModel(model=spec.compile(), terrain=built_terrain)
