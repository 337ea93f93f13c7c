"""First-order low-pass filter for the agent's residuals (thesis Section 4.2.5, Eq. 4.4).

``y_t = α x_t + (1 - α) y_{t-1}`` with ``y_{-1} = 0`` by default and ``α = 0.1`` in all the thesis's
experiments. Only the residuals are filtered, never the kernel's trajectories (docs/control.md).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ["RESIDUAL_ALPHA", "LowPassFilter"]

RESIDUAL_ALPHA: float = 0.1
"""Smoothing factor α of the residuals' filter in every experiment of the thesis (Section 4.2.5)."""


class LowPassFilter:
    """Exponential (first-order IIR) low-pass filter over arrays of a fixed shape, Eq. 4.4.

    Each call ``y = f(x)`` updates and returns ``y_t = α x_t + (1 - α) y_{t-1}``. The state starts at zero
    (or the value given to :meth:`reset`). ``α = 1`` disables filtering.
    """

    def __init__(self, shape: int | tuple[int, ...], alpha: float = RESIDUAL_ALPHA) -> None:
        """
        Args:
            shape: shape of the filtered array, e.g. ``(4, 3)`` for foot-position residuals or ``(12,)``.
            alpha: smoothing factor α in (0, 1]; the weight of the newest input.
        """
        if isinstance(alpha, (bool, np.bool_)) or not isinstance(
            alpha, (int, float, np.integer, np.floating)
        ):
            raise ValueError(f"alpha must be a real number in (0, 1], got {alpha!r}")
        if not (math.isfinite(alpha) and 0.0 < alpha <= 1.0):
            raise ValueError(f"alpha must be in (0, 1], got {alpha!r}")
        try:
            shape_t = (int(shape),) if isinstance(shape, (int, np.integer)) else tuple(int(s) for s in shape)
        except (TypeError, ValueError):
            raise ValueError(f"shape must be an int or a tuple of ints, got {shape!r}") from None
        if any(s < 0 for s in shape_t):
            raise ValueError(f"shape must have non-negative sizes, got {shape!r}")
        self._alpha = float(alpha)
        self._shape = shape_t
        self._state = np.zeros(shape_t)

    @property
    def alpha(self) -> float:
        """Smoothing factor α (weight of the newest input)."""
        return self._alpha

    @property
    def shape(self) -> tuple[int, ...]:
        """Shape of the filtered arrays."""
        return self._shape

    @property
    def value(self) -> np.ndarray:
        """Current filter output ``y_{t-1}`` (a copy). Shape: ``shape``."""
        return self._state.copy()

    def __call__(self, x: Any) -> np.ndarray:
        """Filter one sample.

        Args:
            x: new input ``x_t`` (finite). Shape: ``shape`` exactly.

        Returns:
            ``y_t = α x_t + (1 - α) y_{t-1}`` (a copy; the filter keeps its own). Shape: ``shape``.
        """
        arr = np.asarray(x, dtype=float)
        if arr.shape != self._shape:
            raise ValueError(f"input must have shape {self._shape}, got {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise ValueError("input must be finite (a NaN or inf would stay in the filter state)")
        self._state = self._alpha * arr + (1.0 - self._alpha) * self._state
        return self._state.copy()

    def reset_rows(self, rows: Any) -> None:
        """Zero the state of some rows of a batched filter (``rows`` indexes the first axis)."""
        self._state[rows] = 0.0

    def reset(self, value: Any = 0.0) -> None:
        """Set the state ``y_{t-1}`` to ``value`` (a scalar or an array broadcastable to ``shape``)."""
        arr = np.asarray(value, dtype=float)
        try:
            state = np.broadcast_to(arr, self._shape).astype(float)
        except ValueError:
            raise ValueError(
                f"reset value of shape {arr.shape} does not broadcast to {self._shape}"
            ) from None
        if not np.all(np.isfinite(state)):
            raise ValueError("reset value must be finite")
        self._state = state
