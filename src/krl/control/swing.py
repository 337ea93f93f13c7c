"""Raibert swing-foot control (thesis Section 4.2.6.1, Eq. 4.5; Fig. 4.6b).

A swinging foot follows a path from its lift-off position to a landing point chosen by the Raibert
heuristic: horizontally a straight line, vertically a parabola through lift-off, an apex ``step_height``
above the default foot height, and the landing point. The path is timed so that 80 % of it is covered
in the first half of the swing (``remap_swing_phase``), which leaves the second half for an accurate,
gentle landing. All positions are in the base frame [m]; shapes broadcast over leading dimensions.
"""

from __future__ import annotations

import numpy as np

from krl.robots.a1.constants import ABDUCTION_OFFSET, FOOT_RADIUS, HIP_OFFSETS, LEG_SIDE

NOMINAL_FOOT_XY: np.ndarray = HIP_OFFSETS[:, :2] + np.stack(
    [np.zeros(4), LEG_SIDE * ABDUCTION_OFFSET], axis=1
)
"""Default (neutral) foot position in the horizontal plane of the base frame: under the hip joint [m].
Shape: (4, 2)."""

PATH_AT_HALF_SWING: float = 0.8
"""Fraction of the swing path covered at half the swing time."""


def remap_swing_phase(fraction: np.ndarray) -> np.ndarray:
    """Swing time fraction (0..1) -> path fraction (0..1): 0.8 sin(π s) for s <= 0.5, then linear to 1."""
    s = np.asarray(fraction, dtype=float)
    return np.where(
        s <= 0.5,
        PATH_AT_HALF_SWING * np.sin(np.pi * s),
        PATH_AT_HALF_SWING + (s - 0.5) * 2.0 * (1.0 - PATH_AT_HALF_SWING),
    )


def parabola_through(u: np.ndarray, start: np.ndarray, apex: np.ndarray, end: np.ndarray) -> np.ndarray:
    """Value at ``u`` of the parabola through (0, start), (0.5, apex), (1, end)."""
    a = 2.0 * start - 4.0 * apex + 2.0 * end
    b = -3.0 * start + 4.0 * apex - end
    return a * u * u + b * u + start


def swing_position(
    fraction: np.ndarray, lift_off: np.ndarray, landing: np.ndarray, apex_z: np.ndarray
) -> np.ndarray:
    """Foot target during swing [m].

    Args:
        fraction: elapsed fraction of the swing time, 0..1. Shape: (...,).
        lift_off: foot position when the swing began. Shape: (..., 3).
        landing: landing target. Shape: (..., 3).
        apex_z: height of the path's midpoint (base-frame z). Shape: (...,).
    Returns: shape (..., 3).
    """
    u = remap_swing_phase(fraction)
    lift_off = np.asarray(lift_off, dtype=float)
    landing = np.asarray(landing, dtype=float)
    xy = (1.0 - u)[..., None] * lift_off[..., :2] + u[..., None] * landing[..., :2]
    z = parabola_through(u, lift_off[..., 2], np.asarray(apex_z, dtype=float), landing[..., 2])
    return np.concatenate((xy, z[..., None]), axis=-1)


def raibert_landing(
    hip_velocity: np.ndarray,
    hip_velocity_command: np.ndarray,
    stance_duration: float,
    ride_height: float,
    gain: float,
) -> np.ndarray:
    """Landing targets of the four feet, base frame [m]. Shape: (4, 3).

    ``p_land = p_nominal + v_hip τ_stance / 2 − k (v_cmd,hip − v_hip)`` horizontally (our reading of
    Eq. 4.5, docs/expert.md): the foot lands half a stance ahead of the hip's motion, displaced against
    the velocity error so that a too-slow robot tips forward and speeds up; vertically it lands on the
    ground at ``ride_height`` below the base origin.

    Args:
        hip_velocity: hip velocities in the base frame [m/s]. Shape: (4, 3).
        hip_velocity_command: commanded hip velocities in the base frame [m/s]. Shape: (4, 3).
        stance_duration: τ_stance [s].
        ride_height: base-origin height above the ground [m].
        gain: Raibert feedback gain k [s].
    """
    xy = (
        NOMINAL_FOOT_XY
        + hip_velocity[:, :2] * (stance_duration / 2.0)
        - gain * (hip_velocity_command[:, :2] - hip_velocity[:, :2])
    )
    z = np.full((4, 1), -ride_height + FOOT_RADIUS)
    return np.concatenate((xy, z), axis=1)
