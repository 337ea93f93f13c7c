"""The residual action path, for N robots at once (thesis Fig. 4.1, Section 4.2.5).

Each 200 Hz control step:

1. :meth:`ResidualController.prepare`: the gait clock advances and the kernel maps the velocity command
   and the phases to the four feet's targets A^ref_t in the base frame [m];
2. the policy observes (:meth:`ResidualController.observation_inputs`) and chooses an action in
   [-1, 1]^12;
3. :meth:`ResidualController.joint_targets`: the action, scaled per axis by the residual bound, passes
   through the low-pass filter of Eq. 4.4, ``δA^lpf_t = α δA_t + (1 - α) δA^lpf_{t-1}``, is added to
   A^ref_t, and the analytic IK turns the sum into joint targets for the Table 4.2 PD.

The same object serves training (:mod:`krl.agent.env`), ``krl agent run`` and ``krl evaluate``
(:class:`krl.agent.controller.AgentController`), so the action path cannot differ between them.
"""

from __future__ import annotations

import numpy as np

from krl.agent.config import ACTION_SIZE, ResidualConfig
from krl.agent.observation import ObservationInputs
from krl.control.filters import LowPassFilter
from krl.control.gait import gait_params, leg_phases, normalised_phase
from krl.control.kinematics import inverse_kinematics
from krl.data.columns import input_columns
from krl.kernel.features import features_from_columns
from krl.kernel.model import Kernel
from krl.kernel.settings import training_settings
from krl.robots.a1.constants import NUM_LEGS
from krl.sim.batch import StateBatch
from krl.util.timing import CONTROL_DT

__all__ = ["ACTION_SIZE", "BATCHABLE_VARIANTS", "ResidualController"]

BATCHABLE_VARIANTS: tuple[str, ...] = ("base", "ind", "ext", "dyn1")
"""Kernel variants the residual path runs (kernel-dyn2's 5-step input history is not batched)."""


class ResidualController:
    """Kernel + low-pass-filtered residuals -> joint targets, for ``num_robots`` robots.

    Args:
        kernel: the kernel giving the reference foot targets; its gait, stance duration and (kernel-ext)
            heights are those of its training data.
        config: residual bound and filter α.
        num_robots: N.
    """

    def __init__(self, kernel: Kernel, config: ResidualConfig, num_robots: int) -> None:
        if kernel.variant not in BATCHABLE_VARIANTS:
            raise ValueError(
                f"the residual agent runs kernels of the variants {', '.join(BATCHABLE_VARIANTS)}, "
                f"not kernel-{kernel.variant}"
            )
        self.kernel = kernel
        self.config = config
        trained = training_settings(kernel).expert
        self.gait = gait_params(trained.gait, stance_duration=trained.stance_duration)
        self.step_height = trained.step_height
        self.ride_height = trained.ride_height
        self.bound = np.asarray(config.residual_bound, dtype=float)
        """Residual per unit action, (x, y, z) [m]. Shape: (3,)."""
        self.filter = LowPassFilter((num_robots, NUM_LEGS, 3), config.alpha)
        self.steps = np.zeros(num_robots, dtype=np.int64)
        """Gait clock of each robot: control steps since its reset."""
        self.command = np.zeros((num_robots, 3))
        """Velocity commands of the prepared step. Shape: (N, 3)."""
        self.normalised_phase = np.zeros((num_robots, NUM_LEGS))
        """Normalised phases of the prepared step. Shape: (N, 4)."""
        self.kernel_targets = np.zeros((num_robots, NUM_LEGS, 3))
        """The kernel's foot targets of the prepared step, base frame [m]. Shape: (N, 4, 3)."""

    @property
    def num_robots(self) -> int:
        return len(self.steps)

    @property
    def residual(self) -> np.ndarray:
        """The last filtered residual δA^lpf, base frame [m] (a copy). Shape: (N, 4, 3)."""
        return self.filter.value

    def reset(self, rows: np.ndarray | slice | int = slice(None)) -> None:
        """Restart the gait clock and zero the filter of some robots (all by default)."""
        self.steps[rows] = 0
        self.filter.reset_rows(rows)

    def prepare(self, state: StateBatch, command: np.ndarray, rows: np.ndarray | None = None) -> None:
        """Advance the gait clocks and compute the kernel's targets for the coming step.

        Args:
            state: the current states (:class:`krl.sim.batch.StateBatch`) of the robots in ``rows``.
            command: their velocity commands (v_x, v_y, ω_z) [m/s, m/s, rad/s]. Shape: (n, 3).
            rows: indices of the robots to prepare (n of them); None: all N.
        """
        rows = np.arange(self.num_robots) if rows is None else np.asarray(rows)
        self.steps[rows] += 1
        command = np.asarray(command, dtype=float).reshape(len(rows), 3)
        phases = leg_phases(self.steps[rows] * CONTROL_DT, self.gait)
        normalised = normalised_phase(phases, self.gait.swing_ratio)
        columns = input_columns(state, command, normalised, self.step_height, self.ride_height)
        features = features_from_columns(self.kernel.variant, columns)
        self.command[rows] = command
        self.normalised_phase[rows] = normalised
        self.kernel_targets[rows] = self.kernel.predict(features).reshape(len(rows), NUM_LEGS, 3)

    def observation_inputs(self, state: StateBatch) -> ObservationInputs:
        """What the observation of the prepared step is computed from."""
        return ObservationInputs(
            state, self.command, self.filter.value, self.normalised_phase, self.kernel_targets
        )

    def joint_targets(self, action: np.ndarray) -> np.ndarray:
        """Joint-angle targets [rad] for the prepared step from the actions (clipped to [-1, 1]).

        Shapes: (N, 12) -> (N, 12).
        """
        action = np.asarray(action, dtype=float)
        if action.shape != (self.num_robots, 3 * NUM_LEGS):
            raise ValueError(f"actions must have shape ({self.num_robots}, 12), got {action.shape}")
        if not np.isfinite(action).all():
            raise ValueError("actions must be finite")
        residual = np.clip(action, -1.0, 1.0).reshape(self.num_robots, NUM_LEGS, 3) * self.bound
        filtered = self.filter(residual)
        return inverse_kinematics(self.kernel_targets + filtered).q
