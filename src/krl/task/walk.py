"""One walk of a ``… run`` command (``krl expert run``, ``krl kernel run``, ``krl agent run``): a controller
on a terrain to random or given waypoints, or at a fixed command, optionally filmed; its printed summary."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from krl.control.types import Controller
from krl.task.waypoints import TARGET_TIME_LIMIT, random_targets
from krl.util.rounding import readable


@dataclass(frozen=True)
class WalkPlan:
    """What to walk: the terrain (``terrain``, its ``params``, ``seed`` of the terrain's and waypoints'
    random draws); the waypoints (``waypoints`` given, else ``targets`` random ones) or a fixed velocity
    ``command`` (vx, vy, wz) for ``duration`` [s]; the time allowed per waypoint; an MP4 ``video`` of
    ``video_size`` (width, height) pixels (None: the recorder's)."""

    terrain: str = "flat"
    params: dict[str, Any] = field(default_factory=dict)
    seed: int = 0
    targets: int = 5
    waypoints: tuple[tuple[float, float], ...] = ()
    command: tuple[float, float, float] | None = None
    duration: float = 10.0
    target_time_limit: float = TARGET_TIME_LIMIT
    video: str | None = None
    video_size: tuple[int, int] | None = None

    def __post_init__(self) -> None:
        if self.command is None and not self.waypoints and self.targets < 1:
            raise ValueError(f"--targets must be >= 1, got {self.targets}")


def walk(
    plan: WalkPlan, controller: Controller, step_hook: Callable[[], None] | None = None
) -> dict[str, Any]:
    """Walk ``controller`` as ``plan`` says; returns the summary a ``… run`` command prints (rounded by
    :func:`krl.util.rounding.readable`). ``step_hook()`` is called after every control step (e.g. to collect
    timings)."""
    from krl.sim.model import build_model
    from krl.sim.robot import A1Sim
    from krl.task.runner import Runner

    sim = A1Sim(build_model(plan.terrain, plan.params, plan.seed))
    recorder = None
    if plan.video:
        from krl.sim.video import VideoRecorder

        size = {} if plan.video_size is None else {"width": plan.video_size[0], "height": plan.video_size[1]}
        recorder = VideoRecorder(sim, plan.video, **size)

    def on_step(record) -> None:
        if step_hook is not None:
            step_hook()
        if recorder is not None:
            recorder.capture()

    runner = Runner(sim, controller, on_step=on_step)
    try:
        if plan.command is not None:
            result = runner.hold_command(np.array(plan.command), plan.duration)
            targets = np.zeros((0, 2))
        else:
            if plan.waypoints:
                targets = np.array(plan.waypoints)
            else:
                targets = random_targets(np.random.default_rng(plan.seed), plan.targets, sim.terrain.spawn_xy)
            result = runner.walk_to(targets, target_time_limit=plan.target_time_limit)
    finally:
        if recorder is not None:
            recorder.close()
    return readable(_summary(plan, result, len(targets), sim.terrain.name))


def _summary(plan: WalkPlan, result, targets: int, terrain: str) -> dict[str, Any]:
    """The walk's summary: waypoints and how it ended, times, real-time factor, mean velocity, terrain."""
    summary: dict[str, Any] = {
        "targets": targets,
        "targets_reached": result.targets_reached,
        "fell": result.fell,
        "timed_out": result.timed_out,
        "sim_seconds": result.sim_seconds,
        "wall_seconds": result.wall_seconds,
        "real_time_factor": result.sim_seconds / max(result.wall_seconds, 1e-9),
        "mean_velocity": [float(v) for v in result.mean_velocity()],
        "terrain": terrain,
    }
    if plan.video:
        summary["video"] = str(plan.video)
    return summary
