"""The A1's left-right mirror: one home for how every observation feature and action part reflects.

The A1 is symmetric about its sagittal plane, the base frame's x-z plane, but for its trunk's inertial
frame (``tests/analysis/agent/test_mirror_physics.py`` measures how much, docs/agent-robust.md).
Reflecting a state through that plane swaps the legs FR <-> FL and RR <-> RL and negates every lateral (y)
component of a polar vector and the x and z components of an axial one (angular velocity, roll, yaw).
Every mirror here is a *signed permutation* ``mirrored[i] = sign[i] * x[index[i]]``, so it is linear,
exact in floating point, and its own inverse.

============================= ==================================================================
kind                          mirror
============================= ==================================================================
polar vector (x, y, z)        (x, -y, z): linear velocity, gravity direction, a foot's residual or target
axial vector (x, y, z)        (-x, y, -z): angular velocity (roll and yaw rates)
command (v_x, v_y, ω_z)       (v_x, -v_y, -ω_z)
roll, pitch                   (-roll, pitch)
per-leg joint (ab, hip, kn)   legs swapped, abduction negated (its axis is the base x axis), hip and knee kept
per-leg scalar                legs swapped: contacts, contact forces, gait phases
heights, clock rate           unchanged
height scan (x_i, y_j)        the value at (x_i, -y_j): the grid mirrored left-right
friction, terrain level       unchanged; a push's force is a polar vector
============================= ==================================================================

The gait phases swap with the legs: in a trot (FR with RL, FL with RR, half a period apart) the mirrored
robot's clock is the original's shifted by half a period, a state of the same gait.

A value function is mirror-invariant (the reward terms measure speeds, heights and attitudes, which the
reflection maps onto themselves under the mirrored command), and so is a push's survival.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from krl.robots.a1.constants import NUM_LEGS

LEG_MIRROR: tuple[int, ...] = (1, 0, 3, 2)
"""The leg each leg becomes in the mirror, in LEG_NAMES order (FR, FL, RR, RL)."""


class MirrorError(ValueError):
    """A feature or action part the mirror does not know, or one whose range is not mirror-symmetric."""


@dataclass(frozen=True)
class SignedPermutation:
    """``mirrored[..., i] = sign[i] * x[..., index[i]]``: the reflection of a vector of ``size`` numbers."""

    index: np.ndarray
    """Source position of each number. Shape: (size,), int."""
    sign: np.ndarray
    """+1 or -1 per number. Shape: (size,), float."""

    @property
    def size(self) -> int:
        return len(self.index)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """Mirror the last axis of ``x``. Shape: (..., size) -> (..., size), NumPy or a torch tensor."""
        if hasattr(x, "new_tensor"):  # torch: index and sign as tensors on x's device
            return x[..., x.new_tensor(self.index).long()] * x.new_tensor(self.sign)
        return x[..., self.index] * self.sign

    def matrix(self) -> np.ndarray:
        """The permutation as a (size, size) matrix M with ``mirrored = M @ x``."""
        matrix = np.zeros((self.size, self.size))
        matrix[np.arange(self.size), self.index] = self.sign
        return matrix

    @staticmethod
    def concatenate(parts: Sequence[SignedPermutation]) -> SignedPermutation:
        """The mirror of the concatenation of vectors, each mirrored by its part."""
        indices, signs, start = [], [], 0
        for part in parts:
            indices.append(part.index + start)
            signs.append(part.sign)
            start += part.size
        if not parts:
            return SignedPermutation(np.zeros(0, dtype=np.int64), np.zeros(0))
        return SignedPermutation(np.concatenate(indices), np.concatenate(signs))


def _signs(signs: Sequence[float]) -> SignedPermutation:
    """A mirror that keeps every number in place and multiplies it by its sign."""
    return SignedPermutation(np.arange(len(signs)), np.asarray(signs, dtype=float))


def _per_leg(signs: Sequence[float]) -> SignedPermutation:
    """A mirror of a leg-major (4 × k) vector: legs swapped by :data:`LEG_MIRROR`, each leg's k numbers
    multiplied by ``signs``."""
    k = len(signs)
    index = np.array([LEG_MIRROR[leg] * k + j for leg in range(NUM_LEGS) for j in range(k)])
    return SignedPermutation(index, np.tile(np.asarray(signs, dtype=float), NUM_LEGS))


POLAR = (1.0, -1.0, 1.0)
"""Signs of a polar vector's (x, y, z) in the mirror."""
AXIAL = (-1.0, 1.0, -1.0)
"""Signs of an axial vector's (x, y, z) (an angular velocity) in the mirror."""
COMMAND = (1.0, -1.0, -1.0)
"""Signs of a velocity command's (v_x, v_y, ω_z) in the mirror."""
JOINT = (-1.0, 1.0, 1.0)
"""Signs of a leg's (abduction, hip, knee) angles or rates in the mirror (after the legs swap)."""

FEATURE_MIRRORS: dict[str, SignedPermutation] = {
    "base_lin_vel": _signs(POLAR),
    "base_ang_vel": _signs(AXIAL),
    "command": _signs(COMMAND),
    "joint_pos": _per_leg(JOINT),
    "joint_vel": _per_leg(JOINT),
    "gravity": _signs(POLAR),
    "roll_pitch": _signs((-1.0, 1.0)),
    "residual": _per_leg(POLAR),
    "foot_contact": _per_leg((1.0,)),
    "phase": _per_leg((1.0,)),
    "kernel_targets": _per_leg(POLAR),
    "contact_force": _per_leg((1.0,)),
    "kernel_command": _signs(COMMAND),
    "heights": _signs((1.0, 1.0)),
    "clock_rate": _signs((1.0,)),
    "ground_friction": _signs((1.0,)),
    "push_force": _signs(POLAR),
    "terrain_level": _signs((1.0,)),
}
"""The mirror of every observation feature of :data:`krl.agent.observation.FEATURES` of a fixed size, by
name; the height scans' depends on their grid (:func:`scan_mirror`)."""

SCAN_FEATURES: tuple[str, ...] = ("height_scan", "height_scan_clean")
"""The features whose mirror is :func:`scan_mirror`."""


def scan_mirror(scan) -> SignedPermutation:
    """The mirror of a height scan on the grid of ``scan`` (a :class:`krl.agent.config.ScanConfig`): point
    ``(x_i, y_j)`` takes the value of ``(x_i, -y_j)``, the grid's y being symmetric; heights keep their
    sign."""
    ny = len(scan.y)
    index = np.array([i * ny + (ny - 1 - j) for i in range(len(scan.x)) for j in range(ny)])
    return SignedPermutation(index, np.ones(len(index)))


ACTION_PART_MIRRORS: dict[str, SignedPermutation] = {
    "residual": _per_leg(POLAR),
    "command": _signs(COMMAND),
    "steer": _signs(COMMAND),
    "heights": _signs((1.0, 1.0)),
    "clock_rate": _signs((1.0,)),
}
"""The mirror of every action part of :mod:`krl.agent.action`, in physical units, by name. A part's action
numbers mirror the same way where its range is symmetric about its nominal value wherever the sign is -1
(:func:`action_mirror` checks)."""


def observation_mirror(features: Sequence[str], scan=None) -> SignedPermutation:
    """The mirror of an observation of ``features`` (in order; ``scan``: the height scans' grid, a
    :class:`krl.agent.config.ScanConfig`, needed where they are observed); MirrorError for a feature it
    lacks."""
    missing = [name for name in features if name not in FEATURE_MIRRORS and name not in SCAN_FEATURES]
    if scan is None and any(name in SCAN_FEATURES for name in features):
        raise MirrorError("a height scan's mirror needs its grid (observation.scan)")
    if missing:
        raise MirrorError(f"no mirror for observation feature {missing[0]!r}")
    return SignedPermutation.concatenate(
        [scan_mirror(scan) if name in SCAN_FEATURES else FEATURE_MIRRORS[name] for name in features]
    )


def action_mirror(parts) -> SignedPermutation:
    """The mirror of an action of ``parts`` (:func:`krl.agent.action.action_parts`, in order).

    An action number in [-1, 1] maps piecewise-linearly onto ``[low, nominal, high]``; its mirror is the
    action's negation only where the part's range is symmetric (``nominal - low == high - nominal``, nominal
    0) for every number the mirror negates.

    Raises:
        MirrorError: a part without a mirror, or a negated number whose range is not symmetric about 0.
    """
    mirrors = []
    for part in parts:
        mirror = ACTION_PART_MIRRORS.get(part.name)
        if mirror is None or mirror.size != part.size:
            raise MirrorError(f"no mirror for action part {part.name!r} of {part.size} numbers")
        for i in np.flatnonzero(mirror.sign < 0):
            low, nominal, high = part.low[i], part.nominal[i], part.high[i]
            if nominal != 0 or not np.isclose(-low, high):
                raise MirrorError(
                    f"action part {part.name!r} number {part.labels[i]!r} has the range "
                    f"[{low:g}, {high:g}] around {nominal:g}, which the mirror's sign flip does not keep"
                )
        mirrors.append(mirror)
    return SignedPermutation.concatenate(mirrors)
