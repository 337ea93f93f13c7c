"""The expert's CoM metric (thesis Fig. 4.8, A.2, A.3; ``docs/expert_analysis.md``).

The CoM's world trajectory high-passed with ``(I − M)²``, ``M`` the centred moving average over the fewest
whole gait cycles lasting at least :data:`DETREND_MIN_SECONDS` (this removes the walk along the path, speed
changes and turns included, and keeps every oscillation at the gait frequency and its harmonics unchanged),
rotated into the trunk's heading frame (x forward, y left, z up); ``com_std_x/y/z`` are the standard
deviations over time of that deviation. The trunk's roll and pitch standard deviations (rocking seen as
tilt) come with them.
"""

from __future__ import annotations

import math

import numpy as np

from krl.util.timing import CONTROL_DT

DETREND_MIN_SECONDS: float = 1.0
"""The moving average ``M`` of the detrending spans the fewest whole gait cycles lasting at least this [s]."""
SKIP_SECONDS: float = 1.0
"""Time from the standing start that the CoM statistics leave out [s]."""


def gait_cycle(stance_duration: float, gait: str = "trot") -> float:
    """Step-cycle duration τ_step of ``gait`` with the given stance duration [s]."""
    from krl.control.gait import gait_params

    return gait_params(gait, stance_duration=stance_duration).step_duration


def detrend_window_steps(
    cycle: float, min_seconds: float = DETREND_MIN_SECONDS, dt: float = CONTROL_DT
) -> int:
    """Control steps in the fewest whole gait cycles (each ``cycle`` seconds) lasting >= ``min_seconds``.

    For the trot (r_swing = 0.4): τ_stance 0.3 s -> 2 cycles of 0.5 s = 200 steps; 0.25 s -> 3 cycles of
    0.4167 s = 250 steps; 0.2 s -> 3 cycles of 0.3333 s = 200 steps.
    """
    if not (math.isfinite(cycle) and cycle > 0):
        raise ValueError(f"gait cycle must be > 0 s, got {cycle}")
    cycles = max(1, math.ceil(min_seconds / cycle - 1e-9))
    return max(1, round(cycles * cycle / dt))


def moving_average_kernel(window: int) -> np.ndarray:
    """Weights of the centred moving average ``M`` over ``window`` samples.

    An odd window is a plain average of ``window`` samples; an even one is the usual centred "2 x w"
    average (``window + 1`` samples, half weight at both ends). Either way a signal periodic in
    ``window`` samples averages exactly to its mean and a linear trend passes unchanged.
    """
    if window < 1:
        raise ValueError(f"window must be >= 1 sample, got {window}")
    if window % 2:
        return np.full(window, 1.0 / window)
    kernel = np.full(window + 1, 1.0 / window)
    kernel[[0, -1]] = 0.5 / window
    return kernel


def detrend_kernel(window: int) -> np.ndarray:
    """Weights of the high-pass ``(I − M)²`` (:func:`moving_average_kernel`), applied as one convolution.

    ``(I − M)² x = x − 2 M x + M M x``: a sinusoid with a whole number of periods in the window passes
    unchanged (``M`` maps it to zero), and polynomials up to degree 3 (straight walking, speed ramps,
    the slow curvature of turns) are removed exactly, where plain ``I − M`` would leave a bias of
    ``a T² / 24`` for an acceleration ``a`` (centripetal included) and window length ``T``.
    """
    average = moving_average_kernel(window)
    high_pass = -average
    high_pass[len(average) // 2] += 1.0
    return np.convolve(high_pass, high_pass)


def com_deviation(com: np.ndarray, yaw: np.ndarray, window: int) -> tuple[np.ndarray, slice]:
    """The CoM's oscillation about its smoothed path, in the heading frame [m].

    Args:
        com: CoM positions in the world frame [m]. Shape: (N, 3).
        yaw: trunk yaw at the same instants [rad]. Shape: (N,).
        window: moving-average length in samples (a whole number of gait cycles, see
            :func:`detrend_window_steps`).

    Returns:
        ``(deviation, where)``: ``deviation[k] = Rz(yaw[i])ᵀ ((I − M)² com)[i]`` (:func:`detrend_kernel`)
        for the samples ``i`` in ``where`` (those with both windows fully inside the run): x forward, y
        left, z up. Shape: (M, 3); M = 0 when the run is shorter than the kernel.
    """
    com = np.asarray(com, dtype=float)
    yaw = np.asarray(yaw, dtype=float)
    if com.ndim != 2 or com.shape[1] != 3 or yaw.shape != (len(com),):
        raise ValueError(f"com must be (N, 3) and yaw (N,), got {com.shape} and {yaw.shape}")
    kernel = detrend_kernel(window)
    first = len(kernel) // 2
    if len(com) < len(kernel):
        return np.empty((0, 3)), slice(first, first)
    offset = np.stack([np.convolve(com[:, j], kernel, mode="valid") for j in range(3)], 1)
    where = slice(first, first + len(offset))
    c, s = np.cos(yaw[where]), np.sin(yaw[where])
    deviation = np.stack(
        (c * offset[:, 0] + s * offset[:, 1], -s * offset[:, 0] + c * offset[:, 1], offset[:, 2]), 1
    )
    return deviation, where


def com_metrics(com: np.ndarray, rpy: np.ndarray, window: int, skip: int = 0) -> dict[str, float]:
    """Rocking metrics of one run (NaN where the run is too short).

    Args:
        com: CoM positions in the world frame [m]. Shape: (N, 3).
        rpy: trunk roll, pitch, yaw [rad]. Shape: (N, 3).
        window: detrending window in samples (:func:`com_deviation`).
        skip: leading samples left out (the standing start).

    Returns:
        ``com_std_x``, ``com_std_y``, ``com_std_z``: standard deviation over time of the heading-frame
        CoM deviation [m]; ``com_std``: their root sum of squares [m]; ``roll_std_deg``,
        ``pitch_std_deg``: standard deviation of the trunk's roll and pitch [deg]; ``com_height_mean``:
        mean CoM height [m]; ``samples``: how many samples the CoM standard deviations cover.
    """
    com = np.asarray(com, dtype=float)[skip:]
    rpy = np.asarray(rpy, dtype=float)[skip:]
    deviation, _ = com_deviation(com, rpy[:, 2], window)
    nan = float("nan")
    out: dict[str, float] = {}
    if len(deviation) >= 2:
        std = deviation.std(axis=0)
        out.update(com_std_x=std[0], com_std_y=std[1], com_std_z=std[2], com_std=np.sqrt((std**2).sum()))
    else:
        out.update(com_std_x=nan, com_std_y=nan, com_std_z=nan, com_std=nan)
    if len(rpy) >= 2:
        out["roll_std_deg"] = np.degrees(rpy[:, 0].std())
        out["pitch_std_deg"] = np.degrees(rpy[:, 1].std())
        out["com_height_mean"] = com[:, 2].mean()
    else:
        out.update(roll_std_deg=nan, pitch_std_deg=nan, com_height_mean=nan)
    out = {key: float(value) for key, value in out.items()}
    out["samples"] = len(deviation)
    return out
