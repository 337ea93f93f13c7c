"""Scoring one run: a course from one start pose, or one attempt of the push sweep; the friction sweep.

:func:`score_walk` walks a :class:`krl.task.runner.Runner` and keeps its episode's record
(:class:`krl.task.record.EpisodeRecords`: the reward terms, the waypoints reached, the distance walked, the
heading at the push); :func:`run_metrics` turns the record into the run's metrics, a JSON-ready dict (keys
in :data:`RUN_METRICS`), as batched evaluation (:mod:`krl.eval.batch`) does too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from krl.control.commands import CommandParams
from krl.control.mpc import MPCError
from krl.eval.summaries import PUSH_DIRECTIONS, QUARTER
from krl.sim.pushes import OnePush, check_push_magnitude
from krl.sim.robot import SimulationUnstableError
from krl.sim.terrains import MAX_GROUND_FRICTION
from krl.task.episode import EpisodeStep
from krl.task.record import EpisodeRecord, EpisodeRecords
from krl.task.reward import EVALUATION_REWARD, RewardConfig
from krl.task.runner import Runner, RunResult, StepRecord
from krl.task.waypoints import TARGET_TIME_LIMIT
from krl.util.thesis import THESIS_PUSH_ATTEMPTS, THESIS_PUSH_MAGNITUDES

RUN_METRICS: tuple[str, ...] = (
    "targets",
    "targets_reached",
    "success",
    "fell",
    "timed_out",
    "error",
    "ended",
    "steps",
    "reward_total",
    "reward_per_step",
    "reward_terms",
    "time_to_finish",
    "distance_walked",
    "sim_seconds",
    "wall_seconds",
)
"""Keys of a run's metrics (:func:`run_metrics`). Records made before ``ended`` existed lack it."""


def run_metrics(record: EpisodeRecord, targets: int, sim_seconds: float) -> dict[str, Any]:
    """A run's metrics (keys :data:`RUN_METRICS`) from its episode's ``record`` (:mod:`krl.task.record`),
    the number of its waypoints and its simulated time [s]. The reward total is the sum of the term totals,
    the reward per step that over the steps taken (0 for no step). A run an ``error`` ended (the simulation
    diverged, the MPC gave up) is no success, and the aggregates count it as a fall.
    """
    total = sum(record.terms.values())
    success = record.targets_reached == targets and not record.fell and record.error is None
    return {
        "targets": targets,
        "targets_reached": record.targets_reached,
        "success": success,
        "fell": record.fell,
        "timed_out": record.timed_out,
        "error": record.error,
        "ended": record.ended,
        "steps": record.steps,
        "reward_total": total,
        "reward_per_step": total / record.steps if record.steps else 0.0,
        "reward_terms": dict(record.terms),
        "time_to_finish": sim_seconds if success else None,
        "distance_walked": record.distance_walked,
        "sim_seconds": sim_seconds,
        "wall_seconds": record.wall_seconds,
    }


def score_walk(
    sim,
    controller,
    targets: np.ndarray,
    start_pose: tuple[float, float, float],
    time_limit: float,
    d_min: float,
    reward: RewardConfig = EVALUATION_REWARD,
    push=None,
    video: str | Path | None = None,
    trace: list[np.ndarray] | None = None,
    push_in_heading_frame: bool = False,
    frames=None,
) -> dict[str, Any]:
    """Walk ``controller`` from ``start_pose`` through ``targets`` within ``time_limit`` [s] and score it.

    ``push`` (a :class:`krl.sim.pushes.Push`) is scheduled after the reset, and the metrics then carry
    ``push_heading``, the base's yaw [rad] at the control step the push starts (None if the run ended
    before it); with ``push_in_heading_frame`` its force is relative to that heading (x forward, y left) and
    is turned by it into the world frame when the push starts (:func:`_push_scheduler`). ``video`` records
    an MP4; ``trace`` receives the base position (x, y, z) [m] after every control step; ``frames`` (a
    :class:`krl.sim.video.FrameLog` of ``sim``) logs the frames to film afterwards.
    A diverging simulation or an MPC that gives up ends the run with an ``error`` (counted as a fall by the
    aggregates) instead of stopping the evaluation.
    """
    from dataclasses import replace

    records = EpisodeRecords(1)
    recorder = None
    if video is not None:
        from krl.sim.video import VideoRecorder

        recorder = VideoRecorder(sim, video)

    def on_step(record: StepRecord, step: EpisodeStep) -> None:
        records.add(step, [0], np.array([sim.step_count]))
        for capturing in (recorder, frames):
            if capturing is not None:
                capturing.capture()
        if trace is not None:
            trace.append(record.after.base_pos.copy())

    runner = Runner(sim, controller, replace(CommandParams(), d_min=d_min), reward=reward)
    records.begin([0], [push])
    result, error = RunResult(), None
    try:
        result = runner.walk_to(
            targets,
            target_time_limit=time_limit,
            start_pose=start_pose,
            time_limit=time_limit,
            on_task_step=on_step,
            pushes=None if push is None else OnePush(push, push_in_heading_frame),
        )
    except (SimulationUnstableError, MPCError) as failure:
        error = f"{type(failure).__name__}: {failure}"
    finally:
        if recorder is not None:
            recorder.close()
    record = records.finish(0, result.targets_reached, result.timed_out, error)
    metrics = run_metrics(record, len(targets), sim.time)
    if push is not None:
        metrics["push_heading"] = record.push_heading
    return metrics


# --- the push sweep (thesis Section 5.3) ---------------------------------------------------------

PUSH_DIRECTION_DRAWS: tuple[str, ...] = ("uniform", "balanced")
"""How the push sweep draws each attempt's direction (:attr:`PushSweep.directions`)."""


@dataclass(frozen=True)
class PushSweep:
    """The robustness sweep: walk to one waypoint on flat ground while one push hits the trunk.

    Attempt ``a`` draws the push's start time, direction and point from ``default_rng([seed, a])``
    whatever the magnitude, so every magnitude (and every controller) meets the same pushes and the
    magnitude is the only thing that changes along the sweep.
    """

    magnitudes: tuple[float, ...] = THESIS_PUSH_MAGNITUDES
    """Push forces [N], distinct (thesis Table 5.5: 250-900 N in steps of 50)."""
    attempts: int = THESIS_PUSH_ATTEMPTS
    """Attempts per magnitude (the thesis's 10)."""
    seed: int = 0
    """Seed of the pushes' random draws."""
    target: tuple[float, float] = (3.0, 0.0)
    """The waypoint, world (x, y) [m]; the robot starts at the origin facing +x."""
    window: tuple[float, float] = (2.0, 5.0)
    """The push starts at a time ~ U(window) [s], while the robot walks."""
    time_limit: float = TARGET_TIME_LIMIT
    """Time allowed to reach the waypoint [s]."""
    d_min: float = CommandParams.d_min
    """Waypoint threshold [m]."""
    directions: str = "uniform"
    """How each attempt's push direction is drawn (:data:`PUSH_DIRECTION_DRAWS`). ``uniform``: azimuth
    ~ U(-π, π) in the world frame, the thesis's (the robot starts facing +x, the target). ``balanced``:
    attempt ``a`` is pushed in quarter ``PUSH_DIRECTIONS[a % 4]`` (forward, left, backward, right) of the
    base's heading when the push starts, the azimuth ~ U(±45°) about the quarter's centre, so each quarter
    has ``attempts / 4`` attempts per magnitude (``attempts`` must be divisible by 4); the start time,
    elevation and point are the uniform draw's."""

    def __post_init__(self) -> None:
        if not self.magnitudes:
            raise ValueError("a push sweep needs at least one push magnitude")
        for magnitude in self.magnitudes:
            check_push_magnitude(magnitude)
        if len(set(self.magnitudes)) != len(self.magnitudes):
            raise ValueError(f"push magnitudes must be distinct, got {self.magnitudes}")
        if self.attempts < 1:
            raise ValueError(f"attempts must be >= 1, got {self.attempts}")
        low, high = self.window
        if not 0 <= low <= high < self.time_limit:
            raise ValueError(f"push window must satisfy 0 <= low <= high < time_limit, got {self.window}")
        if self.directions not in PUSH_DIRECTION_DRAWS:
            known = ", ".join(PUSH_DIRECTION_DRAWS)
            raise ValueError(f"unknown push directions {self.directions!r}; known: {known}")
        if self.directions == "balanced" and self.attempts % len(PUSH_DIRECTIONS):
            raise ValueError(
                f"balanced push directions need attempts divisible by {len(PUSH_DIRECTIONS)} (one attempt "
                f"per quarter in turn), got {self.attempts}"
            )

    def to_dict(self) -> dict[str, Any]:
        """The sweep's settings, stored in every record and compared on resumption. ``directions`` is there
        only when not ``uniform``: records made before the option existed resume as before."""
        settings = {
            "magnitudes": list(self.magnitudes),
            "attempts": self.attempts,
            "seed": self.seed,
            "target": list(self.target),
            "window": list(self.window),
            "time_limit": self.time_limit,
            "d_min": self.d_min,
        }
        if self.directions != "uniform":
            settings["directions"] = self.directions
        return settings

    def stratum(self, attempt: int) -> str | None:
        """The quarter of :data:`krl.eval.summaries.PUSH_DIRECTIONS` attempt ``attempt``'s push is drawn in
        (``balanced``: the attempt's index mod 4, whatever ``attempts``), or None (``uniform``)."""
        if self.directions == "uniform":
            return None
        return PUSH_DIRECTIONS[attempt % len(PUSH_DIRECTIONS)]

    @property
    def walk_heading(self) -> float:
        """The direction of the walk, from the origin to the target [rad]."""
        return math.atan2(self.target[1], self.target[0])

    def push(self, magnitude: float, attempt: int):
        """The push of one attempt (:class:`krl.sim.pushes.Push`): in the world frame (``uniform``), or
        relative to the base's heading at the push, x forward and y left (``balanced``)."""
        from krl.sim.pushes import scripted_push

        rng = np.random.default_rng([self.seed, attempt])
        stratum = self.stratum(attempt)
        if stratum is None:
            return scripted_push(magnitude, rng, self.window)
        centre = PUSH_DIRECTIONS.index(stratum) * QUARTER
        return scripted_push(
            magnitude, rng, self.window, azimuth_range=(centre - QUARTER / 2, centre + QUARTER / 2)
        )

    def walk(self, controller, push, video=None, sim=None) -> dict[str, Any]:
        """The sweep's walk with ``push`` (a :class:`krl.sim.pushes.Push`, in the frame :meth:`push` draws
        it in): from the origin to the waypoint in ``sim`` (default an A1Sim on flat ground); the run's
        metrics (:func:`score_walk`)."""
        from krl.sim.model import build_model
        from krl.sim.robot import A1Sim

        return score_walk(
            A1Sim(build_model("flat")) if sim is None else sim,
            controller,
            np.array([self.target]),
            (0.0, 0.0, 0.0),
            self.time_limit,
            self.d_min,
            push=push,
            video=video,
            push_in_heading_frame=self.directions != "uniform",
        )


def score_push_attempt(
    sweep: PushSweep, controller, magnitude: float, attempt: int, video=None, sim=None
) -> dict[str, Any]:
    """One attempt of the sweep (in ``sim``, default :meth:`PushSweep.walk`'s): the run's metrics plus the
    push (magnitude [N], impulse [N·s], Δv [m/s]) with its force in the world frame. A ``balanced`` push's
    force is the one applied, turned by ``push_heading``, and its record adds ``stratum``, its quarter; a
    push that never came (the run ended first) is recorded turned by the walk's direction, the heading
    :func:`krl.eval.summaries.push_direction` then falls back to, so the report's quarter is the stratum."""
    push = sweep.push(magnitude, attempt)
    return push_attempt_metrics(sweep, attempt, push, sweep.walk(controller, push, video=video, sim=sim))


def push_attempt_metrics(sweep: PushSweep, attempt: int, push, metrics: dict[str, Any]) -> dict[str, Any]:
    """An attempt's walk ``metrics`` (with ``push_heading``) and its push (:meth:`PushSweep.push`) as the
    attempt's metrics (:func:`score_push_attempt`)."""
    stratum = sweep.stratum(attempt)
    if stratum is None:
        return {**metrics, "push": push.summary()}
    heading = metrics["push_heading"]
    applied = push.turned(sweep.walk_heading if heading is None else heading)
    return {**metrics, "push": {**applied.summary(), "stratum": stratum}}


# --- the friction sweep (ours, issue #25) --------------------------------------------------------------

FRICTION_SWEEP_FRICTIONS: tuple[float, ...] = (1.0, 0.8, 0.6, 0.5, 0.4, 0.3)
"""Default ground friction coefficients μ of the sweep [-]: 1, the thesis's ground (4.2.1), as the
reference; 0.8 and 0.6, where 0.6 is the μ of the MPC's own friction pyramid (docs/mpc.md), so below it the
ground no longer holds every force the expert plans; 0.5, where issue #25 sets its target (success >= 0.9
on the flat and height-field courses); 0.4 and 0.3, slippery ground (wet or dusty), to find where each
controller starts to slip and fall."""


FRICTION_RANGE = f"0 < μ <= {MAX_GROUND_FRICTION:g}"
"""The ground friction coefficients a sweep can set, as messages state them: the range of every terrain's
``friction`` parameter (:data:`krl.sim.terrains.MAX_GROUND_FRICTION`)."""


def friction_in_range(mu: float) -> bool:
    """Whether ``mu`` [-] is a ground friction coefficient every terrain takes (:data:`FRICTION_RANGE`), so a
    sweep can be refused whole before its first run instead of failing at the first course built at ``mu``."""
    return math.isfinite(mu) and 0 < mu <= MAX_GROUND_FRICTION


@dataclass(frozen=True)
class FrictionSweep:
    """The friction sweep: courses walked again, from every start pose, with the ground's sliding friction
    μ (the terrain parameter ``friction``, docs/terrains.md) set to each of ``frictions`` in turn. Only μ
    changes along the sweep: the course, its starts and its time limit stay."""

    frictions: tuple[float, ...] = FRICTION_SWEEP_FRICTIONS
    """Ground friction coefficients μ [-], each in :data:`FRICTION_RANGE` and distinct."""
    courses: tuple[str, ...] = ("flat", "heightfield")
    """The courses walked at each μ (shipped names or course files): flat ground and a height field."""

    def __post_init__(self) -> None:
        if not self.frictions:
            raise ValueError("the friction sweep needs at least one friction coefficient")
        for mu in self.frictions:
            if not friction_in_range(mu):
                raise ValueError(f"friction {mu:g} is out of range: {FRICTION_RANGE} (in {self.frictions})")
        if len(set(self.frictions)) != len(self.frictions):
            raise ValueError(f"frictions must be distinct, got {self.frictions}")
        if not self.courses:
            raise ValueError("the friction sweep needs at least one course")

    def load_courses(self) -> list:
        """The sweep's courses (:class:`krl.eval.courses.Course`), each once
        (:func:`krl.eval.courses.distinct_courses`); a :class:`krl.eval.courses.CourseError` if one cannot be
        loaded."""
        from krl.eval.courses import distinct_courses, load_course

        return distinct_courses([load_course(name) for name in dict.fromkeys(self.courses)])

    @staticmethod
    def on(course, friction: float):
        """``course`` (a :class:`krl.eval.courses.Course`) with its ground's friction set to ``friction``
        [-] (its fingerprint changes with it)."""
        from dataclasses import replace

        return replace(course, terrain_params={**course.terrain_params, "friction": friction})
