"""Leg kinematics of the Unitree A1: forward kinematics, Jacobians, foot velocities and analytic IK.

Pure, batched NumPy functions (no MuJoCo). Every array may carry arbitrary leading batch dimensions
``...``; the trailing dimensions follow krl's conventions (:mod:`krl.robots.a1.constants`): legs in the
order FR, FL, RR, RL, joints per leg abduction (axis x), hip (axis y), knee (axis y), so a flat joint
vector ``(..., 12)`` has index ``3 * leg + joint`` and a leg-wise one has shape ``(..., 4, 3)``.
Positions are foot-sphere centres in metres in the base (trunk) frame unless a name says otherwise;
angles are in radians. The equations, frames, IK branch and the handling of unreachable targets are
written out in ``docs/kinematics.md``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from krl.robots.a1.constants import (
    ABDUCTION_OFFSET,
    CALF_LENGTH,
    HIP_OFFSETS,
    JOINT_LOWER,
    JOINT_UPPER,
    LEG_SIDE,
    NUM_JOINTS,
    NUM_LEGS,
    THIGH_LENGTH,
)

__all__ = [
    "IKResult",
    "foot_jacobians",
    "foot_positions",
    "foot_positions_in_hip",
    "foot_velocities",
    "inverse_kinematics",
]

# --- derived constants (computed once, from the constants module) ----------------------------------

_L1 = float(ABDUCTION_OFFSET)
_L2 = float(THIGH_LENGTH)
_L3 = float(CALF_LENGTH)
_LATERAL = LEG_SIDE * ABDUCTION_OFFSET
"""Signed lateral offset of each hip-pitch joint from its abduction axis (+y for left legs) [m]. (4,)"""

_LOWER = JOINT_LOWER.reshape(NUM_LEGS, 3)
_UPPER = JOINT_UPPER.reshape(NUM_LEGS, 3)

_TOL = 1e-9
"""Slack [m or rad] allowed when deciding ``reachable``, so targets exactly on the boundary of the
workspace (as produced by forward kinematics at a joint limit) are not rejected by rounding."""

# Knee: q2 = -arccos(c), c = (L^2 - l2^2 - l3^2) / (2 l2 l3), L = planar hip-to-foot distance.
# Within the knee range [lo, hi] (both in [-pi, 0]) c runs from cos(lo) (folded, L_min) to cos(hi)
# (stretched, L_max).
_KNEE_LO = float(JOINT_LOWER[2])
_KNEE_HI = float(JOINT_UPPER[2])
_C_MIN_LIMITS = float(np.cos(_KNEE_LO))
_C_MAX_LIMITS = float(np.cos(_KNEE_HI))
_REACH_MIN = float(np.sqrt(_L2**2 + _L3**2 + 2.0 * _L2 * _L3 * _C_MIN_LIMITS))
"""Shortest hip-pitch-joint-to-foot distance the knee limits allow [m] (about 0.0883)."""
_REACH_MAX = float(np.sqrt(_L2**2 + _L3**2 + 2.0 * _L2 * _L3 * _C_MAX_LIMITS))
"""Longest hip-pitch-joint-to-foot distance the knee limits allow [m] (about 0.3589)."""

# Abduction and hip angles are wrapped into the 2*pi window centred on their joint range, so an
# out-of-range angle is the one nearest (in the circular sense) to the range it misses.
_AH_LOWER = _LOWER[:, :2]
_AH_UPPER = _UPPER[:, :2]
_AH_CENTRE = 0.5 * (_AH_LOWER + _AH_UPPER)  # (4, 2)

_BRANCH_SIGN = np.array([-1.0, 1.0])
"""Sign of the leg-plane z coordinate in the two abduction branches: index 0 (preferred) has the
foot below the abduction axis in the rotated leg frame, index 1 above it."""


class IKResult(NamedTuple):
    """Result of :func:`inverse_kinematics`.

    Attributes:
        q: joint angles [rad], flat joint order. Shape ``(..., 12)``.
        reachable: whether each leg's target lies in the workspace allowed by the leg geometry and the
            joint limits (to within 1e-9). Shape ``(..., 4)``, dtype bool.
    """

    q: np.ndarray
    reachable: np.ndarray


# --- input checking --------------------------------------------------------------------------------


def _as_float_array(x: object, name: str) -> np.ndarray:
    try:
        a = np.asarray(x)
    except Exception as exc:  # ragged nested sequences and the like
        raise ValueError(f"{name} could not be converted to an array: {exc}".replace("\n", " ")) from None
    if a.dtype.kind not in "iuf":
        raise ValueError(f"{name} must be a real numeric array; got dtype {a.dtype} with shape {a.shape}")
    if a.dtype != np.float64:
        a = a.astype(np.float64)
    return a


def _legwise(x: object, name: str, allow_flat: bool) -> np.ndarray:
    """Check ``x`` and return it as a float64 array of shape ``(..., 4, 3)``."""
    a = _as_float_array(x, name)
    shape = a.shape
    if a.ndim >= 2 and shape[-2] == NUM_LEGS and shape[-1] == 3:
        pass
    elif allow_flat and a.ndim >= 1 and shape[-1] == NUM_JOINTS:
        a = a.reshape(*shape[:-1], NUM_LEGS, 3)
    else:
        expected = "(..., 4, 3) or (..., 12)" if allow_flat else "(..., 4, 3)"
        raise ValueError(f"{name} must have shape {expected}; got shape {shape}")
    if not np.isfinite(a).all():
        raise ValueError(f"{name} must be finite; got non-finite values in an array of shape {shape}")
    return a


# --- forward kinematics ----------------------------------------------------------------------------


def _fk_terms(q: np.ndarray) -> tuple[np.ndarray, ...]:
    """Shared terms of FK and the Jacobian for leg-wise angles ``q`` (..., 4, 3)."""
    q0 = q[..., 0]
    q1 = q[..., 1]
    q12 = q1 + q[..., 2]
    s0 = np.sin(q0)
    c0 = np.cos(q0)
    s12 = np.sin(q12)
    c12 = np.cos(q12)
    # Foot in the leg plane (hip-pitch frame before the abduction rotation), all (..., 4):
    x = -_L2 * np.sin(q1) - _L3 * s12
    z = -_L2 * np.cos(q1) - _L3 * c12
    # Rotate (lateral offset, z) about the abduction (x) axis.
    py = c0 * _LATERAL - s0 * z
    pz = s0 * _LATERAL + c0 * z
    return x, py, pz, z, s0, c0, s12, c12


def foot_positions_in_hip(q: object) -> np.ndarray:
    """Foot positions relative to each leg's abduction-joint origin, in the base frame.

    Args:
        q: joint angles [rad]. Shape ``(..., 4, 3)`` (leg-wise) or ``(..., 12)`` (flat).

    Returns:
        Foot-sphere centres minus ``HIP_OFFSETS`` [m], base-frame axes. Shape ``(..., 4, 3)``.

    Raises:
        ValueError: wrong shape, non-numeric or non-finite ``q``.
    """
    qa = _legwise(q, "q", allow_flat=True)
    x, py, pz = _fk_terms(qa)[:3]
    return np.stack((x, py, pz), axis=-1)


def foot_positions(q: object) -> np.ndarray:
    """Foot positions in the base (trunk) frame.

    Args:
        q: joint angles [rad]. Shape ``(..., 4, 3)`` or ``(..., 12)``.

    Returns:
        Foot-sphere centres [m] in the base frame (origin at the trunk centre, x forward, y left,
        z up). Shape ``(..., 4, 3)``.

    Raises:
        ValueError: wrong shape, non-numeric or non-finite ``q``.
    """
    return foot_positions_in_hip(q) + HIP_OFFSETS


def _jacobians(qa: np.ndarray) -> np.ndarray:
    x, py, pz, z, s0, c0, s12, c12 = _fk_terms(qa)
    zero = np.zeros_like(x)
    k_c = -_L3 * c12
    k_s = _L3 * s12
    # Rows: d(px, py, pz); columns: d/d(abduction, hip, knee).
    jac = np.stack(
        (
            zero, z, k_c,
            -pz, s0 * x, -s0 * k_s,
            py, -c0 * x, c0 * k_s,
        ),
        axis=-1,
    )  # fmt: skip
    return jac.reshape(*x.shape, 3, 3)


def foot_jacobians(q: object) -> np.ndarray:
    """Analytic Jacobians of the base-frame foot positions with respect to each leg's joint angles.

    Args:
        q: joint angles [rad]. Shape ``(..., 4, 3)`` or ``(..., 12)``.

    Returns:
        ``J[..., leg, i, j] = d p[..., leg, i] / d q[..., leg, j]`` [m/rad], ``i`` over base-frame
        x, y, z and ``j`` over abduction, hip, knee. Shape ``(..., 4, 3, 3)``. (A leg's foot does not
        depend on the other legs' joints, so the full 12x12 Jacobian is block diagonal.)

    Raises:
        ValueError: wrong shape, non-numeric or non-finite ``q``.
    """
    return _jacobians(_legwise(q, "q", allow_flat=True))


def foot_velocities(q: object, qd: object) -> np.ndarray:
    """Foot velocities relative to the base, in the base frame: ``J(q) @ qd`` per leg.

    Args:
        q: joint angles [rad]. Shape ``(..., 4, 3)`` or ``(..., 12)``.
        qd: joint velocities [rad/s]. Shape ``(..., 4, 3)`` or ``(..., 12)``; its batch dimensions
            must broadcast with those of ``q``.

    Returns:
        Foot-sphere-centre velocities [m/s] relative to the trunk, base-frame axes (the base's own
        linear and angular velocity are not included). Shape ``(..., 4, 3)`` (broadcast batch).

    Raises:
        ValueError: wrong shape, non-numeric or non-finite input, or batch shapes that do not broadcast.
    """
    jac = _jacobians(_legwise(q, "q", allow_flat=True))
    qda = _legwise(qd, "qd", allow_flat=True)
    try:
        return np.einsum("...ij,...j->...i", jac, qda)
    except ValueError:
        raise ValueError(
            f"q and qd batch shapes do not broadcast; got leg-wise shapes {jac.shape[:-1]} and {qda.shape}"
        ) from None


# --- inverse kinematics ----------------------------------------------------------------------------


def _wrap(angle: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Wrap ``angle`` into ``[centre - pi, centre + pi)``."""
    return np.mod(angle - centre + np.pi, 2.0 * np.pi) - np.pi + centre


def inverse_kinematics(p: object, clip_to_limits: bool = True) -> IKResult:
    """Analytic (closed-form) inverse kinematics for the four legs.

    Conventions (derivation in ``docs/kinematics.md``):

    * Knee-backward branch: the knee angle is ``-arccos(.)``, i.e. in ``[-pi, 0]``, as the A1's knee
      range ``[-2.697, -0.916]`` requires.
    * Abduction branch: of the two abduction angles that put the foot in the leg plane, the one with
      the foot *below* the abduction axis in the rotated leg frame is used, unless it violates the
      abduction/hip limits by more than the other one does.
    * Unreachable targets give a finite answer and ``reachable=False`` for that leg: a target closer
      to the abduction axis than the lateral offset is projected radially onto that cylinder; a
      planar hip-to-foot distance outside the reach is scaled along its direction to the nearest
      reach (the knee-limited reach ``[0.0883, 0.3589]`` m with ``clip_to_limits``, the geometric
      reach ``[|l2 - l3|, l2 + l3]`` without); with ``clip_to_limits`` the angles are then clipped
      into ``[JOINT_LOWER, JOINT_UPPER]``. Without it abduction and hip are only wrapped into the
      2*pi window centred on their range.

    Args:
        p: foot-sphere-centre targets [m] in the base frame. Shape ``(..., 4, 3)``.
        clip_to_limits: clip the solution into the joint limits (default True).

    Returns:
        :class:`IKResult` with ``q`` [rad] of shape ``(..., 12)`` (flat joint order) and
        ``reachable`` of shape ``(..., 4)`` (bool).

    Raises:
        ValueError: wrong shape, non-numeric or non-finite ``p``.
    """
    pa = _legwise(p, "p", allow_flat=False)
    batch = pa.shape[:-2]
    rel = pa - HIP_OFFSETS
    x = rel[..., 0]
    py = rel[..., 1]
    pz = rel[..., 2]

    # Abduction: (py, pz) = Rx(q0) (lateral, z), so py^2 + pz^2 = lateral^2 + z^2.
    r2 = py * py + pz * pz
    ok_cylinder = r2 >= (_L1 - _TOL) ** 2
    z_abs = np.sqrt(np.maximum(r2 - _L1 * _L1, 0.0))  # (..., 4)
    z_br = z_abs[..., None] * _BRANCH_SIGN  # (..., 4, 2): both abduction branches
    q0 = np.arctan2(pz, py)[..., None] - np.arctan2(z_br, _LATERAL[:, None])

    # Knee: planar distance from the hip-pitch joint to the foot (the same in both branches).
    planar2 = x * x + z_abs * z_abs
    c = (planar2 - _L2 * _L2 - _L3 * _L3) / (2.0 * _L2 * _L3)
    planar = np.sqrt(planar2)
    ok_reach = (planar >= _REACH_MIN - _TOL) & (planar <= _REACH_MAX + _TOL)
    if clip_to_limits:
        c = np.clip(c, _C_MIN_LIMITS, _C_MAX_LIMITS)
    else:
        c = np.clip(c, -1.0, 1.0)
    q2 = -np.arccos(c)

    # Hip: (-z) + i(-x) = (a + i b) exp(i q1) with a = l2 + l3 cos q2, b = l3 sin q2.
    a = _L2 + _L3 * c
    b = -_L3 * np.sqrt(1.0 - c * c)
    q1 = np.arctan2(-x[..., None], -z_br) - np.arctan2(b, a)[..., None]

    # Wrap abduction and hip into the windows centred on their ranges; pick the branch.
    q01 = _wrap(np.stack((q0, q1), axis=-1), _AH_CENTRE[:, None, :])  # (..., 4, 2 branches, 2 joints)
    violation = (
        np.maximum(_AH_LOWER[:, None, :] - q01, 0.0) + np.maximum(q01 - _AH_UPPER[:, None, :], 0.0)
    ).sum(axis=-1)  # (..., 4, 2)
    use_upper = violation[..., 1] + _TOL < violation[..., 0]  # (..., 4)
    q01 = np.where(use_upper[..., None], q01[..., 1, :], q01[..., 0, :])  # (..., 4, 2)
    ok_limits = np.minimum(violation[..., 0], violation[..., 1]) <= _TOL

    q = np.concatenate((q01, q2[..., None]), axis=-1)  # (..., 4, 3)
    if clip_to_limits:
        q = np.clip(q, _LOWER, _UPPER)
    reachable = ok_cylinder & ok_reach & ok_limits
    return IKResult(q=q.reshape(*batch, NUM_JOINTS), reachable=reachable)
