"""The residual action path, for N robots at once (thesis Fig. 4.1, Section 4.2.5).

Each 200 Hz control step:

1. :meth:`ResidualController.prepare`: the gait clock advances and the kernel maps the velocity command
   and the phases to the four feet's targets A^ref_t in the base frame [m];
2. the policy observes (:meth:`ResidualController.observation_inputs`) and chooses an action in
   [-1, 1]^D (:mod:`krl.agent.action` names its parts);
3. :meth:`ResidualController.joint_targets`: the residual part, scaled per axis by the residual bound,
   passes through the low-pass filter of Eq. 4.4, ``δA^lpf_t = α δA_t + (1 - α) δA^lpf_{t-1}``, is added to
   A^ref_t, and the analytic IK turns the sum into joint targets for the Table 4.2 PD. The drive parts
   (if any) pass through their own filter and set the kernel's command and heights and the clock's rate
   from the next step on.

With every drive switched off it is the thesis's agent, bit for bit (tests/agent/test_residual.py).
The same object serves training (:mod:`krl.agent.env`), ``krl agent run`` and ``krl evaluate``
(:class:`krl.agent.controller.AgentController`), so the action path cannot differ between them.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from krl.agent.action import DRIVE_PARTS, action_parts
from krl.agent.config import ResidualConfig
from krl.agent.observation import ObservationInputs
from krl.control.filters import LowPassFilter
from krl.control.gait import gait_params, leg_phases, normalised_phase
from krl.control.kinematics import inverse_kinematics
from krl.data.columns import input_columns
from krl.kernel.features import features_from_columns
from krl.kernel.model import Kernel
from krl.kernel.settings import training_settings
from krl.robots.a1.constants import NUM_LEGS
from krl.sim.state import StateBatch
from krl.util.timing import CONTROL_DT

__all__ = ["BATCHABLE_VARIANTS", "ResidualController"]

BATCHABLE_VARIANTS: tuple[str, ...] = ("base", "ind", "ext", "dyn1")
"""Kernel variants the residual path runs (kernel-dyn2's 5-step input history is not batched)."""


class ResidualController:
    """Kernel + low-pass-filtered residuals (+ driven kernel inputs) -> joint targets, for N robots.

    Args:
        kernel: the kernel giving the reference foot targets; its gait, stance duration and (kernel-ext)
            heights are those of its training data.
        config: the action path (residual bound, filter α, drives).
        num_robots: N.
        rowwise: run the kernel on each robot's row alone (:func:`krl.util.affine.affine`), so a robot's
            targets are those it gets alone (batched evaluation); training batches the rows.
    """

    def __init__(
        self, kernel: Kernel, config: ResidualConfig, num_robots: int, rowwise: bool = False
    ) -> None:
        if kernel.variant not in BATCHABLE_VARIANTS:
            raise ValueError(
                f"the residual agent runs kernels of the variants {', '.join(BATCHABLE_VARIANTS)}, "
                f"not kernel-{kernel.variant}"
            )
        self.kernel = kernel
        self.config = config
        self.rowwise = rowwise
        self.parts = action_parts(config, kernel)
        """The action's parts, in order (:mod:`krl.agent.action`)."""
        trained = training_settings(kernel).expert
        self.gait = gait_params(trained.gait, stance_duration=trained.stance_duration)
        self.bound = np.asarray(config.residual_bound, dtype=float)
        """Residual per unit action, (x, y, z) [m]. Shape: (3,)."""
        self.filter = LowPassFilter((num_robots, NUM_LEGS, 3), config.residual_alpha)
        drives = [part for part in self.parts if part.name in DRIVE_PARTS]
        self._nominal = np.array([0.0, 0.0, 0.0, trained.step_height, trained.ride_height, 1.0])
        self._drive_columns = {
            "command": slice(0, 3),
            "steer": slice(0, 3),
            "heights": slice(3, 5),
            "clock_rate": slice(5, 6),
        }
        ranges = training_settings(kernel).command
        self._command_low, self._command_high = (
            np.array([ranges.vx_range[k], ranges.vy_range[k], ranges.yaw_rate_range[k]]) for k in (0, 1)
        )
        self.drive_filter = LowPassFilter((num_robots, sum(p.size for p in drives)), config.gait_alpha)
        """The drive parts' deviations from their nominal values, filtered (``gait_alpha``)."""
        self.clock = np.zeros(num_robots)
        """Gait clock of each robot [control steps]: +1 per step (the driven rate, if driven) since reset."""
        self.command = np.zeros((num_robots, 3))
        """The task's velocity commands of the prepared step. Shape: (N, 3)."""
        self.kernel_command = np.zeros((num_robots, 3))
        """The velocity commands the kernel received in the prepared step. Shape: (N, 3)."""
        self.normalised_phase = np.zeros((num_robots, NUM_LEGS))
        """Normalised phases of the prepared step. Shape: (N, 4)."""
        self.kernel_targets = np.zeros((num_robots, NUM_LEGS, 3))
        """The kernel's foot targets of the prepared step, base frame [m]. Shape: (N, 4, 3)."""

    @property
    def num_robots(self) -> int:
        return len(self.clock)

    @property
    def residual(self) -> np.ndarray:
        """The last filtered residual δA^lpf, base frame [m] (a copy). Shape: (N, 4, 3)."""
        return self.filter.value

    @property
    def gait_inputs(self) -> np.ndarray:
        """The filtered drives for the coming step: the kernel's command (``drive_command``) or the offset to
        the task's (``drive_steer``), else 0; step height [m] and ride height [m], else the kernel's nominal
        ones; the clock rate, else 1. Shape: (N, 6), columns (v_x, v_y, ω_z, step height, ride height,
        clock rate); :attr:`kernel_command` holds the command the kernel received."""
        values = np.tile(self._nominal, (self.num_robots, 1))
        filtered, start = self.drive_filter.value, 0
        for part in self.parts:
            if part.name in DRIVE_PARTS:
                values[:, self._drive_columns[part.name]] += filtered[:, start : start + part.size]
                start += part.size
        return values

    def reset(self, rows: np.ndarray | slice | int = slice(None)) -> None:
        """Restart the gait clock and zero the filters of some robots (all by default)."""
        self.clock[rows] = 0.0
        self.filter.reset_rows(rows)
        self.drive_filter.reset_rows(rows)

    def prepare(self, state: StateBatch, command: np.ndarray, rows: np.ndarray | None = None) -> None:
        """Advance the gait clocks and compute the kernel's targets for the coming step.

        Args:
            state: the current states (:class:`krl.sim.state.StateBatch`) of the robots in ``rows``.
            command: the task's velocity commands (v_x, v_y, ω_z) [m/s, m/s, rad/s]. Shape: (n, 3).
            rows: indices of the robots to prepare (n of them); None: all N.
        """
        rows = np.arange(self.num_robots) if rows is None else np.asarray(rows)
        command = np.asarray(command, dtype=float).reshape(len(rows), 3)
        kernel_command, step_height, ride_height = command, self._nominal[3], self._nominal[4]
        rate = 1.0
        if self.config.drives_gait:
            inputs = self.gait_inputs[rows]
            kernel_command = command
            if self.config.drive_command:
                kernel_command = inputs[:, :3]
            elif self.config.drive_steer:
                kernel_command = np.clip(command + inputs[:, :3], self._command_low, self._command_high)
            step_height, ride_height, rate = inputs[:, 3], inputs[:, 4], inputs[:, 5]
        self.clock[rows] += rate
        phases = leg_phases(self.clock[rows] * CONTROL_DT, self.gait)
        normalised = normalised_phase(phases, self.gait.swing_ratio)
        columns = input_columns(state, kernel_command, normalised, step_height, ride_height)
        features = features_from_columns(self.kernel.variant, columns)
        self.command[rows] = command
        self.kernel_command[rows] = kernel_command
        self.normalised_phase[rows] = normalised
        targets = self.kernel.predict(features, self.rowwise)
        self.kernel_targets[rows] = targets.reshape(len(rows), NUM_LEGS, 3)

    def observation_inputs(
        self, state: StateBatch, sensed: Mapping[str, np.ndarray] | None = None
    ) -> ObservationInputs:
        """What the observation of the prepared step is computed from; ``sensed``: the sensed features'
        values (:mod:`krl.agent.sensing`), where the observation has any."""
        return ObservationInputs(
            state,
            self.command,
            self.filter.value,
            self.normalised_phase,
            self.kernel_targets,
            self.gait_inputs,
            {} if sensed is None else sensed,
        )

    def joint_targets(self, action: np.ndarray) -> np.ndarray:
        """Joint-angle targets [rad] for the prepared step from the actions (clipped to [-1, 1]); the
        drive parts update the filtered kernel inputs and clock rate of the next step.

        Shapes: (N, D) -> (N, 12), D = ``config.action_size``.
        """
        action = np.asarray(action, dtype=float)
        size = self.config.action_size
        if action.shape != (self.num_robots, size):
            raise ValueError(f"actions must have shape ({self.num_robots}, {size}), got {action.shape}")
        if not np.isfinite(action).all():
            raise ValueError("actions must be finite")
        action = np.clip(action, -1.0, 1.0)
        targets, start, deviations = self.kernel_targets, 0, []
        for part in self.parts:
            numbers = action[:, start : start + part.size]
            start += part.size
            if part.name == "residual":
                residual = numbers.reshape(self.num_robots, NUM_LEGS, 3) * self.bound
                targets = targets + self.filter(residual)
            else:
                deviations.append(part.value(numbers) - np.asarray(part.nominal))
        if deviations:
            self.drive_filter(np.concatenate(deviations, axis=1))
        return inverse_kinematics(targets).q
