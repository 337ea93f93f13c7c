"""Gait generator (thesis Section 4.2.3, Eq. 4.1-4.3, Table 4.1) and phase features (Eq. 4.6).

Every leg ``i`` has a phase ``φ_i ∈ (0, 1]`` that runs through one step cycle in ``τ_step`` seconds. The leg
swings while ``φ_i ≤ r_swing`` and stands while ``φ_i > r_swing``; the initial phases ``θ_i`` set how the legs
are coordinated (which gait it is). Legs are ordered as in :data:`krl.robots.a1.constants.LEG_NAMES`
(FR, FL, RR, RL).

Pure functions accept time or phase arrays with any leading dimensions and add a trailing leg axis of size
``NUM_LEGS``; :class:`GaitGenerator` is the small stateful wrapper the 200 Hz control loop steps. How each
ambiguity of the thesis was resolved is written down in ``docs/control.md``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

import numpy as np

from krl.robots.a1.constants import LEG_NAMES, NUM_LEGS
from krl.util.timing import CONTROL_DT

__all__ = [
    "GAITS",
    "GaitGenerator",
    "GaitParams",
    "contact_schedule",
    "gait_params",
    "leg_phases",
    "normalised_phase",
    "sine_phase",
    "stance_mask",
    "state_fraction",
]

_PHASE_DECIMALS = 12
"""Phases are rounded to this many decimals so that exact boundaries (``φ = r_swing``, ``φ = 1``) are not
moved across by float error in ``t / τ_step``; 1e-12 of a cycle is far below one control step."""


def _as_float(name: str, value: Any) -> float:
    """``float(value)`` for real numbers (not bool); a ValueError naming ``name`` otherwise."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name} must be a real number, got {value!r}")
    return float(value)


@dataclass(frozen=True)
class GaitParams:
    """Parameters of one gait (one row of thesis Table 4.1)."""

    initial_phases: tuple[float, float, float, float]
    """Initial phases ``θ_i`` of the legs FR, FL, RR, RL [cycles]. Shape: (4,). Each in [0, 1]; 0 and 1 are
    the same instant of the cycle (the thesis writes ``(0, 1]`` but its walk row uses 0). Any sequence is
    accepted and stored as a tuple of floats."""

    swing_ratio: float
    """Swing ratio ``r_swing``: fraction of a step cycle spent in swing [-]. In the open interval (0, 1)
    (``r_swing = 1`` would make Eq. 4.1 divide by zero)."""

    stance_duration: float
    """Stance duration ``τ_stance``: time a foot stays on the ground per cycle [s]. Positive."""

    def __post_init__(self) -> None:
        try:
            arr = np.asarray(self.initial_phases, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(
                f"initial_phases must be a sequence of {NUM_LEGS} numbers, got {self.initial_phases!r}"
            ) from None
        if arr.shape != (NUM_LEGS,):
            raise ValueError(
                f"initial_phases must have shape ({NUM_LEGS},) (one per leg {', '.join(LEG_NAMES)}), "
                f"got shape {arr.shape}: {self.initial_phases!r}"
            )
        phases = tuple(float(p) for p in arr)
        for leg, p in zip(LEG_NAMES, phases, strict=True):
            if not (0.0 <= p <= 1.0):
                raise ValueError(f"initial_phases[{leg}] must be in [0, 1], got {p!r}")
        object.__setattr__(self, "initial_phases", phases)
        r = _as_float("swing_ratio", self.swing_ratio)
        if not (0.0 < r < 1.0):
            raise ValueError(f"swing_ratio must be in the open interval (0, 1), got {self.swing_ratio!r}")
        object.__setattr__(self, "swing_ratio", r)
        s = _as_float("stance_duration", self.stance_duration)
        if not (math.isfinite(s) and s > 0.0):
            raise ValueError(
                f"stance_duration must be a positive finite number of seconds, got {self.stance_duration!r}"
            )
        object.__setattr__(self, "stance_duration", s)

    @property
    def swing_duration(self) -> float:
        """Swing duration ``τ_swing = τ_stance / (1 - r_swing) · r_swing`` (Eq. 4.1) [s]."""
        return self.stance_duration / (1.0 - self.swing_ratio) * self.swing_ratio

    @property
    def step_duration(self) -> float:
        """Step-cycle duration ``τ_step = τ_stance + τ_swing`` (Eq. 4.2) [s]."""
        return self.stance_duration + self.swing_duration

    @property
    def initial_phase_array(self) -> np.ndarray:
        """Initial phases as a new float array [cycles]. Shape: (4,)."""
        return np.array(self.initial_phases, dtype=float)


GAITS: Mapping[str, GaitParams] = MappingProxyType(
    {
        "walk": GaitParams(initial_phases=(0.0, 0.5, 0.75, 0.25), swing_ratio=0.25, stance_duration=0.3),
        "trot": GaitParams(initial_phases=(0.9, 0.4, 0.4, 0.9), swing_ratio=0.4, stance_duration=0.3),
        "bound": GaitParams(initial_phases=(0.4, 0.4, 0.9, 0.9), swing_ratio=0.3, stance_duration=0.1),
    }
)
"""The gaits of thesis Table 4.1, by name (read-only)."""


def gait_params(name: str, **overrides: Any) -> GaitParams:
    """Return the Table 4.1 preset ``name`` with some fields replaced.

    Example: ``gait_params("trot", stance_duration=0.2)``.

    Raises:
        ValueError: unknown gait name, unknown field name, or an invalid overridden value.
    """
    if name not in GAITS:
        raise ValueError(f"unknown gait {name!r}; known gaits: {', '.join(sorted(GAITS))}")
    fields = {f.name for f in dataclasses.fields(GaitParams)}
    unknown = sorted(set(overrides) - fields)
    if unknown:
        raise ValueError(f"unknown GaitParams field(s) {unknown}; fields: {', '.join(sorted(fields))}")
    return dataclasses.replace(GAITS[name], **overrides)


def _check_swing_ratio(swing_ratio: float) -> float:
    r = float(swing_ratio)
    if not (0.0 < r < 1.0):
        raise ValueError(f"swing_ratio must be in the open interval (0, 1), got {swing_ratio!r}")
    return r


def leg_phases(t: float | np.ndarray, params: GaitParams) -> np.ndarray:
    """Leg phases at time ``t`` (Eq. 4.3): ``φ_i = (θ_i + t / τ_step) mod 1``, with 0 mapped to 1.

    Args:
        t: time since the gait started [s]. Shape: (...) (a scalar or any array); must be finite.
        params: gait parameters.

    Returns:
        Phases in (0, 1] [cycles]. Shape: (..., 4).
    """
    t_arr = np.asarray(t, dtype=float)
    if not np.all(np.isfinite(t_arr)):
        raise ValueError("t must be finite")
    raw = params.initial_phase_array + t_arr[..., None] / params.step_duration
    frac = np.mod(np.round(np.mod(raw, 1.0), _PHASE_DECIMALS), 1.0)
    return np.where(frac == 0.0, 1.0, frac)


def stance_mask(phase: np.ndarray, swing_ratio: float) -> np.ndarray:
    """Stance (foot on the ground) where ``φ > r_swing``; swing where ``φ ≤ r_swing``.

    Args:
        phase: leg phases in (0, 1]. Shape: (...).
        swing_ratio: ``r_swing`` in (0, 1).

    Returns:
        Boolean mask, True in stance. Shape: (...).
    """
    return np.asarray(phase, dtype=float) > _check_swing_ratio(swing_ratio)


def contact_schedule(t: float | np.ndarray, params: GaitParams) -> np.ndarray:
    """Planned contact schedule: True where a leg is in stance at time ``t``.

    Args:
        t: times [s]. Shape: (...), e.g. (T,).
        params: gait parameters.

    Returns:
        Boolean stance mask. Shape: (..., 4), e.g. (T, 4).
    """
    return stance_mask(leg_phases(t, params), params.swing_ratio)


def state_fraction(phase: np.ndarray, swing_ratio: float) -> np.ndarray:
    """Fraction of the current swing or stance that has elapsed.

    ``φ / r_swing`` in swing and ``(φ - r_swing) / (1 - r_swing)`` in stance; both lie in (0, 1] for phases
    in (0, 1] (1 at the last instant of the state). This is Eq. 4.6 without the +1 that marks swing.

    Args:
        phase: leg phases in (0, 1]. Shape: (...).
        swing_ratio: ``r_swing`` in (0, 1).

    Returns:
        Elapsed fraction [-]. Shape: (...).
    """
    r = _check_swing_ratio(swing_ratio)
    phi = np.asarray(phase, dtype=float)
    return np.where(phi <= r, phi / r, (phi - r) / (1.0 - r))


def normalised_phase(phase: np.ndarray, swing_ratio: float) -> np.ndarray:
    """Normalised phase ``|φ|`` of Eq. 4.6.

    ``1 + φ / r_swing`` in swing and ``(φ - r_swing) / (1 - r_swing)`` in stance. The value
    is in (1, 2] during swing and in (0, 1] during stance, whatever the gait.

    Args:
        phase: leg phases in (0, 1]. Shape: (...).
        swing_ratio: ``r_swing`` in (0, 1).

    Returns:
        Normalised phases [-]. Shape: (...).
    """
    r = _check_swing_ratio(swing_ratio)
    phi = np.asarray(phase, dtype=float)
    return np.where(phi <= r, 1.0 + phi / r, (phi - r) / (1.0 - r))


def sine_phase(phase: np.ndarray, swing_ratio: float) -> np.ndarray:
    """Sine form of the normalised phase, ``sin(|φ| · π)`` (thesis text after Eq. 4.6).

    Non-negative in stance, non-positive in swing, zero at every swing/stance transition.

    Args:
        phase: leg phases in (0, 1]. Shape: (...).
        swing_ratio: ``r_swing`` in (0, 1).

    Returns:
        Values in [-1, 1]. Shape: (...).
    """
    return np.sin(normalised_phase(phase, swing_ratio) * np.pi)


class GaitGenerator:
    """Stateful gait clock: advances by one control step per :meth:`step`.

    Time is kept as an integer step count (``time = step_count · dt``) so that long runs do not drift.
    All readouts describe the current time, i.e. before the next :meth:`step`.
    """

    def __init__(self, params: GaitParams, dt: float = CONTROL_DT) -> None:
        """
        Args:
            params: gait parameters (e.g. ``GAITS["trot"]``).
            dt: step size [s]; the 200 Hz control period by default.
        """
        if not isinstance(params, GaitParams):
            raise ValueError(f"params must be a GaitParams, got {type(params).__name__}")
        dt = _as_float("dt", dt)
        if not (math.isfinite(dt) and dt > 0.0):
            raise ValueError(f"dt must be a positive finite number of seconds, got {dt!r}")
        self._params = params
        self._dt = float(dt)
        self._step_count = 0

    @property
    def params(self) -> GaitParams:
        """Current gait parameters."""
        return self._params

    @property
    def dt(self) -> float:
        """Step size [s]."""
        return self._dt

    @property
    def step_count(self) -> int:
        """Number of :meth:`step` calls since the last reset."""
        return self._step_count

    @property
    def time(self) -> float:
        """Time since the last reset [s]."""
        return self._step_count * self._dt

    def step(self) -> np.ndarray:
        """Advance by ``dt`` and return the new phases. Shape: (4,)."""
        self._step_count += 1
        return self.phases

    def reset(self, params: GaitParams | None = None) -> None:
        """Return to time 0 (phases = initial phases), optionally switching to new gait parameters."""
        if params is not None:
            if not isinstance(params, GaitParams):
                raise ValueError(f"params must be a GaitParams, got {type(params).__name__}")
            self._params = params
        self._step_count = 0

    @property
    def phases(self) -> np.ndarray:
        """Leg phases ``φ`` in (0, 1] (Eq. 4.3) [cycles]. Shape: (4,)."""
        return leg_phases(self.time, self._params)

    @property
    def normalised_phases(self) -> np.ndarray:
        """Normalised phases ``|φ|`` (Eq. 4.6): (1, 2] in swing, (0, 1] in stance. Shape: (4,)."""
        return normalised_phase(self.phases, self._params.swing_ratio)

    @property
    def sine_phases(self) -> np.ndarray:
        """``sin(|φ| · π)``. Shape: (4,)."""
        return sine_phase(self.phases, self._params.swing_ratio)

    @property
    def stance_mask(self) -> np.ndarray:
        """True for legs in stance. Shape: (4,), bool."""
        return stance_mask(self.phases, self._params.swing_ratio)

    @property
    def swing_mask(self) -> np.ndarray:
        """True for legs in swing. Shape: (4,), bool."""
        return ~self.stance_mask

    @property
    def state_fraction(self) -> np.ndarray:
        """Elapsed fraction of each leg's current swing or stance, in (0, 1]. Shape: (4,)."""
        return state_fraction(self.phases, self._params.swing_ratio)
