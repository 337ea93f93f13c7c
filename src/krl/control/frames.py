"""Frame helpers: quantities of the trunk expressed in its heading frame.

The heading frame is the world frame turned by the trunk's yaw about the vertical: x forward along the
heading, y to the left, z up. Velocity commands (Algorithm 2) live in it, so the realised velocity the
reward compares them with is expressed in it too.
"""

from __future__ import annotations

import numpy as np


def heading_velocity(lin_vel_world: np.ndarray, yaw: np.ndarray, yaw_rate: np.ndarray) -> np.ndarray:
    """(v_x, v_y) in the heading frame [m/s] and the yaw rate [rad/s].

    Args:
        lin_vel_world: trunk linear velocity in the world frame [m/s]. Shape: (..., 3).
        yaw: trunk yaw [rad]. Shape: (...).
        yaw_rate: world-frame angular velocity about z [rad/s]. Shape: (...).

    Returns:
        Shape: (..., 3).
    """
    c, s = np.cos(yaw), np.sin(yaw)
    vx, vy = lin_vel_world[..., 0], lin_vel_world[..., 1]
    return np.stack((c * vx + s * vy, -s * vx + c * vy, np.asarray(yaw_rate, dtype=float)), axis=-1)


def realised_velocity(state) -> np.ndarray:
    """(v_x, v_y) of the trunk in its heading frame [m/s] and the yaw rate [rad/s] of a
    :class:`krl.sim.state.RobotState` (shape (3,)) or a :class:`krl.sim.state.StateBatch` (shape (N, 3))."""
    return heading_velocity(state.lin_vel_world, state.rpy[..., 2], state.ang_vel_world[..., 2])
