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

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any, NamedTuple

import numpy as np

from krl.control.commands import CommandParams
from krl.control.types import attach_scene
from krl.eval.episodes import push_attempt_metrics, run_metrics
from krl.sim.backend import make_backend
from krl.sim.model import BuiltModel, build_model
from krl.sim.pushes import OnePush, Push
from krl.task.episode import EpisodeBatch
from krl.task.record import EpisodeRecords
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
    targets: int
    """Its waypoints."""
    pushed: bool
    """It has a push (its record carries ``push_heading``)."""


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
    records = EpisodeRecords(slots)
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
        records.begin([slot], [push])
        running[slot] = _Run(index, task, len(walk.targets), push is not None)
        if over[0]:  # every waypoint within reach at the start: a walk of no step
            end(slot)

    def end(slot: int, error: str | None = None) -> None:
        run = running[slot]
        episodes.stop(slot)
        task = run.task
        record = records.finish(slot, task.reached_count, task.status is TaskStatus.TIMED_OUT, error)
        result = run_metrics(record, run.targets, float(sims.step_counts[slot] * CONTROL_DT))
        if run.pushed:
            result["push_heading"] = record.push_heading
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
        walked = [slot for slot in rows.tolist() if running[slot] is not None]
        for slot in walked:
            if step.unstable[slot]:
                end(slot, error=f"SimulationUnstableError: {sims.divergence(slot)}")
        walked = [slot for slot in walked if running[slot] is not None]
        records.add(step, walked, sims.step_counts)
        for slot in walked:
            if step.ended[slot]:
                end(slot)
    return [_record(*parts) for parts in zip(runs, walks, metrics, strict=True)]


def _record(run, walk: _Walk, metrics: dict[str, Any]) -> dict[str, Any]:
    """A run's record from its walk's metrics (the push sweep's with the push it walked)."""
    if run.sweep is not None:
        metrics = push_attempt_metrics(run.sweep, run.attempt, walk.push, metrics)
    return run.record(metrics)
