"""The one episode record: what every driver of the episode loop (:class:`krl.task.episode.EpisodeBatch`)
keeps of an episode, kept one way.

Training (:class:`krl.agent.env.ResidualEnvBatch`'s ``info["episode"]``), batched evaluation
(:func:`krl.eval.batch.run_batch`) and a walk scored alone (:func:`krl.eval.episodes.score_walk`) each hold
an :class:`EpisodeRecords` beside their :class:`krl.task.episode.EpisodeBatch`: :meth:`EpisodeRecords.begin`
with the episode, :meth:`EpisodeRecords.add` after each of its control steps, :meth:`EpisodeRecords.finish`
when it ends, which gives the :class:`EpisodeRecord` the driver writes out. What ended the episode
(:data:`krl.task.episode.ENDINGS`), the waypoints it reached and the base's heading at its push are decided
here only.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from krl.sim.pushes import Push
from krl.task.episode import EpisodeStep, ending

__all__ = ["PUSH_VERDICT_TIME", "EpisodeRecord", "EpisodeRecords", "push_heading"]

PUSH_VERDICT_TIME: float = 2.0
"""A push is survived when the robot has not fallen this long after its start [s] (the push lasts 0.3 s)."""


def push_heading(push: Push | None, step: EpisodeStep, index: int, step_count: int) -> float | None:
    """The base's yaw [rad] the robot ``index`` had before ``step`` when ``step`` is the first control step
    of its ``push`` (the robot's ``step_count`` control steps include it), else None."""
    if push is not None and push.active_at(step_count - 1):
        return float(step.before.rpy[index, 2])
    return None


@dataclass(frozen=True)
class EpisodeRecord:
    """One ended episode."""

    steps: int
    """Control steps taken."""
    reward: float
    """The sum of the step rewards (each the sum of the step's terms)."""
    terms: dict[str, float]
    """Each reward term summed over the steps."""
    targets_reached: int
    """Waypoints reached (those the task left behind, unless an error ended the episode: then those its
    steps reached)."""
    fell: bool
    """The robot fell (or its physics diverged)."""
    unstable: bool
    """The robot's physics diverged."""
    timed_out: bool
    """The task ran out of time (a waypoint's or the whole walk's) without a fall or an error."""
    error: str | None
    """The one-line reason an error ended the episode (the simulation diverged, the controller gave up)."""
    distance_walked: float
    """Planar path length of the base [m]."""
    push_heading: float | None
    """The base's yaw [rad] before its push's first control step; None without a push, or before it came."""
    wall_seconds: float
    """Wall time from the episode's start to its end [s]."""

    @property
    def ended(self) -> str:
        """Why the episode ended (:data:`krl.task.episode.ENDINGS`)."""
        return ending(self.error, self.fell, self.timed_out)


class EpisodeRecords:
    """The running records of N robots' episodes (arrays over the robots).

    Args:
        n: robots.
    """

    def __init__(self, n: int) -> None:
        self.steps = np.zeros(n, dtype=np.int64)
        self.reward = np.zeros(n)
        self.terms: dict[str, np.ndarray] = {}
        """Each reward term summed over the current episodes, one array of shape (N,) per term."""
        self.reached = np.zeros(n, dtype=np.int64)
        """Steps that reached a waypoint. Shape: (N,)."""
        self.fell = np.zeros(n, dtype=bool)
        self.unstable = np.zeros(n, dtype=bool)
        self.distance = np.zeros(n)
        """Planar path length of each base [m]. Shape: (N,)."""
        self.pushes: list[Push | None] = [None] * n
        self.push_headings: list[float | None] = [None] * n
        self.started = [time.perf_counter()] * n
        """Wall clock at each episode's start [s]."""
        self.push_watch = np.full(n, np.nan)
        """Start time [s] of each robot's latest push whose verdict is not known yet, else NaN."""

    def begin(self, rows: Sequence[int] | np.ndarray, pushes: Sequence[Push | None] | None = None) -> None:
        """Start the records of robots ``rows``, each with its one push (None: none, or not watched)."""
        rows = np.atleast_1d(np.asarray(rows, dtype=np.int64))
        for array in (self.steps, self.reward, self.reached, self.fell, self.unstable, self.distance):
            array[rows] = 0
        self.push_watch[rows] = np.nan
        for sums in self.terms.values():
            sums[rows] = 0.0
        now = time.perf_counter()
        for k, index in enumerate(rows.tolist()):
            self.pushes[index] = None if pushes is None else pushes[k]
            self.push_headings[index] = None
            self.started[index] = now

    def add(self, step: EpisodeStep, rows: Sequence[int] | np.ndarray, step_counts: np.ndarray) -> None:
        """Count the part of the control step ``step`` of robots ``rows``; ``step_counts``: every robot's
        control steps since its reset, the step included (shape (N,), int)."""
        rows = np.atleast_1d(np.asarray(rows, dtype=np.int64))
        self.steps[rows] += 1
        self.reward[rows] += np.sum(list(step.terms.values()), axis=0)[rows]
        for name, values in step.terms.items():
            sums = self.terms.get(name)
            if sums is None:
                sums = self.terms[name] = np.zeros(len(self.steps))
            sums[rows] += values[rows]
        self.reached[rows] += step.reached[rows]
        self.fell[rows] |= step.fell[rows]
        self.unstable[rows] |= step.unstable[rows]
        moved = step.states.base_pos[rows, :2] - step.before.base_pos[rows, :2]
        for index, (dx, dy) in zip(rows.tolist(), moved.tolist(), strict=True):
            self.distance[index] += math.hypot(dx, dy)
            if self.push_headings[index] is None:
                heading = push_heading(self.pushes[index], step, index, int(step_counts[index]))
                self.push_headings[index] = heading

    def judge_pushes(self, step: EpisodeStep) -> dict[int, bool]:
        """The push verdicts the control step ``step`` brought, by robot: False where the robot fell within
        :data:`PUSH_VERDICT_TIME` of its latest push's start, True once that time passed without a fall or
        when a new push came before the verdict."""
        verdicts: dict[int, bool] = {}
        for index, push in enumerate(step.pushes):
            if push is not None:
                if not np.isnan(self.push_watch[index]):  # a push before the last one's verdict
                    verdicts[index] = True
                self.push_watch[index] = push.start_time
        watched = ~np.isnan(self.push_watch)
        failed = watched & step.fell
        survived = watched & ~step.fell & (step.states.time - self.push_watch >= PUSH_VERDICT_TIME)
        for index in np.flatnonzero(failed | survived).tolist():
            verdicts[index] = bool(survived[index])
            self.push_watch[index] = np.nan
        return verdicts

    def finish(
        self, index: int, task_reached: int, task_timed_out: bool, error: str | None = None
    ) -> EpisodeRecord:
        """Robot ``index``'s record of the episode that has just ended: its task left ``task_reached``
        waypoints behind and ran out of time or not (``task_timed_out``); ``error``, the one-line reason
        where an error ended the episode (the task's outcome then does not count)."""
        fell = bool(self.fell[index])
        reached = int(self.reached[index])
        if error is None:
            # a step can leave two waypoints behind when the next already lies within D_min
            reached = max(reached, task_reached)
        return EpisodeRecord(
            steps=int(self.steps[index]),
            reward=float(self.reward[index]),
            terms={name: float(sums[index]) for name, sums in self.terms.items()},
            targets_reached=reached,
            fell=fell,
            unstable=bool(self.unstable[index]),
            timed_out=error is None and task_timed_out and not fell,
            error=error,
            distance_walked=float(self.distance[index]),
            push_heading=self.push_headings[index],
            wall_seconds=time.perf_counter() - self.started[index],
        )
