"""The policy's action: its parts, in order, with their units and the values ±1 and 0 map to.

An action is ``config.action_size`` numbers in [-1, 1], made of the parts that
:class:`krl.agent.config.ResidualConfig` switches on, in this order:

========== ==== =============== ============================================================================
part       size unit            what (-1 / 0 / +1 map to ``low`` / ``nominal`` / ``high``, linearly between)
========== ==== =============== ============================================================================
residual   12   m               per foot (FR, FL, RR, RL) an (x, y, z) base-frame residual: ± residual_bound
command    3    m/s, m/s, rad/s the velocity command fed to the kernel: its training command ranges, 0 at 0
steer      3    m/s, m/s, rad/s an offset added to the task's command before the kernel: ± the ranges' highs
heights    2    m               kernel-ext's step and ride heights: their training ranges, nominal at 0
clock_rate 1    1               the gait clock's rate: ``rhythm_range``, 1 (the kernel's own rhythm) at 0
========== ==== =============== ============================================================================

Every part but the residual (the *drive*) passes, in physical units and as a deviation from its nominal
value, through one low-pass filter (α = ``gait_alpha``, Eq. 4.4's form) that restarts at the nominal values;
the filtered values feed the kernel and the clock from the next control step on.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from krl.agent.config import AgentConfigError, ResidualConfig
from krl.control.expert import RIDE_HEIGHT_RANGE, STEP_HEIGHT_RANGE
from krl.kernel.model import Kernel
from krl.kernel.settings import training_settings
from krl.robots.a1.constants import LEG_NAMES

__all__ = ["DRIVE_PARTS", "ActionPart", "action_parts", "describe_parts"]

COMMAND_LABELS: tuple[str, ...] = ("v_x", "v_y", "yaw_rate")
"""The names of a velocity command's numbers (m/s, m/s, rad/s)."""

DRIVE_PARTS: tuple[str, ...] = ("command", "steer", "heights", "clock_rate")
"""The parts that drive the kernel's inputs or the clock, in action order."""

SATURATED: float = 0.99
"""An action number at or beyond ±this asks for its bound (actions are clipped to ±1)."""


@dataclass(frozen=True)
class ActionPart:
    """One part of the action: ``size`` numbers mapped piecewise-linearly onto [low, nominal, high]."""

    name: str
    unit: str
    description: str
    low: tuple[float, ...]
    """Value at action -1, per number."""
    nominal: tuple[float, ...]
    """Value at action 0 (the faithful agent's value), per number."""
    high: tuple[float, ...]
    """Value at action +1, per number."""
    labels: tuple[str, ...]
    """Each number's name (``FR.x``, ``v_x``, ``step_height``, ``rate``)."""

    @property
    def size(self) -> int:
        return len(self.nominal)

    def value(self, action: np.ndarray) -> np.ndarray:
        """Physical values of actions already clipped to [-1, 1]. Shapes: (N, size) -> (N, size)."""
        low, nominal, high = (np.asarray(v) for v in (self.low, self.nominal, self.high))
        return nominal + np.where(action < 0, action * (nominal - low), action * (high - nominal))

    def action(self, value: np.ndarray) -> np.ndarray:
        """The actions that give ``value`` (clipped to [-1, 1]): the inverse of :meth:`value`.
        Shapes: (N, size) -> (N, size)."""
        low, nominal, high = (np.asarray(v) for v in (self.low, self.nominal, self.high))
        deviation = np.asarray(value, dtype=float) - nominal
        return np.clip(
            np.where(deviation < 0, deviation / (nominal - low), deviation / (high - nominal)), -1, 1
        )


def action_parts(config: ResidualConfig, kernel: Kernel) -> tuple[ActionPart, ...]:
    """The parts of ``config``'s action for ``kernel``, in action order (module docstring).

    Raises:
        AgentConfigError: ``drive_heights`` with a kernel that has no height inputs (not kernel-ext).
    """
    parts = []
    if config.residuals:
        bound = tuple(config.residual_bound) * 4
        parts.append(
            ActionPart(
                "residual",
                "m",
                "per foot (FR, FL, RR, RL) an (x, y, z) base-frame residual, filtered with residual_alpha",
                tuple(-b for b in bound),
                (0.0,) * len(bound),
                bound,
                tuple(f"{leg}.{axis}" for leg in LEG_NAMES for axis in "xyz"),
            )
        )
    settings = training_settings(kernel)
    ranges = (settings.command.vx_range, settings.command.vy_range, settings.command.yaw_rate_range)
    if config.drive_command:
        parts.append(
            ActionPart(
                "command",
                "m/s, m/s, rad/s",
                "(v_x, v_y, yaw rate) fed to the kernel instead of the task's command",
                tuple(r[0] for r in ranges),
                (0.0, 0.0, 0.0),
                tuple(r[1] for r in ranges),
                COMMAND_LABELS,
            )
        )
    if config.drive_steer:
        parts.append(
            ActionPart(
                "steer",
                "m/s, m/s, rad/s",
                "an offset (v_x, v_y, yaw rate) to the task's command, the sum clipped to its ranges",
                tuple(-r[1] for r in ranges),
                (0.0, 0.0, 0.0),
                tuple(r[1] for r in ranges),
                COMMAND_LABELS,
            )
        )
    if config.drive_heights:
        if kernel.variant != "ext":
            raise AgentConfigError(
                f"drive_heights needs kernel-ext (the kernel with step and ride height inputs), "
                f"not kernel-{kernel.variant}"
            )
        expert = settings.expert
        parts.append(
            ActionPart(
                "heights",
                "m",
                "kernel-ext's step height and ride height",
                (STEP_HEIGHT_RANGE[0], RIDE_HEIGHT_RANGE[0]),
                (expert.step_height, expert.ride_height),
                (STEP_HEIGHT_RANGE[1], RIDE_HEIGHT_RANGE[1]),
                ("step_height", "ride_height"),
            )
        )
    if config.drive_rhythm:
        low, high = config.rhythm_range
        parts.append(
            ActionPart(
                "clock_rate",
                "1",
                "gait clock rate, in multiples of the kernel's own stepping frequency",
                (low,),
                (1.0,),
                (high,),
                ("rate",),
            )
        )
    return tuple(parts)


def describe_parts(config: ResidualConfig, kernel: Kernel) -> list[dict[str, object]]:
    """The parts of ``config``'s action for ``kernel`` as plain data, in action order: name, ``start`` and
    ``stop`` (the part's slice of the action), unit, meaning, the values at action -1, 0 and +1, and each
    number's label (what ``krl export``'s contract and ``krl agent info`` show)."""
    described, start = [], 0
    for part in action_parts(config, kernel):
        described.append(
            {
                "name": part.name,
                "start": start,
                "stop": start + part.size,
                "unit": part.unit,
                "meaning": part.description,
                "at_minus_1": list(part.low),
                "at_0": list(part.nominal),
                "at_plus_1": list(part.high),
                "labels": list(part.labels),
            }
        )
        start += part.size
    return described
