"""The kernel as a walking controller: gait clock + command -> kernel -> foot targets -> IK -> PD.

Each control step the gait generator advances, the kernel maps (command, phases[, heights, state]) to
the four feet's positions in the base frame, the analytic IK turns them into joint targets, and the
Table 4.2 PD tracks them at 1 kHz. Features are built by the same function that built the training
features (:func:`krl.kernel.features.features_from_columns`), so the two cannot drift apart.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from krl.control.expert import RIDE_HEIGHT_RANGE, STEP_HEIGHT_RANGE
from krl.control.gait import GaitGenerator, gait_params
from krl.control.kinematics import inverse_kinematics
from krl.control.types import JointCommand
from krl.data.columns import input_columns
from krl.kernel.features import HISTORY, features_from_columns, input_names
from krl.kernel.model import Kernel
from krl.kernel.settings import training_settings
from krl.robots.a1.constants import NUM_LEGS
from krl.sim.state import RobotState


class KernelController:
    """Implements :class:`krl.control.types.Controller` with a trained kernel.

    Args:
        kernel: the trained kernel.
        gait: gait name; default: the gait of the kernel's training data.
        stance_duration: τ_stance [s]; default: that of the training data.
        step_height, ride_height: kernel-ext's height inputs [m]; default: the expert settings of the
            training data (for ext data, the nominal heights). A variant without height inputs refuses
            them (ValueError) rather than ignoring them.
    """

    def __init__(
        self,
        kernel: Kernel,
        gait: str | None = None,
        stance_duration: float | None = None,
        step_height: float | None = None,
        ride_height: float | None = None,
    ) -> None:
        self.kernel = kernel
        trained = training_settings(kernel).expert
        gait = trained.gait if gait is None else gait
        stance_duration = trained.stance_duration if stance_duration is None else stance_duration
        self.gait_name: str = gait
        """Name of the gait fed to the kernel (Table 4.1)."""
        self.gait = GaitGenerator(gait_params(gait, stance_duration=stance_duration))
        self.takes_heights: bool = "step_height" in input_names(kernel.variant)
        """Whether the kernel has step and ride height inputs (kernel-ext)."""
        if not self.takes_heights and (step_height is not None or ride_height is not None):
            raise self._no_heights()
        self.step_height = float(trained.step_height if step_height is None else step_height)
        self.ride_height = float(trained.ride_height if ride_height is None else ride_height)
        if self.takes_heights:
            self.set_heights(self.step_height, self.ride_height)
        self._history: deque[dict[str, np.ndarray]] = deque(maxlen=HISTORY)
        self.last_targets: np.ndarray | None = None
        """Foot targets of the last step, base frame [m]. Shape: (4, 3)."""

    def set_heights(self, step_height: float, ride_height: float) -> None:
        """Set kernel-ext's step and ride height inputs [m] (validated against the training ranges)."""
        if not self.takes_heights:
            raise self._no_heights()
        for name, value, (low, high) in (
            ("step_height", step_height, STEP_HEIGHT_RANGE),
            ("ride_height", ride_height, RIDE_HEIGHT_RANGE),
        ):
            if not low <= value <= high:
                raise ValueError(f"{name} must be in [{low}, {high}] m, got {value}")
        self.step_height, self.ride_height = float(step_height), float(ride_height)

    def _no_heights(self) -> ValueError:
        return ValueError(
            f"kernel-{self.kernel.variant} has no step or ride height input (only kernel-ext has them)"
        )

    def reset(self, state: RobotState) -> None:
        self.gait.reset()
        self._history.clear()
        self.last_targets = None

    def foot_targets(self, state: RobotState, command: np.ndarray) -> np.ndarray:
        """Advance the gait clock and return the kernel's foot targets, base frame [m]. Shape: (4, 3)."""
        self.gait.step()
        row = input_columns(state, command, self.gait.normalised_phases, self.step_height, self.ride_height)
        variant = self.kernel.variant
        if variant == "dyn2":
            self._history.append(row)
            rows = [self._history[0]] * (HISTORY - len(self._history)) + list(self._history)
            columns = {key: np.concatenate([r[key] for r in rows]) for key in row}
            columns["new_segment"] = np.zeros(HISTORY, dtype=bool)
            features = features_from_columns(variant, columns)[-1:]
        else:
            features = features_from_columns(variant, row)
        return self.kernel.predict(features).reshape(NUM_LEGS, 3)

    def act(self, state: RobotState, command: np.ndarray) -> JointCommand:
        targets = self.foot_targets(state, command)
        self.last_targets = targets
        return JointCommand(inverse_kinematics(targets).q)
