"""Unitree A1: the published numbers krl's model and controllers are built from.

Every constant about the robot lives here, once. Numbers come from the A1 URDF published by Unitree
(``shared/reference/a1.urdf``) unless a comment says otherwise; ``docs/model.md`` explains each choice.

Conventions used across krl:

* Legs are ordered FR, FL, RR, RL (front-right, front-left, rear-right, rear-left).
* Each leg has three joints, ordered abduction (hip roll, axis x), hip (thigh pitch, axis y) and
  knee (calf pitch, axis y). A flat joint vector has shape ``(12,)`` with index ``3 * leg + joint``.
* The base frame is the trunk frame: x forward, y left, z up, origin at the trunk's geometric centre
  (the point the hip offsets are measured from).
* A foot position is the centre of the foot sphere.
"""

from __future__ import annotations

import numpy as np

LEG_NAMES: tuple[str, ...] = ("FR", "FL", "RR", "RL")
"""Leg order used by every array in krl."""

JOINT_KINDS: tuple[str, ...] = ("abduction", "hip", "knee")
"""Joint order within a leg."""

JOINT_NAMES: tuple[str, ...] = tuple(f"{leg}_{kind}" for leg in LEG_NAMES for kind in JOINT_KINDS)
"""MJCF joint (and actuator) names in flat joint order. Shape: (12,)."""

FOOT_NAMES: tuple[str, ...] = tuple(f"{leg}_foot" for leg in LEG_NAMES)
"""MJCF foot body, geom, site and sensor names in leg order."""

NUM_LEGS: int = 4
NUM_JOINTS: int = 12

# --- geometry [m] ---------------------------------------------------------------------------------

HIP_OFFSETS: np.ndarray = np.array(
    [[0.183, -0.047, 0.0], [0.183, 0.047, 0.0], [-0.183, -0.047, 0.0], [-0.183, 0.047, 0.0]]
)
"""Abduction-joint origins in the base frame [m]. Shape: (4, 3)."""

LEG_SIDE: np.ndarray = np.array([-1.0, 1.0, -1.0, 1.0])
"""+1 for left legs, -1 for right legs. Shape: (4,)."""

ABDUCTION_OFFSET: float = 0.08505
"""Lateral distance from the abduction axis to the hip (thigh) joint [m]."""

THIGH_LENGTH: float = 0.2
"""Hip joint to knee joint [m]."""

CALF_LENGTH: float = 0.2
"""Knee joint to foot-sphere centre [m]."""

FOOT_RADIUS: float = 0.02
"""Collision radius of the foot sphere [m]."""

TRUNK_HALF_SIZE: np.ndarray = np.array([0.1335, 0.097, 0.057])
"""Half extents of the trunk collision box (URDF: 0.267 x 0.194 x 0.114) [m]. Shape: (3,)."""

# --- masses [kg] ----------------------------------------------------------------------------------

TOTAL_MASS: float = 4.713 + 0.001 + 4 * (0.696 + 0.001 + 1.013 + 0.166 + 0.06)
"""Trunk + IMU + 4 x (hip + shoulder dummy + thigh + calf + foot) [kg] (about 12.458)."""

# --- joint limits ---------------------------------------------------------------------------------

_LEG_LOWER = np.array([-0.802851455917, -1.0471975512, -2.69653369433])
_LEG_UPPER = np.array([0.802851455917, 4.18879020479, -0.916297857297])

JOINT_LOWER: np.ndarray = np.tile(_LEG_LOWER, NUM_LEGS)
"""Lower joint limits [rad]. Shape: (12,)."""

JOINT_UPPER: np.ndarray = np.tile(_LEG_UPPER, NUM_LEGS)
"""Upper joint limits [rad]. Shape: (12,)."""

# --- actuation ------------------------------------------------------------------------------------

MOTOR_TORQUE_LIMIT: float = 33.5
"""Peak output torque of the A1 joint motor [N·m], applied to every joint (docs/model.md)."""

MOTOR_MAX_SPEED: float = 21.0
"""Joint speed at which the motor can no longer add power [rad/s] (A1 product data)."""

MOTOR_FULL_TORQUE_SPEED: float = 10.5
"""Joint speed up to which the full torque is available when motoring [rad/s] (our assumption,
docs/model.md); between this and ``MOTOR_MAX_SPEED`` the motoring torque falls linearly to zero."""

ARMATURE: float = 0.01
"""Reflected rotor inertia added to every joint [kg·m²] (docs/model.md)."""

KP: np.ndarray = np.tile([100.0, 100.0, 100.0], NUM_LEGS)
"""PD stiffness (thesis Table 4.2) [N·m/rad]. Shape: (12,)."""

KD: np.ndarray = np.tile([1.0, 2.0, 2.0], NUM_LEGS)
"""PD damping (thesis Table 4.2) [N·m·s/rad]. Shape: (12,)."""

# --- default pose ---------------------------------------------------------------------------------

STANDING_JOINT_ANGLES: np.ndarray = np.tile([0.0, 0.9, -1.8], NUM_LEGS)
"""Default standing pose [rad]. Shape: (12,). The feet are then 0.2486 m below the hips."""

STANDING_HEIGHT: float = float(
    THIGH_LENGTH * np.cos(STANDING_JOINT_ANGLES[1])
    + CALF_LENGTH * np.cos(STANDING_JOINT_ANGLES[1] + STANDING_JOINT_ANGLES[2])
    + FOOT_RADIUS
)
"""Height of the base origin above flat ground in the standing pose [m] (about 0.269)."""

STANDING_INERTIA: np.ndarray = np.array(
    [[0.1422, -0.0001, -0.0102], [-0.0001, 0.3881, -0.0002], [-0.0102, -0.0002, 0.4206]]
)
"""Whole-robot inertia about its centre of mass in the standing pose, trunk axes [kg·m²]. Shape: (3, 3).
Computed from the MJCF's bodies (tests/sim/test_robot.py checks it); the MPC's rigid body."""

FOOT_FRICTION: float = 1.0
"""Sliding friction coefficient of feet and ground (thesis 4.2.1)."""
