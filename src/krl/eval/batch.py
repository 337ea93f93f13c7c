"""Batched evaluation: a worker walks its runs of one controller together, in the one episode loop.

:func:`run_batch` takes runs (:class:`krl.eval.evaluate.EvalRun`: courses from their starts, push-sweep
attempts, friction-sweep runs) of one controller and seed, builds the controller once
(:meth:`krl.eval.controllers.ControllerSpec.build_batch`) and walks up to :data:`BATCH_SLOTS` runs at once,
one robot each, in one :class:`krl.task.episode.EpisodeBatch`; a robot whose run ended starts the next run
waiting. Each robot's run is the one :func:`krl.eval.episodes.score_walk` walks alone, step for step and bit
for bit (the networks run row by row, :mod:`krl.util.affine`), so a record does not depend on the runs
walked beside it, on the batch size or on the number of workers; only ``wall_seconds`` (the wall time the
run took while sharing the batch) differs.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any, NamedTuple

import numpy as np

from krl.control.commands import CommandParams
from krl.control.types import attach_scene
from krl.eval.episodes import EpisodeScorer, push_attempt_metrics
from krl.sim.backend import SimBackend, make_backend
from krl.sim.model import BuiltModel, build_model
from krl.sim.pushes import OnePush, Push
from krl.task.episode import EpisodeBatch, EpisodeStep
from krl.task.reward import EVALUATION_REWARD
from krl.task.waypoints import TaskStatus, WaypointTask
from krl.util.timing import CONTROL_DT

BATCH_SLOTS: int = 16
"""Robots a worker walks at once (the training recipe's robots per worker)."""


class _Walk(NamedTuple):
    """What one run walks."""

    built: BuiltModel
    targets: np.ndarray
    """Waypoints, world (x, y) [m]. Shape: (K, 2)."""
    start: tuple[float, float, float]
    """Start pose (x, y, yaw) [m, m, rad]."""
    time_limit: float
    """[s], for each waypoint and for the whole walk."""
    d_min: float
    """Waypoint threshold [m]."""
    push: Push | None = None
    heading_frame: bool = False
    """The push's force is relative to the base's heading when it starts."""


@dataclass
class _Run:
    """One run walking in a slot of the batch."""

    index: int
    """The run's place in :func:`run_batch`'s runs."""
    task: WaypointTask
    scorer: EpisodeScorer
    push: Push | None
    started: float = field(default_factory=time.perf_counter)
    """Wall clock at its start [s]."""
    push_heading: float | None = None
    """The base's yaw [rad] before the push's first control step (None until the push came)."""


def _walk(run, flat: list[BuiltModel], models: dict[str, BuiltModel]) -> _Walk:
    """What ``run`` walks; course models are compiled once per course."""
    sweep = run.sweep
    if sweep is not None:
        if not flat:
            flat.append(build_model("flat"))
        push = sweep.push(run.magnitude, run.attempt)
        target = np.array([sweep.target])
        heading = sweep.directions != "uniform"
        return _Walk(flat[0], target, (0.0, 0.0, 0.0), sweep.time_limit, sweep.d_min, push, heading)
    course = run.course
    fingerprint = course.fingerprint
    if fingerprint not in models:
        models[fingerprint] = course.build()
    start = tuple(course.starts[run.start])
    return _Walk(models[fingerprint], np.array(course.waypoints), start, course.time_limit, course.d_min)


def run_batch(runs: Sequence) -> list[dict[str, Any]]:
    """The records (:meth:`krl.eval.evaluate.EvalRun.record`, as :func:`krl.eval.evaluate.run_one` makes
    them) of ``runs``, all of one controller and seed and none filmed, in their order."""
    spec, seed = runs[0].controller, runs[0].seed
    if any(t.controller != spec or t.seed != seed or t.video for t in runs):
        raise ValueError("a batch holds runs of one controller and seed, none filmed")
    flat: list[BuiltModel] = []
    models: dict[str, BuiltModel] = {}
    walks = [_walk(run, flat, models) for run in runs]
    slots = min(BATCH_SLOTS, len(runs))
    sims = make_backend([walks[0].built] * slots)
    episodes = EpisodeBatch(sims, EVALUATION_REWARD)
    controller = spec.build_batch(seed, slots)
    attach_scene(controller, sims)
    waiting = deque(range(len(runs)))
    running: list[_Run | None] = [None] * slots
    metrics: list[dict[str, Any] | None] = [None] * len(runs)

    def begin(slot: int) -> None:
        index = waiting.popleft()
        walk = walks[index]
        sims.replace(slot, walk.built)
        x, y, yaw = walk.start
        state = sims.reset(slot, xy=(x, y), yaw=yaw)
        controller.reset(slot, state)
        params = replace(CommandParams(), d_min=walk.d_min)
        task = WaypointTask(walk.targets, params, walk.time_limit, walk.time_limit)
        task.reset(state.base_pos[:2])
        push = walk.push
        over = episodes.start([slot], [task], [None if push is None else OnePush(push, walk.heading_frame)])
        running[slot] = _Run(index, task, EpisodeScorer(walk.targets), push)
        if over[0]:  # every waypoint within reach at the start: a walk of no step
            running[slot].scorer.passed(task.reached_count)
            end(slot, timed_out=task.status is TaskStatus.TIMED_OUT)

    def end(slot: int, timed_out: bool = False, error: str | None = None) -> None:
        run = running[slot]
        episodes.stop(slot)
        wall = time.perf_counter() - run.started
        result = run.scorer.metrics(float(sims.step_counts[slot] * CONTROL_DT), wall, timed_out, error)
        if run.push is not None:
            result["push_heading"] = run.push_heading
        metrics[run.index] = result
        running[slot] = None

    while True:
        for slot in range(slots):
            while running[slot] is None and waiting:
                begin(slot)
        if not episodes.active.any():
            break
        rows = np.flatnonzero(episodes.active)
        command, failed = controller.act(episodes.states, episodes.commands, rows)
        for slot, error in failed.items():
            end(slot, error=f"{type(error).__name__}: {error}")
        step = episodes.step(*command)
        for slot in rows.tolist():
            if running[slot] is not None:
                _count(step, slot, running[slot], sims, end)
    return [_record(*parts) for parts in zip(runs, walks, metrics, strict=True)]


def _count(step: EpisodeStep, slot: int, run: _Run, sims: SimBackend, end) -> None:
    """Score robot ``slot``'s part of ``step`` into its run, and end the run where the step ended it."""
    if step.unstable[slot]:
        end(slot, error=f"SimulationUnstableError: {sims.divergence(slot)}")
        return
    run.scorer.add(step, slot)
    push = run.push
    if push is not None and run.push_heading is None and push.active_at(int(sims.step_counts[slot]) - 1):
        run.push_heading = float(step.before.rpy[slot, 2])  # the step just taken is the push's first
    if step.ended[slot]:
        timed_out = run.task.status is TaskStatus.TIMED_OUT and not step.fell[slot]
        run.scorer.passed(run.task.reached_count)
        end(slot, timed_out=bool(timed_out))


def _record(run, walk: _Walk, metrics: dict[str, Any]) -> dict[str, Any]:
    """A run's record from its walk's metrics (the push sweep's with the push it walked)."""
    if run.sweep is not None:
        metrics = push_attempt_metrics(run.sweep, run.attempt, walk.push, metrics)
    return run.record(metrics)
