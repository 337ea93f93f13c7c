"""The expert's runs behind its figures, one job each: a walk to waypoints (a CoM condition) or a hold of a
fixed command (a velocity-sweep point). Jobs are plain frozen data, so they travel to worker processes
(:func:`krl.util.parallel.run_jobs`) and equal jobs of two figures run once.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from krl.analysis.common import hold_velocity
from krl.analysis.expert.metrics import (
    SKIP_SECONDS,
    com_deviation,
    com_metrics,
    detrend_window_steps,
    gait_cycle,
)
from krl.control.expert import NOMINAL_RIDE_HEIGHT, NOMINAL_STEP_HEIGHT
from krl.task import TARGET_TIME_LIMIT
from krl.util.timing import CONTROL_DT

SWEEP_STANCE: float = 0.2
"""τ_stance of the ride/step-height sweeps and of the velocity sweep [s] (the thesis's steady expert)."""
EXCERPT_START: float = 10.0
"""Start of the time-series excerpt drawn in the CoM figures [s] (earlier in short runs)."""
EXCERPT_LENGTH: float = 3.0
"""Length of that excerpt [s]."""
PATH_DECIMATION: int = 10
"""Every how many control steps the drawn CoM path keeps a point."""


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
    """A fresh expert with these stance duration [s], ride and step heights [m], on flat ground."""
    from krl.control.expert import ExpertParams, MPCExpert
    from krl.sim.model import build_model
    from krl.sim.robot import A1Sim

    expert = MPCExpert(ExpertParams(stance_duration=stance, ride_height=ride, step_height=step))
    return expert, A1Sim(build_model("flat", None, seed))


def _run_walk(job: WalkJob) -> dict[str, Any]:
    """The walk's outcome and CoM metrics (:func:`com_metrics`), its CoM path every
    :data:`PATH_DECIMATION` steps ((M, 2) [m]) and an excerpt of the deviation and height to draw."""
    from krl.task.runner import Runner

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
    """The realised velocity while holding the job's command (:func:`krl.analysis.common.hold_velocity`)."""
    expert, sim = _expert_and_sim(SWEEP_STANCE, NOMINAL_RIDE_HEIGHT, NOMINAL_STEP_HEIGHT, job.seed)
    return hold_velocity(sim, expert, job.command, job.duration)


def run_job(job: Job) -> dict[str, Any]:
    """Run one job (in a worker process); its result, with ``wall_seconds`` [s]."""
    start = time.perf_counter()
    out = _run_walk(job) if isinstance(job, WalkJob) else _run_hold(job)
    out["wall_seconds"] = time.perf_counter() - start
    return out
