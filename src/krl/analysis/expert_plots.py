"""The MPC expert's analysis figures: ``krl expert plot WHICH --out DIR`` (``docs/expert_analysis.md``).

``WHICH`` is one of

- ``com-variance`` (thesis Fig. 4.8): the expert walks to the same random waypoints with stance durations
  0.3, 0.25 and 0.2 s; how much does its centre of mass (CoM) wobble?
- ``ride-height`` (Fig. A.2): the same at stance 0.2 s for several ride heights;
- ``step-height`` (Fig. A.3): the same at stance 0.2 s for several step heights;
- ``velocity`` (the MPC half of Fig. 4.15): realised against commanded velocity, each component swept
  over the command generator's limits with the other two held at zero;
- ``all``: the four of them (a condition shared by two figures runs once).

Each figure gives ``WHICH.png``, ``WHICH.json`` and ``WHICH.csv`` in ``DIR``, each written atomically (temp
file + ``os.replace``). The conditions run in parallel worker processes (``--workers``); every condition
is deterministic given the seed, so the numbers do not depend on the worker count.

CoM metric (:func:`com_deviation`, :func:`com_metrics`): the CoM's world trajectory high-passed with
``(I − M)²``, ``M`` the centred moving average over the fewest whole gait cycles lasting at least
:data:`DETREND_MIN_SECONDS` (this removes the walk along the path, speed changes and turns included, and
keeps every oscillation at the gait frequency and its harmonics unchanged), rotated into the trunk's
heading frame (x forward, y left, z up); ``com_std_x/y/z`` are the standard deviations over time of that
deviation. The trunk's roll and pitch standard deviations (rocking seen as tilt) come with them.
"""

from __future__ import annotations

import json
import math
import os
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from krl.control.expert import NOMINAL_RIDE_HEIGHT, NOMINAL_STEP_HEIGHT
from krl.output import FIG_DPI, csv_bytes, figure_bytes, json_value, write_atomic
from krl.parallel import run_jobs
from krl.runner import HOLD_RAMP, HOLD_SETTLE, TARGET_DISTANCE, TARGET_TIME_LIMIT
from krl.timing import CONTROL_DT

__all__ = [
    "CHOICES",
    "FIGURES",
    "PlotError",
    "com_deviation",
    "com_metrics",
    "detrend_kernel",
    "detrend_window_steps",
    "fit_line",
    "gait_cycle",
    "make_figures",
    "moving_average_kernel",
]


class PlotError(ValueError):
    """A bad ``krl expert plot`` argument (one-line message)."""


FIGURES: tuple[str, ...] = ("com-variance", "ride-height", "step-height", "velocity")
"""The figures, in the order ``all`` makes them."""

CHOICES: tuple[str, ...] = (*FIGURES, "all")

THESIS_FIGURE: dict[str, str] = {
    "com-variance": "Fig. 4.8",
    "ride-height": "Fig. A.2",
    "step-height": "Fig. A.3",
    "velocity": "Fig. 4.15 (MPC)",
}

STANCE_DURATIONS: tuple[float, ...] = (0.3, 0.25, 0.2)
"""τ_stance of Fig. 4.8's panels A, B, C [s]."""
SWEEP_STANCE: float = 0.2
"""τ_stance of the ride/step-height sweeps and of the velocity sweep [s] (the thesis's steady expert)."""
RIDE_HEIGHTS: tuple[float, ...] = (0.18, 0.21, 0.25, 0.28)
"""Ride heights of the Fig. A.2 sweep [m] (the expert's range is 0.18-0.28 m)."""
STEP_HEIGHTS: tuple[float, ...] = (0.05, 0.09, 0.13, 0.18)
"""Step heights of the Fig. A.3 sweep [m] (the expert's range is 0.05-0.18 m)."""

DEFAULT_TARGETS: int = 10
"""Random waypoints per CoM condition (about 95 s of walking)."""
QUICK_TARGETS: int = 1
QUICK_TARGET_DISTANCE: tuple[float, float] = (1.8, 2.0)

DEFAULT_DURATION: float = 8.0
"""Length of each fixed-command run of the velocity sweep [s] (1 s ramp + 1 s settling + 6 s measured)."""
QUICK_DURATION: float = 3.0

SWEEP_POINTS: int = 11
"""Points per velocity component (vx, wz: steps of 0.1; vy: 7 points, steps of 0.1)."""
QUICK_SWEEP_POINTS: int = 3

DETREND_MIN_SECONDS: float = 1.0
"""The moving average ``M`` of the detrending spans the fewest whole gait cycles lasting at least this [s]."""
SKIP_SECONDS: float = 1.0
"""Time from the standing start that the CoM statistics leave out [s]."""
EXCERPT_START: float = 10.0
"""Start of the time-series excerpt drawn in the CoM figures [s] (earlier in short runs)."""
EXCERPT_LENGTH: float = 3.0
"""Length of that excerpt [s]."""
PATH_DECIMATION: int = 10
"""Every how many control steps the drawn CoM path keeps a point."""

FIG_SIZE: tuple[float, float] = (9.0, 6.0)


# --- metrics ---------------------------------------------------------------------------------------


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


def fit_line(x: Sequence[float], y: Sequence[float]) -> dict[str, float]:
    """Least-squares line ``y ≈ slope x + offset`` over the finite pairs, with its RMS and largest residual.

    NaNs throughout when fewer than two distinct finite x values remain.
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    keep = np.isfinite(x) & np.isfinite(y)
    x, y = x[keep], y[keep]
    if len(np.unique(x)) < 2:
        nan = float("nan")
        return {"slope": nan, "offset": nan, "rmse": nan, "max_abs_residual": nan, "points": len(x)}
    slope, offset = np.polyfit(x, y, 1)
    residual = y - (slope * x + offset)
    return {
        "slope": float(slope),
        "offset": float(offset),
        "rmse": float(np.sqrt(np.mean(residual**2))),
        "max_abs_residual": float(np.abs(residual).max()),
        "points": len(x),
    }


# --- conditions and the worker side ------------------------------------------------------------------


@dataclass(frozen=True)
class WalkJob:
    """One CoM condition: the expert walks to the waypoints."""

    stance_duration: float
    ride_height: float
    step_height: float
    seed: int
    targets: tuple[tuple[float, float], ...]

    @property
    def label(self) -> str:
        return f"walk stance={self.stance_duration:g}s ride={self.ride_height:g}m step={self.step_height:g}m"


@dataclass(frozen=True)
class HoldJob:
    """One velocity-sweep point: the expert holds a fixed command from a standing start."""

    command: tuple[float, float, float]
    duration: float
    seed: int

    @property
    def label(self) -> str:
        return "hold vx={:+.2f} vy={:+.2f} wz={:+.2f}".format(*self.command)


Job = WalkJob | HoldJob


def _expert_and_sim(stance: float, ride: float, step: float, seed: int):
    from krl.control.expert import ExpertParams, MPCExpert
    from krl.sim.model import build_model
    from krl.sim.robot import A1Sim

    expert = MPCExpert(ExpertParams(stance_duration=stance, ride_height=ride, step_height=step))
    return expert, A1Sim(build_model("flat", None, seed))


def _run_walk(job: WalkJob) -> dict[str, Any]:
    from krl.runner import Runner

    expert, sim = _expert_and_sim(job.stance_duration, job.ride_height, job.step_height, job.seed)
    rows: list[np.ndarray] = []

    def on_step(record) -> None:
        after = record.after
        rows.append(np.concatenate(([after.time], after.com, after.rpy, record.command)))

    runner = Runner(sim, expert, on_step=on_step)
    error = None
    targets_reached, fell, timed_out = 0, False, False
    try:
        result = runner.walk_to(np.array(job.targets), target_time_limit=TARGET_TIME_LIMIT)
        targets_reached, fell, timed_out = result.targets_reached, result.fell, result.timed_out
    except RuntimeError as exc:  # MPCError, SimulationUnstableError: keep what was recorded
        error = f"{type(exc).__name__}: {exc}"
    data = np.array(rows).reshape(-1, 10)
    t, com, rpy = data[:, 0], data[:, 1:4], data[:, 4:7]
    cycle = gait_cycle(job.stance_duration)
    window = detrend_window_steps(cycle)
    skip = min(len(t), round(SKIP_SECONDS / CONTROL_DT))
    metrics = com_metrics(com, rpy, window, skip)
    # time-series excerpt for the figure
    deviation, where = com_deviation(com[skip:], rpy[skip:, 2], window)
    t_dev = t[skip:][where]
    start = EXCERPT_START
    if len(t_dev) and t_dev[-1] - EXCERPT_LENGTH < start:
        start = max(float(t_dev[0]), float(t_dev[-1]) - EXCERPT_LENGTH)
    pick = (t_dev >= start) & (t_dev <= start + EXCERPT_LENGTH)
    duration = float(t[-1]) if len(t) else 0.0
    path_length = float(np.linalg.norm(np.diff(com[:, :2], axis=0), axis=1).sum()) if len(t) > 1 else 0.0
    return {
        "targets_reached": targets_reached,
        "fell": fell,
        "timed_out": timed_out,
        "error": error,
        "sim_seconds": round(duration, 3),
        "gait_cycle": cycle,
        "window_steps": window,
        "mean_speed": path_length / duration if duration > 0 else float("nan"),
        **metrics,
        "path_xy": com[::PATH_DECIMATION, :2].copy(),
        "excerpt": {
            "t": t_dev[pick],
            "dev_x": deviation[pick, 0],
            "dev_y": deviation[pick, 1],
            "height": com[skip:][where][pick, 2],
        },
    }


def _run_hold(job: HoldJob) -> dict[str, Any]:
    from krl.runner import Runner

    expert, sim = _expert_and_sim(SWEEP_STANCE, NOMINAL_RIDE_HEIGHT, NOMINAL_STEP_HEIGHT, job.seed)
    runner = Runner(sim, expert)
    error = None
    try:
        result = runner.hold_command(np.array(job.command), job.duration, ramp=HOLD_RAMP)
        realised, fell = np.array(result.realised).reshape(-1, 3), result.fell
    except RuntimeError as exc:
        error, realised, fell = f"{type(exc).__name__}: {exc}", np.zeros((0, 3)), True
    if len(realised):
        mean, std = realised.mean(axis=0), realised.std(axis=0)
    else:
        mean = std = np.full(3, np.nan)
    return {
        "fell": fell,
        "error": error,
        "samples": len(realised),
        "mean": [float(v) for v in mean],
        "std": [float(v) for v in std],
    }


def _run_job(job: Job) -> dict[str, Any]:
    start = time.perf_counter()
    out = _run_walk(job) if isinstance(job, WalkJob) else _run_hold(job)
    out["wall_seconds"] = time.perf_counter() - start
    return out


# --- planning ---------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Settings:
    seed: int
    targets: int
    duration: float
    quick: bool


def _waypoints(settings: Settings) -> tuple[tuple[float, float], ...]:
    from krl.runner import random_targets

    distance = QUICK_TARGET_DISTANCE if settings.quick else TARGET_DISTANCE
    points = random_targets(np.random.default_rng(settings.seed), settings.targets, (0.0, 0.0), distance)
    return tuple((float(x), float(y)) for x, y in points)


def _com_conditions(which: str) -> list[tuple[str, dict[str, float]]]:
    """(legend label, expert settings) per condition of a CoM figure."""
    ride, step = NOMINAL_RIDE_HEIGHT, NOMINAL_STEP_HEIGHT
    if which == "com-variance":
        return [(f"τ_stance = {s:g} s", {"stance": s, "ride": ride, "step": step}) for s in STANCE_DURATIONS]
    if which == "ride-height":
        return [
            (f"ride height {h:g} m", {"stance": SWEEP_STANCE, "ride": h, "step": step}) for h in RIDE_HEIGHTS
        ]
    return [(f"step height {h:g} m", {"stance": SWEEP_STANCE, "ride": ride, "step": h}) for h in STEP_HEIGHTS]


def _sweep(settings: Settings) -> list[tuple[str, float, tuple[float, float, float]]]:
    """(axis, commanded value, command) per velocity-sweep point, within CommandParams' limits."""
    from krl.control.commands import CommandParams

    params = CommandParams()
    points = QUICK_SWEEP_POINTS if settings.quick else SWEEP_POINTS
    out = []
    for axis, (low, high) in zip(
        ("vx", "vy", "wz"), (params.vx_range, params.vy_range, params.yaw_rate_range), strict=True
    ):
        count = points if axis != "vy" or settings.quick else 1 + round((high - low) / 0.1)
        for value in np.linspace(low, high, count):
            value = round(float(value), 6) + 0.0  # no -0.0
            command = [0.0, 0.0, 0.0]
            command["vx vy wz".split().index(axis)] = value
            out.append((axis, value, (command[0], command[1], command[2])))
    return out


def _plan(which: Sequence[str], settings: Settings) -> dict[str, list[tuple[Any, Job]]]:
    """Per figure: (condition description, job); equal jobs across figures are the same object key."""
    plan: dict[str, list[tuple[Any, Job]]] = {}
    waypoints = _waypoints(settings)
    for name in which:
        if name == "velocity":
            plan[name] = [
                ((axis, value), HoldJob(command, settings.duration, settings.seed))
                for axis, value, command in _sweep(settings)
            ]
        else:
            plan[name] = [
                (
                    (label, cfg),
                    WalkJob(cfg["stance"], cfg["ride"], cfg["step"], settings.seed, waypoints),
                )
                for label, cfg in _com_conditions(name)
            ]
    return plan


# --- running ----------------------------------------------------------------------------------------


def _summary_line(job: Job, result: dict[str, Any]) -> str:
    if isinstance(job, WalkJob):
        detail = (
            f"com_std x/y/z = {1e3 * result['com_std_x']:.1f}/{1e3 * result['com_std_y']:.1f}/"
            f"{1e3 * result['com_std_z']:.1f} mm, reached {result['targets_reached']}/{len(job.targets)}"
        )
    else:
        detail = "realised = ({:+.3f}, {:+.3f}, {:+.3f})".format(*result["mean"])
    flags = " FELL" if result["fell"] else ""
    flags += f" ERROR {result['error']}" if result.get("error") else ""
    return f"{job.label}: {detail}{flags} ({result['wall_seconds']:.1f} s)"


def _execute(jobs: list[Job], workers: int, progress: bool) -> dict[Job, dict[str, Any]]:
    """Run each distinct job once through :func:`krl.parallel.run_jobs` (in this process for one worker);
    with ``progress``, a bar on a terminal and one line per finished condition on stderr either way."""
    # longest first: waypoint walks before fixed-command holds
    order = sorted(jobs, key=lambda job: isinstance(job, HoldJob))
    done = 0

    def report(index: int, result: dict[str, Any]) -> None:
        nonlocal done
        done += 1
        if progress:
            print(f"[{done}/{len(order)}] {_summary_line(order[index], result)}", file=sys.stderr, flush=True)

    results = run_jobs(
        _run_job, order, workers, on_result=report, progress="expert conditions" if progress else None
    )
    return dict(zip(order, results, strict=True))


# --- output -----------------------------------------------------------------------------------------


COM_COLUMNS: tuple[str, ...] = (
    "label",
    "stance_duration",
    "ride_height",
    "step_height",
    "com_std_x",
    "com_std_y",
    "com_std_z",
    "com_std",
    "roll_std_deg",
    "pitch_std_deg",
    "com_height_mean",
    "mean_speed",
    "targets_reached",
    "fell",
    "timed_out",
    "sim_seconds",
    "gait_cycle",
    "window_steps",
    "samples",
)

COM_METRIC_TEXT = (
    "CoM deviation = Rz(yaw)^T ((I - M)^2 com) = Rz(yaw)^T (com - 2 M com + M M com), M = centred moving "
    f"average over the fewest whole gait cycles lasting >= {DETREND_MIN_SECONDS:g} s, in the trunk's "
    f"heading frame (x forward, y left, z up), from t = {SKIP_SECONDS:g} s; com_std_x/y/z = its standard "
    "deviation over time [m]; com_std = their root sum of squares [m]; roll_std_deg / pitch_std_deg = "
    "standard deviation of trunk roll / pitch over the same time [deg]; com_height_mean [m]; "
    "mean_speed = CoM path length / time [m/s]"
)


def _com_tables(which: str, conditions: list, results: dict, settings: Settings) -> tuple[dict, list]:
    rows = []
    for (label, cfg), job in conditions:
        result = results[job]
        row = {
            "label": label,
            "stance_duration": cfg["stance"],
            "ride_height": cfg["ride"],
            "step_height": cfg["step"],
            **{key: result[key] for key in COM_COLUMNS if key in result},
        }
        row["error"] = result["error"]
        rows.append(row)
    table = {
        "figure": which,
        "thesis_figure": THESIS_FIGURE[which],
        "seed": settings.seed,
        "quick": settings.quick,
        "waypoints": [list(p) for p in conditions[0][1].targets],
        "target_time_limit": TARGET_TIME_LIMIT,
        "metric": COM_METRIC_TEXT,
        "conditions": rows,
    }
    return table, rows


def _velocity_tables(conditions: list, results: dict, settings: Settings) -> tuple[dict, list]:
    rows = []
    for (axis, value), job in conditions:
        result = results[job]
        row = {"axis": axis, "commanded": value}
        for i, name in enumerate(("vx", "vy", "wz")):
            row[f"{name}_mean"] = result["mean"][i]
            row[f"{name}_std"] = result["std"][i]
        row.update(fell=result["fell"], samples=result["samples"], error=result["error"])
        rows.append(row)
    fits = {}
    for axis in ("vx", "vy", "wz"):
        points = [r for r in rows if r["axis"] == axis and not r["fell"]]
        fits[axis] = fit_line([r["commanded"] for r in points], [r[f"{axis}_mean"] for r in points])
        others = [o for o in ("vx", "vy", "wz") if o != axis]
        fits[axis]["max_abs_cross"] = max(
            (abs(r[f"{o}_mean"]) for r in points for o in others if math.isfinite(r[f"{o}_mean"])),
            default=float("nan"),
        )
    table = {
        "figure": "velocity",
        "thesis_figure": THESIS_FIGURE["velocity"],
        "seed": settings.seed,
        "quick": settings.quick,
        "stance_duration": SWEEP_STANCE,
        "duration": settings.duration,
        "ramp": HOLD_RAMP,
        "measured_from": HOLD_RAMP + HOLD_SETTLE,
        "metric": (
            "each point: the command (others zero) held from a standing start, rising from zero over "
            f"{HOLD_RAMP:g} s; realised (vx, vy) of the trunk origin in its heading frame [m/s] and yaw "
            f"rate wz [rad/s] at every control step from t = {HOLD_RAMP + HOLD_SETTLE:g} s; *_mean / *_std "
            "= mean / standard deviation over time; fits: least squares realised_mean = slope * commanded "
            "+ offset over the points that did not fall; max_abs_cross = largest |mean| of the two "
            "uncommanded components"
        ),
        "fits": fits,
        "conditions": rows,
    }
    return table, rows


VELOCITY_COLUMNS = (
    "axis",
    "commanded",
    "vx_mean",
    "vx_std",
    "vy_mean",
    "vy_std",
    "wz_mean",
    "wz_std",
    "fell",
    "samples",
)


def _plot_com(which: str, conditions: list, results: dict, settings: Settings):
    from matplotlib.figure import Figure

    fig = Figure(figsize=FIG_SIZE, dpi=FIG_DPI, layout="constrained")
    axes = fig.subplots(2, 3)
    colors = [f"C{i}" for i in range(len(conditions))]
    labels = [label for (label, _), _ in conditions]
    waypoints = np.array(conditions[0][1].targets)
    ax = axes[0, 0]
    handles = []
    for color, label, (_, job) in zip(colors, labels, conditions, strict=True):
        path = results[job]["path_xy"]
        handles += ax.plot(path[:, 0], path[:, 1], color=color, lw=0.8, label=label)
        if results[job]["fell"]:
            ax.plot(*path[-1], "x", color=color, ms=8)
    marks = ax.plot(0.0, 0.0, "ko", ms=4, label="start")
    marks += ax.plot(waypoints[:, 0], waypoints[:, 1], "k*", ms=7, label="waypoints")
    if any(results[job]["fell"] for _, job in conditions):
        marks += ax.plot([], [], "kx", ms=8, label="fell")
    ax.set(xlabel="x [m]", ylabel="y [m]", title="CoM path (top view)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(handles=marks, fontsize=6, loc="best")
    fig.legend(handles=handles, loc="outside lower center", ncol=len(handles), fontsize=8)
    panels = (
        (axes[0, 1], "dev_y", 1e3, "lateral CoM deviation y' [mm]"),
        (axes[0, 2], "height", 1.0, "CoM height z [m]"),
        (axes[1, 0], "dev_x", 1e3, "forward CoM deviation x' [mm]"),
    )
    for ax, key, scale, ylabel in panels:
        for color, label, (_, job) in zip(colors, labels, conditions, strict=True):
            excerpt = results[job]["excerpt"]
            ax.plot(excerpt["t"], scale * excerpt[key], color=color, lw=0.8, label=label)
        ax.set(xlabel="time [s]", ylabel=ylabel, title=ylabel.split(" [")[0] + " (excerpt)")
    width = 0.8 / len(conditions)
    ax = axes[1, 1]
    for i, (color, label, (_, job)) in enumerate(zip(colors, labels, conditions, strict=True)):
        values = [1e3 * results[job][k] for k in ("com_std_x", "com_std_y", "com_std_z")]
        bars = ax.bar(
            np.arange(3) + (i - (len(conditions) - 1) / 2) * width, values, width, color=color, label=label
        )
        ax.bar_label(bars, fmt="%.1f", fontsize=5)
    ax.set_xticks(np.arange(3), ["x' forward", "y' lateral", "z up"])
    ax.set(ylabel="std of CoM deviation [mm]", title="CoM standard deviation (whole run)")
    ax = axes[1, 2]
    for i, (color, label, (_, job)) in enumerate(zip(colors, labels, conditions, strict=True)):
        values = [results[job]["roll_std_deg"], results[job]["pitch_std_deg"]]
        bars = ax.bar(
            np.arange(2) + (i - (len(conditions) - 1) / 2) * width, values, width, color=color, label=label
        )
        ax.bar_label(bars, fmt="%.2f", fontsize=5)
    ax.set_xticks(np.arange(2), ["roll", "pitch"])
    ax.set(ylabel="std of trunk angle [deg]", title="trunk tilt standard deviation (whole run)")
    for ax in axes.flat:
        ax.tick_params(labelsize=7)
        ax.title.set_fontsize(8)
        ax.xaxis.label.set_fontsize(7)
        ax.yaxis.label.set_fontsize(7)
    stance = {
        "com-variance": "varying τ_stance",
        "ride-height": f"τ_stance = {SWEEP_STANCE:g} s, varying ride height",
        "step-height": f"τ_stance = {SWEEP_STANCE:g} s, varying step height",
    }[which]
    fig.suptitle(
        f"Thesis {THESIS_FIGURE[which]}: MPC expert CoM, {stance} "
        f"(seed {settings.seed}, {len(waypoints)} waypoints{', quick' if settings.quick else ''})",
        fontsize=9,
    )
    return fig


def draw_fit_and_axes(ax, fit: dict[str, float], lim: float, name: str, unit: str, label: str) -> None:
    """On a realised-vs-commanded panel: the fitted line over [-lim, lim] (if finite) and the axes'
    labels, limits and title. Shared by the expert's and the kernel's velocity figures."""
    if math.isfinite(fit["slope"]):
        ax.plot(
            [-lim, lim],
            [fit["offset"] - fit["slope"] * lim, fit["offset"] + fit["slope"] * lim],
            color="C1",
            lw=0.8,
            label=label,
        )
    ax.set(
        xlabel=f"commanded {name} [{unit}]", ylabel=f"realised {name} [{unit}]", xlim=(-lim, lim), title=name
    )


def _plot_velocity(conditions: list, results: dict, settings: Settings, fits: dict):
    from matplotlib.figure import Figure

    fig = Figure(figsize=(FIG_SIZE[0], FIG_SIZE[1] * 0.6), dpi=FIG_DPI, layout="constrained")
    axes = fig.subplots(1, 3)
    names = {
        "vx": ("forward velocity v_x", "m/s"),
        "vy": ("lateral velocity v_y", "m/s"),
        "wz": ("yaw rate ω_z", "rad/s"),
    }
    for ax, axis in zip(axes, ("vx", "vy", "wz"), strict=True):
        index = ("vx", "vy", "wz").index(axis)
        points = [(value, results[job]) for (a, value), job in conditions if a == axis]
        x = np.array([p[0] for p in points])
        mean = np.array([p[1]["mean"][index] for p in points])
        std = np.array([p[1]["std"][index] for p in points])
        fell = np.array([p[1]["fell"] for p in points], dtype=bool)
        lim = max(abs(x).max(), 1e-3) * 1.15
        ax.plot([-lim, lim], [-lim, lim], "k--", lw=0.8, label="identity (realised = commanded)")
        ax.errorbar(
            x[~fell],
            mean[~fell],
            yerr=std[~fell],
            fmt="o",
            ms=4,
            capsize=3,
            color="C0",
            label="MPC expert: mean ± std over time",
        )
        if fell.any():
            ax.plot(x[fell], mean[fell], "rx", ms=8, label="fell")
        fit = fits[axis]
        label = f"fit: slope {fit['slope']:.3f}, offset {fit['offset']:+.3f}"
        draw_fit_and_axes(ax, fit, lim, *names[axis], label)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=6, loc="upper left")
        ax.tick_params(labelsize=7)
        ax.title.set_fontsize(8)
        ax.xaxis.label.set_fontsize(7)
        ax.yaxis.label.set_fontsize(7)
    fig.suptitle(
        f"Thesis {THESIS_FIGURE['velocity']}: realised vs commanded velocity, MPC expert "
        f"(τ_stance = {SWEEP_STANCE:g} s, {settings.duration:g} s holds, measured from "
        f"{HOLD_RAMP + HOLD_SETTLE:g} s{', quick' if settings.quick else ''})",
        fontsize=9,
    )
    return fig


def make_figures(
    which: str,
    out: str | os.PathLike,
    seed: int = 0,
    targets: int | None = None,
    duration: float | None = None,
    workers: int | None = None,
    quick: bool = False,
    progress: bool = True,
) -> dict[str, Any]:
    """Run the conditions and write ``NAME.png``, ``NAME.json``, ``NAME.csv`` per figure into ``out``.

    Returns ``{"figures": {name: {"png", "json", "csv", "table"}}, "wall_seconds", "conditions_run"}``.

    Raises:
        PlotError: unknown ``which`` or a bad value (checked before anything runs or is written).
    """
    if which not in CHOICES:
        raise PlotError(f"unknown figure {which!r}; choose from {', '.join(CHOICES)}")
    targets = (QUICK_TARGETS if quick else DEFAULT_TARGETS) if targets is None else targets
    duration = (QUICK_DURATION if quick else DEFAULT_DURATION) if duration is None else duration
    if isinstance(targets, bool) or not isinstance(targets, int) or targets < 1:
        raise PlotError(f"--targets must be a whole number >= 1, got {targets!r}")
    minimum = HOLD_RAMP + HOLD_SETTLE
    if not (isinstance(duration, (int, float)) and math.isfinite(duration) and duration > minimum):
        raise PlotError(
            f"--duration must be a number of seconds > {minimum:g} ({HOLD_RAMP:g} s ramp + {HOLD_SETTLE:g} s "
            f"settling), got {duration!r}"
        )
    if workers is None:
        workers = os.cpu_count() or 1
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise PlotError(f"--workers must be a whole number >= 1, got {workers!r}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise PlotError(f"--seed must be a whole number >= 0, got {seed!r}")
    out_dir = Path(out)
    if out_dir.exists() and not out_dir.is_dir():
        raise PlotError(f"--out {str(out_dir)!r} exists and is not a folder")

    settings = Settings(seed=seed, targets=targets, duration=float(duration), quick=quick)
    names = FIGURES if which == "all" else (which,)
    plan = _plan(names, settings)
    jobs = list(dict.fromkeys(job for conditions in plan.values() for _, job in conditions))
    out_dir.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    results = _execute(jobs, workers, progress)
    figures: dict[str, Any] = {}
    for name, conditions in plan.items():
        if name == "velocity":
            table, rows = _velocity_tables(conditions, results, settings)
            fig = _plot_velocity(conditions, results, settings, table["fits"])
            columns: Sequence[str] = VELOCITY_COLUMNS
        else:
            table, rows = _com_tables(name, conditions, results, settings)
            fig = _plot_com(name, conditions, results, settings)
            columns = COM_COLUMNS
        paths = {kind: out_dir / f"{name}.{kind}" for kind in ("png", "json", "csv")}
        table = json_value(table)
        write_atomic(paths["png"], figure_bytes(fig))
        write_atomic(paths["json"], (json.dumps(table, indent=2, ensure_ascii=False) + "\n").encode())
        write_atomic(paths["csv"], csv_bytes(columns, rows))
        figures[name] = {**{kind: str(path) for kind, path in paths.items()}, "table": table}
    return {
        "figures": figures,
        "conditions_run": len(jobs),
        "workers": workers,
        "wall_seconds": round(time.perf_counter() - start, 2),
    }
