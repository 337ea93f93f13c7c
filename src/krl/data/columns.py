"""Dataset columns computed from a simulator state: the one builder of a kernel's input row.

Data collection (:mod:`krl.data.collect`) records these columns; the kernel controller and the residual
agent build the same columns from the state they see and hand them to
:func:`krl.kernel.features.features_from_columns`, so the kernel's inputs in training and in control
cannot differ. The names are :mod:`krl.data.schema`'s.
"""

from __future__ import annotations

import numpy as np

from krl.robots.a1.constants import NUM_LEGS


def input_columns(
    state,
    command: np.ndarray,
    normalised_phase: np.ndarray,
    step_height: float | np.ndarray = 0.0,
    ride_height: float | np.ndarray = 0.0,
) -> dict[str, np.ndarray]:
    """The dataset columns (:mod:`krl.data.schema` names) that the kernel variants read, for one control
    step or a batch of them: the one builder of a kernel's input row, used by data collection, the
    kernel controller and the residual agent.

    Args:
        state: the state the controller saw: a :class:`krl.sim.state.RobotState`, or a
            :class:`krl.sim.state.StateBatch` of N robots.
        command: velocity command (v_x, v_y, ω_z) [m/s, m/s, rad/s]. Shape: (3,) or (N, 3).
        normalised_phase: the gait's normalised phases |φ| (Eq. 4.6) of the step. Shape: (4,) or (N, 4).
        step_height, ride_height: kernel-ext's height inputs [m] (scalars or shape (N,)).

    Returns:
        ``{column: array}`` with a leading row axis (1 row for a single state, N for a batch).
    """
    command = np.asarray(command, dtype=np.float64).reshape(-1, 3)
    rows = len(command)
    normalised = np.asarray(normalised_phase, dtype=np.float64).reshape(rows, NUM_LEGS)
    relative_com = state.com - state.base_pos
    if relative_com.ndim == 1:
        com = relative_com @ state.base_rot
    else:
        com = np.matmul(relative_com[:, None, :], state.base_rot)[:, 0, :]
    return {
        "v_cmd": command[:, :2],
        "yaw_cmd": command[:, 2],
        "normalised_phase": normalised,
        "sine_phase": np.sin(normalised * np.pi),
        "step_height": np.broadcast_to(np.asarray(step_height, dtype=np.float64), (rows,)),
        "ride_height": np.broadcast_to(np.asarray(ride_height, dtype=np.float64), (rows,)),
        "base_lin_vel": state.lin_vel_base.reshape(rows, 3),
        "base_ang_vel": state.ang_vel_base.reshape(rows, 3),
        "q": state.joint_pos.reshape(rows, 12),
        "dq": state.joint_vel.reshape(rows, 12),
        "com": com.reshape(rows, 3),
        "projected_gravity": state.projected_gravity.reshape(rows, 3),
    }
