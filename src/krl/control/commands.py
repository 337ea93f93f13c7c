"""Command generator (thesis Section 4.2.2, Algorithm 2 in Appendix A.4).

Turns a target location into a velocity command ``[v_x, v_y, ω_yaw]`` in the base (heading) frame:
``v_x`` forward [m/s], ``v_y`` left [m/s], ``ω_yaw`` counter-clockwise yaw rate [rad/s]. The command moves
towards the raw command ``[D cos θ, D sin θ, k_yaw θ]`` (``D`` the planar distance to the target, ``θ`` the
heading error) by at most ``rate_limit`` per component per 20 Hz tick, its planar part is capped at
``max_speed``, and each component is clipped to its range.

:func:`next_command` is one tick of that law as a pure function (leading batch dimensions broadcast);
:class:`CommandGenerator` is the stateful version called at every 200 Hz control step, which updates only
every :data:`krl.util.timing.COMMAND_PERIOD_STEPS` calls and holds the command in between. How each
ambiguity of Algorithm 2 was resolved is written down in ``docs/control.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from krl.util.timing import COMMAND_PERIOD_STEPS

__all__ = ["CommandGenerator", "CommandParams", "next_command", "wrap_angle"]


def _as_float(name: str, value: Any) -> float:
    """``float(value)`` for finite real numbers (not bool); a ValueError naming ``name`` otherwise."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name} must be a real number, got {value!r}")
    out = float(value)
    if not math.isfinite(out):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return out


def _as_range(name: str, value: Any) -> tuple[float, float]:
    try:
        low, high = value
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a (low, high) pair, got {value!r}") from None
    low = _as_float(f"{name}[0]", low)
    high = _as_float(f"{name}[1]", high)
    if low > high:
        raise ValueError(f"{name} must have low <= high, got {value!r}")
    return (low, high)


@dataclass(frozen=True)
class CommandParams:
    """Parameters of the command generator (Algorithm 2).

    The thesis states the rate limit (±0.005 per tick at 20 Hz), the yaw gain 0.3 and ``dist_min = 0.5 m``;
    it does not state ``vel_max`` or ``vel_range``: the defaults below are ours, chosen for an A1 trotting
    with a 0.2 s stance (docs/control.md).
    """

    max_speed: float = 0.5
    """Cap on the planar speed ``‖(v_x, v_y)‖`` [m/s] (ours). The yaw rate is not part of this norm."""

    vx_range: tuple[float, float] = (-0.5, 0.5)
    """Clip range (low, high) of the forward velocity ``v_x`` [m/s] (ours)."""

    vy_range: tuple[float, float] = (-0.3, 0.3)
    """Clip range (low, high) of the lateral velocity ``v_y`` [m/s] (ours)."""

    yaw_rate_range: tuple[float, float] = (-0.5, 0.5)
    """Clip range (low, high) of the yaw rate ``ω_yaw`` [rad/s] (ours)."""

    rate_limit: float = 0.005
    """Largest change of each component per command tick ([m/s] for v_x, v_y; [rad/s] for ω_yaw). With
    ticks at 20 Hz this is an acceleration limit of 0.1 m/s² (and 0.1 rad/s²). Positive."""

    yaw_gain: float = 0.3
    """Proportional gain from heading error [rad] to raw yaw-rate command [rad/s], i.e. [1/s].
    Non-negative."""

    d_min: float = 0.5
    """Target threshold ``dist_min``: the target counts as reached when the planar distance is below it [m].
    Non-negative."""

    def __post_init__(self) -> None:
        max_speed = _as_float("max_speed", self.max_speed)
        if max_speed <= 0.0:
            raise ValueError(f"max_speed must be positive, got {self.max_speed!r}")
        rate_limit = _as_float("rate_limit", self.rate_limit)
        if rate_limit <= 0.0:
            raise ValueError(f"rate_limit must be positive, got {self.rate_limit!r}")
        yaw_gain = _as_float("yaw_gain", self.yaw_gain)
        if yaw_gain < 0.0:
            raise ValueError(f"yaw_gain must be non-negative, got {self.yaw_gain!r}")
        d_min = _as_float("d_min", self.d_min)
        if d_min < 0.0:
            raise ValueError(f"d_min must be non-negative, got {self.d_min!r}")
        object.__setattr__(self, "max_speed", max_speed)
        object.__setattr__(self, "rate_limit", rate_limit)
        object.__setattr__(self, "yaw_gain", yaw_gain)
        object.__setattr__(self, "d_min", d_min)
        for name in ("vx_range", "vy_range", "yaw_rate_range"):
            object.__setattr__(self, name, _as_range(name, getattr(self, name)))

    @property
    def low(self) -> np.ndarray:
        """Lower clip bounds ``[v_x, v_y, ω_yaw]``. Shape: (3,)."""
        return np.array([self.vx_range[0], self.vy_range[0], self.yaw_rate_range[0]])

    @property
    def high(self) -> np.ndarray:
        """Upper clip bounds ``[v_x, v_y, ω_yaw]``. Shape: (3,)."""
        return np.array([self.vx_range[1], self.vy_range[1], self.yaw_rate_range[1]])


def wrap_angle(angle: float | np.ndarray) -> np.ndarray:
    """Wrap angles [rad] into (-π, π]. Shape: same as ``angle``."""
    a = np.asarray(angle, dtype=float)
    return np.pi - np.mod(np.pi - a, 2.0 * np.pi)


def _finite_array(name: str, value: Any, last_dim: int | None) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a numeric array, got {value!r}") from None
    if last_dim is not None and (arr.ndim == 0 or arr.shape[-1] != last_dim):
        raise ValueError(f"{name} must have shape (..., {last_dim}), got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} must be finite, got {value!r}")
    return arr


def _limit(cmd: np.ndarray, params: CommandParams) -> np.ndarray:
    """Cap the planar speed at ``max_speed``, then clip each component to its range."""
    speed = np.hypot(cmd[..., 0], cmd[..., 1])
    scale = np.where(speed > params.max_speed, params.max_speed / np.maximum(speed, 1e-300), 1.0)
    cmd = cmd.copy()
    cmd[..., :2] *= scale[..., None]
    return np.clip(cmd, params.low, params.high)


def _clip(value: float, low: float, high: float) -> float:
    """``np.clip`` of one float (the same comparisons: max with ``low``, then min with ``high``)."""
    value = value if value > low else low
    return value if value < high else high


def _tick(
    delta: tuple[float, float] | None, yaw: float, previous: np.ndarray, params: CommandParams
) -> np.ndarray:
    """One tick of one robot's generator: :func:`_next_command` towards a target ``delta`` = target - base
    [m] away, or (``delta`` None) the ramp of a command to zero, bit for bit, on Python floats.

    The transcendental functions stay NumPy's, as on arrays (libm's may differ in the last bit on some
    machines); the rest is the same IEEE arithmetic and the same comparisons, without the cost of ~20
    ufunc calls on 0-d arrays. Shape: (3,).
    """
    rate = params.rate_limit
    v_x, v_y, omega = previous.tolist()
    if delta is None:
        v_x, v_y, omega = (v + _clip(-v, -rate, rate) for v in (v_x, v_y, omega))
    else:
        dx, dy = delta
        dist = float(np.hypot(dx, dy))
        theta = float(wrap_angle(np.arctan2(dy, dx) - yaw)) if dist > 0.0 else 0.0
        raw = (dist * float(np.cos(theta)), dist * float(np.sin(theta)), params.yaw_gain * theta)
        v_x, v_y, omega = (v + _clip(r - v, -rate, rate) for v, r in zip((v_x, v_y, omega), raw, strict=True))
    speed = float(np.hypot(v_x, v_y))
    if speed > params.max_speed:
        scale = params.max_speed / max(speed, 1e-300)
        v_x, v_y = v_x * scale, v_y * scale
    return np.array(
        [
            _clip(v_x, *params.vx_range),
            _clip(v_y, *params.vy_range),
            _clip(omega, *params.yaw_rate_range),
        ]
    )


def next_command(
    target_xy: np.ndarray,
    base_xy: np.ndarray,
    yaw: float | np.ndarray,
    previous_cmd: np.ndarray,
    params: CommandParams | None = None,
) -> np.ndarray:
    """One 20 Hz tick of Algorithm 2's GENERATE_COMMANDS.

    ``D = ‖target - base‖``, ``θ = wrap(atan2(Δy, Δx) - yaw)`` (0 when ``D = 0``), raw command
    ``[D cos θ, D sin θ, k_yaw θ]``; then ``cmd = previous + clip(raw - previous, ±rate_limit)``, the
    planar part is scaled down to ``max_speed`` if faster, and each component is clipped to its range.

    Args:
        target_xy: target position in the world frame [m]. Shape: (..., 2).
        base_xy: base position in the world frame [m]. Shape: (..., 2).
        yaw: base yaw in the world frame [rad]. Shape: (...).
        previous_cmd: the command of the previous tick ``[v_x, v_y, ω_yaw]`` [m/s, m/s, rad/s].
            Shape: (..., 3).
        params: generator parameters; ``CommandParams()`` if omitted.

    Returns:
        The new command ``[v_x, v_y, ω_yaw]`` in the base (heading) frame. Shape: broadcast of the leading
        dimensions + (3,), e.g. (3,) for single inputs.
    """
    params = CommandParams() if params is None else params
    if not isinstance(params, CommandParams):
        raise ValueError(f"params must be a CommandParams, got {type(params).__name__}")
    target = _finite_array("target_xy", target_xy, 2)
    base = _finite_array("base_xy", base_xy, 2)
    yaw_arr = _finite_array("yaw", yaw, None)
    prev = _finite_array("previous_cmd", previous_cmd, 3)
    try:
        np.broadcast_shapes(target.shape[:-1], base.shape[:-1], yaw_arr.shape, prev.shape[:-1])
    except ValueError:
        raise ValueError(
            "leading dimensions do not broadcast: target_xy "
            f"{target.shape}, base_xy {base.shape}, yaw {yaw_arr.shape}, previous_cmd {prev.shape}"
        ) from None
    return _next_command(target, base, yaw_arr, prev, params)


def _next_command(
    target: np.ndarray, base: np.ndarray, yaw: np.ndarray, prev: np.ndarray, params: CommandParams
) -> np.ndarray:
    """:func:`next_command` on checked float arrays (finite, broadcastable), for callers that checked them."""
    delta = target - base
    dist = np.hypot(delta[..., 0], delta[..., 1])
    theta = wrap_angle(np.arctan2(delta[..., 1], delta[..., 0]) - yaw)
    theta = np.where(dist > 0.0, theta, 0.0)
    parts = (dist * np.cos(theta), dist * np.sin(theta), params.yaw_gain * theta)
    raw = np.empty((*np.broadcast_shapes(*(part.shape for part in parts)), 3))
    for axis, part in enumerate(parts):
        raw[..., axis] = part
    cmd = prev + np.clip(raw - prev, -params.rate_limit, params.rate_limit)
    return _limit(cmd, params)


class CommandGenerator:
    """Stateful command generator, called once per control step (200 Hz).

    The command is recomputed with :func:`next_command` on the first call and then every ``period_steps``
    calls (20 Hz by default) and held in between. While no target is set, or once the target is reached,
    the command ramps to zero at the same rate limit instead of jumping. ``reached`` and ``distance`` are
    refreshed on every call.
    """

    def __init__(
        self,
        params: CommandParams | None = None,
        target_xy: np.ndarray | None = None,
        period_steps: int = COMMAND_PERIOD_STEPS,
    ) -> None:
        """
        Args:
            params: generator parameters; ``CommandParams()`` if omitted.
            target_xy: initial target in the world frame [m]. Shape: (2,). None: no target yet.
            period_steps: control steps per command tick (10: 20 Hz at the 200 Hz control rate).
        """
        params = CommandParams() if params is None else params
        if not isinstance(params, CommandParams):
            raise ValueError(f"params must be a CommandParams, got {type(params).__name__}")
        if (
            isinstance(period_steps, bool)
            or not isinstance(period_steps, (int, np.integer))
            or period_steps < 1
        ):
            raise ValueError(f"period_steps must be a positive integer, got {period_steps!r}")
        self._params = params
        self._period = int(period_steps)
        self._target: np.ndarray | None = None
        self._command = np.zeros(3)
        self._step_count = 0
        self._distance = math.nan
        self.reset(target_xy)

    @property
    def params(self) -> CommandParams:
        """Generator parameters."""
        return self._params

    @property
    def period_steps(self) -> int:
        """Control steps per command tick."""
        return self._period

    @property
    def target(self) -> np.ndarray | None:
        """Current target in the world frame [m] (a copy), or None. Shape: (2,)."""
        return None if self._target is None else self._target.copy()

    @property
    def command(self) -> np.ndarray:
        """Current command ``[v_x, v_y, ω_yaw]`` [m/s, m/s, rad/s] (a copy). Shape: (3,)."""
        return self._command.copy()

    @property
    def step_count(self) -> int:
        """Number of :meth:`step` calls since the last reset."""
        return self._step_count

    @property
    def distance(self) -> float:
        """Planar distance to the target at the last call [m]; NaN before the first call or without target."""
        return self._distance

    @property
    def reached(self) -> bool:
        """True when the distance at the last call was below ``d_min`` (False without a target)."""
        return bool(self._distance < self._params.d_min)

    def set_target(self, target_xy: np.ndarray) -> None:
        """Set a new target [m] (shape (2,)); the command keeps its value and moves on at the rate limit."""
        target = _finite_array("target_xy", target_xy, 2)
        if target.shape != (2,):
            raise ValueError(f"target_xy must have shape (2,), got {target.shape}")
        self._target = target.copy()
        self._distance = math.nan

    def reset(self, target_xy: np.ndarray | None = None) -> None:
        """Zero the command and the tick counter; set the target (None clears it)."""
        self._command = np.zeros(3)
        self._step_count = 0
        self._distance = math.nan
        if target_xy is None:
            self._target = None
        else:
            self.set_target(target_xy)

    def step(self, base_xy: np.ndarray, yaw: float) -> np.ndarray:
        """Advance one control step from the robot's pose and return the command to apply.

        Args:
            base_xy: base position in the world frame [m]. Shape: (2,).
            yaw: base yaw in the world frame [rad].

        Returns:
            The command ``[v_x, v_y, ω_yaw]`` [m/s, m/s, rad/s] (a copy). Shape: (3,).
        """
        try:
            base = np.asarray(base_xy, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"base_xy must be a numeric array, got {base_xy!r}") from None
        if base.shape != (2,):
            raise ValueError(f"base_xy must have shape (2,), got {base.shape}")
        x, y = base.tolist()
        if not (math.isfinite(x) and math.isfinite(y)):
            raise ValueError(f"base_xy must be finite, got {base_xy!r}")
        yaw_f = _as_float("yaw", yaw)
        delta = None
        if self._target is None:
            self._distance = math.nan
        else:
            target_x, target_y = self._target.tolist()
            delta = (target_x - x, target_y - y)
            self._distance = float(np.hypot(*delta))
        if self._step_count % self._period == 0:
            # base and yaw checked above, the target by set_target; a reached target ramps to zero
            self._command = _tick(None if self.reached else delta, yaw_f, self._command, self._params)
        self._step_count += 1
        return self._command.copy()

    __call__ = step
