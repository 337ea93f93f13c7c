"""``krl evaluate``: run a controller on courses, the push sweep or the friction sweep, one process per
core, resumably.

Each run (a course from one start pose, with one seed where the controller depends on it; one attempt at
one push magnitude; or a course from one start pose at one ground friction) is a :class:`Task`. Workers
run tasks and return their records; the main process writes each record atomically to
``OUT/<controller>/<course>/<run>.json`` (``OUT/<controller>/push/m<N>-a<k>.json``,
``OUT/<controller>/friction/<course>-mu<μ>-start<k>.json``) as it arrives. A record stores what made it
(controller, course or sweep fingerprint, seed, friction), so a re-run skips finished runs and refuses to
mix results of a different course file or kernel into the same directory. Every run is seeded by its own
key, so results do not depend on the number of workers or on the order in which runs finish.
"""

from __future__ import annotations

import itertools
import json
import math
import statistics
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from krl.eval.controllers import ControllerSpec
from krl.eval.courses import Course
from krl.eval.episodes import FrictionSweep, PushSweep, score_push_attempt, score_walk
from krl.util.output import write_atomic
from krl.util.parallel import run_jobs

RESULT_FORMAT = 1
"""Version of the per-run result files."""

PUSH_DIR = "push"
"""Subdirectory of a controller's results that holds the push sweep."""

FRICTION_DIR = "friction"
"""Subdirectory of a controller's results that holds the friction sweep."""


class EvaluationError(RuntimeError):
    """Stored results that cannot be used (corrupt, or made by something else); one line."""


@dataclass(frozen=True)
class Task:
    """One run. Plain data: it travels to a worker process."""

    key: str
    """Result path under the controller's directory, without ``.json`` (``stairs/start0``)."""
    controller: ControllerSpec
    course: Course | None = None
    start: int = 0
    seed: int | None = None
    sweep: PushSweep | None = None
    magnitude: float = 0.0
    attempt: int = 0
    friction: float | None = None
    """The ground friction μ [-] of a friction sweep's run (``course`` is then the course at that μ)."""
    video: str | None = None
    """Write an MP4 of the run here."""

    def identity(self) -> dict[str, Any]:
        """What the run's result depends on; stored with it and compared on resumption."""
        identity: dict[str, Any] = {"format": RESULT_FORMAT, "controller": self.controller.describe()}
        if self.sweep is not None:
            identity.update(sweep=self.sweep.to_dict(), magnitude=self.magnitude, attempt=self.attempt)
            if self.seed is not None:  # records of one policy, made before seeded sweeps, have no seed
                identity["seed"] = self.seed
        else:
            assert self.course is not None
            identity.update(
                course=self.course.name,
                course_fingerprint=self.course.fingerprint,
                start=self.start,
                seed=self.seed,
            )
            if self.friction is not None:
                identity["friction"] = self.friction
        return identity


def run_seeds(spec: ControllerSpec, seeds: Sequence[int] | None) -> list[int | None]:
    """The seeds ``spec`` runs with: ``[None]`` for a controller that is not seeded; for a seeded one
    ``seeds`` (None: every seed it holds).

    Raises :class:`ControllerSpecError` for a seed a seeded controller holds no policy for (before anything
    is written).
    """
    if not spec.seeded:
        return [None]
    for seed in seeds or ():
        spec.artifact(seed)
    return list(spec.seeds if seeds is None else seeds)


def course_tasks(
    spec: ControllerSpec,
    courses: Sequence[Course],
    seeds: Sequence[int] | None = None,
    video_dir: Path | None = None,
    video_all: bool = False,
) -> list[Task]:
    """Every (course, start[, seed]) run, seeds as :func:`run_seeds`; videos are made of each course's
    first run, or of every run with ``video_all``."""
    tasks = []
    seeds_run = run_seeds(spec, seeds) if courses else []
    for course in courses:
        first = True
        for start in range(len(course.starts)):
            for seed in seeds_run:
                name = f"start{start}" + ("" if seed is None else f"-seed{seed}")
                video = None
                if video_dir is not None and (first or video_all):
                    video = str(video_dir / spec.label / f"{course.name}-{name}.mp4")
                tasks.append(Task(f"{course.name}/{name}", spec, course, start, seed, video=video))
                first = False
    return tasks


def push_tasks(
    spec: ControllerSpec, sweep: PushSweep, seeds: Sequence[int] | None = None, video_dir: Path | None = None
) -> list[Task]:
    """Every (magnitude, attempt[, seed]) of the sweep, seeds as :func:`run_seeds`: each seed's policy
    meets the same pushes. A video of attempt 0 at each magnitude (of the first seed) if asked."""
    tasks = []
    for index, seed in enumerate(run_seeds(spec, seeds)):
        for magnitude in sweep.magnitudes:
            for attempt in range(sweep.attempts):
                name = f"m{magnitude:g}-a{attempt}" + ("" if seed is None else f"-seed{seed}")
                video = None
                if video_dir is not None and attempt == 0 and index == 0:
                    video = str(video_dir / spec.label / f"push-{name}.mp4")
                tasks.append(
                    Task(
                        f"{PUSH_DIR}/{name}",
                        spec,
                        seed=seed,
                        sweep=sweep,
                        magnitude=magnitude,
                        attempt=attempt,
                        video=video,
                    )
                )
    return tasks


def friction_tasks(
    spec: ControllerSpec,
    sweep: FrictionSweep,
    courses: Sequence[Course],
    seeds: Sequence[int] | None = None,
    video_dir: Path | None = None,
) -> list[Task]:
    """Every (course, μ, start[, seed]) run of the friction sweep, seeds as :func:`run_seeds`; ``courses``
    are the sweep's (:meth:`FrictionSweep.load_courses`, loaded once for every controller). A video of
    each course's first run at each μ if asked."""
    tasks = []
    seeds_run = run_seeds(spec, seeds)
    for course, friction in itertools.product(courses, sweep.frictions):
        at_mu = FrictionSweep.on(course, friction)
        for start, seed in itertools.product(range(len(course.starts)), seeds_run):
            name = f"{course.name}-mu{friction:g}-start{start}" + ("" if seed is None else f"-seed{seed}")
            first = start == 0 and seed == seeds_run[0]
            video = str(video_dir / spec.label / f"friction-{name}.mp4") if video_dir and first else None
            tasks.append(
                Task(f"{FRICTION_DIR}/{name}", spec, at_mu, start, seed, friction=friction, video=video)
            )
    return tasks


def run_task(task: Task) -> dict[str, Any]:
    """Run one task (in a worker); returns its record (identity + metrics)."""
    from krl.sim.robot import A1Sim

    controller = task.controller.build(task.seed)
    if task.sweep is not None:
        metrics = score_push_attempt(task.sweep, controller, task.magnitude, task.attempt, video=task.video)
    else:
        course = task.course
        assert course is not None
        metrics = score_walk(
            A1Sim(course.build()),
            controller,
            np.array(course.waypoints),
            course.starts[task.start],
            course.time_limit,
            course.d_min,
            video=task.video,
        )
    return {**task.identity(), "run": task.key, "metrics": metrics}


def result_path(out: Path, task: Task) -> Path:
    return out / task.controller.label / f"{task.key}.json"


def load_record(path: Path, task: Task | None = None) -> dict[str, Any]:
    """Read one stored record; with ``task``, check it was made by that task."""
    try:
        record = json.loads(path.read_text())
        record["metrics"]["success"]
    except (OSError, ValueError, KeyError, TypeError) as error:
        raise EvaluationError(f"{path}: corrupt result file ({error}); delete it to redo that run") from None
    if task is not None:
        stored = {key: record.get(key) for key in task.identity()}
        if stored != task.identity():
            raise EvaluationError(
                f"{path} was made by a different {_differences(stored, task.identity())} than this run; "
                "use another --out or delete the old results"
            )
    return record


_IDENTITY_NAMES = {
    "format": "result format",
    "controller": "controller",
    "course": "course",
    "course_fingerprint": "course",
    "sweep": "push sweep",
    "magnitude": "push sweep",
    "attempt": "push sweep",
    "friction": "ground friction",
    "start": "start",
    "seed": "seed",
}
"""What each key of :meth:`Task.identity` is, in messages."""


def _differences(a: dict[str, Any], b: dict[str, Any]) -> str:
    """What two runs' identities differ in: ``course``, ``controller and course``, ..."""
    keys = [key for key in b if a.get(key) != b[key]]
    return " and ".join(dict.fromkeys(_IDENTITY_NAMES.get(key, key) for key in keys))


def execute(
    tasks: Sequence[Task],
    out: Path,
    workers: int = 1,
    on_done: Callable[[Task, dict[str, Any], bool], None] | None = None,
    on_start: Callable[[], None] | None = None,
) -> list[dict[str, Any]]:
    """Run the tasks whose results are not stored yet; return every task's record, in task order.

    Everything is checked before anything is written: the worker count; that no two different runs
    would share a result file (same controller label and run key, different identity: an
    :class:`EvaluationError`; equal tasks run once); and that every stored result was made by its task.
    Then ``on_start()`` is called (the CLI records its command there), and ``on_done(task, record, ran)``
    for each task as its record becomes available (``ran``: False for a stored result). The runs go
    through :func:`krl.util.parallel.run_jobs`: Ctrl-C or SIGTERM stops the workers and raises
    :class:`krl.util.parallel.Interrupted` (a ``KeyboardInterrupt``); only the runs in flight are lost, every
    record passed to ``on_done`` is stored.
    """
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    planned: dict[Path, Task] = {}
    for task in tasks:
        path = result_path(out, task)
        other = planned.setdefault(path, task)
        if other.identity() != task.identity():
            raise EvaluationError(
                f"{path} would hold two different runs of this call (they differ in "
                f"{_differences(other.identity(), task.identity())}); give them different names"
            )
    records: dict[Path, dict[str, Any]] = {}
    pending = []
    for path, task in planned.items():
        if path.exists() and not (task.video and not Path(task.video).exists()):
            records[path] = load_record(path, task)
        else:
            pending.append(task)
    if on_start is not None:
        on_start()
    if on_done is not None:
        for path, record in records.items():
            on_done(planned[path], record, False)

    def finish(index: int, record: dict[str, Any]) -> None:
        path = result_path(out, pending[index])
        write_atomic(path, json.dumps(record, indent=1))
        records[path] = record
        if on_done is not None:
            on_done(pending[index], record, True)

    run_jobs(run_task, pending, workers, on_result=finish)
    return [records[result_path(out, task)] for task in tasks]


# --- aggregates --------------------------------------------------------------------------------------


def _mean_std(values: Sequence[float]) -> tuple[float, float]:
    """Mean and sample standard deviation (n - 1, as the thesis's tables); std 0 for a single value."""
    mean = statistics.fmean(values)
    return mean, (statistics.stdev(values) if len(values) > 1 else 0.0)


def _counts_as_fall(metrics: dict[str, Any]) -> bool:
    """A fall, or a run that ended with an error (diverging simulation, MPC failure)."""
    return bool(metrics["fell"] or metrics["error"] is not None)


def summarise_course(records: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Mean ± std over a course's runs: reward per step, waypoints reached; success and fall rates.

    A run that ended with an error (diverging simulation, MPC failure) counts as a fall.
    """
    metrics = [r["metrics"] for r in records]
    if not metrics:
        raise ValueError("no runs to summarise")
    reward = _mean_std([m["reward_per_step"] for m in metrics])
    targets = _mean_std([m["targets_reached"] for m in metrics])
    distance = _mean_std([m["distance_walked"] for m in metrics])
    finish_times = [m["time_to_finish"] for m in metrics if m["time_to_finish"] is not None]
    return {
        "runs": len(metrics),
        "targets": metrics[0]["targets"],
        "reward_per_step_mean": reward[0],
        "reward_per_step_std": reward[1],
        "targets_reached_mean": targets[0],
        "targets_reached_std": targets[1],
        "success_rate": sum(m["success"] for m in metrics) / len(metrics),
        "fall_rate": sum(_counts_as_fall(m) for m in metrics) / len(metrics),
        "error_runs": sum(m["error"] is not None for m in metrics),
        "time_to_finish_mean": statistics.fmean(finish_times) if finish_times else None,
        "distance_walked_mean": distance[0],
        "distance_walked_std": distance[1],
    }


SUCCESS_CONFIDENCE_Z = 1.959963984540054
"""Standard-normal quantile of the success rates' two-sided 95 % intervals."""


def success_interval(successes: int, attempts: int) -> tuple[float, float]:
    """Wilson score interval (95 %) of a success rate measured as ``successes`` of ``attempts``.

    It stays inside [0, 1] and is not empty at 0 or 1 successes (10 of 10 gives 0.72-1.00), unlike the
    normal approximation. Used for the push sweep, whose rates come from few attempts per magnitude.
    """
    if not 0 <= successes <= attempts or attempts < 1:
        raise ValueError(f"need 0 <= successes <= attempts >= 1, got {successes} of {attempts}")
    z2 = SUCCESS_CONFIDENCE_Z**2
    rate = successes / attempts
    centre = (rate + z2 / (2 * attempts)) / (1 + z2 / attempts)
    half = SUCCESS_CONFIDENCE_Z * math.sqrt(rate * (1 - rate) / attempts + z2 / (4 * attempts**2))
    half /= 1 + z2 / attempts
    low = 0.0 if successes == 0 else max(0.0, centre - half)
    high = 1.0 if successes == attempts else min(1.0, centre + half)
    return low, high


PUSH_DIRECTIONS: tuple[str, ...] = ("forward", "left", "backward", "right")
"""Quarters of the push's horizontal direction, relative to the base's heading when the push starts
(:func:`push_direction`): each spans 90° centred on its name (``forward``: the force's azimuth within ±45°
of it)."""


def push_direction(record: dict[str, Any]) -> str:
    """Which of :data:`PUSH_DIRECTIONS` a push attempt's force (its horizontal part) points to, relative to
    the base's heading when the push started (``push_heading``); for a record without it (written before
    krl recorded it, or a run that ended before the push), relative to the direction of the sweep's target."""
    metrics = record["metrics"]
    force = metrics["push"]["force"]
    heading = metrics.get("push_heading")
    if heading is None:
        target = record["sweep"]["target"]
        heading = math.atan2(target[1], target[0])
    relative = math.atan2(force[1], force[0]) - heading
    quarter = round(relative / (math.pi / 2)) % 4
    return PUSH_DIRECTIONS[quarter]


def _success(group: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Attempts, success rate and its 95 % interval (:func:`success_interval`) of a group of runs."""
    successes = sum(bool(r["metrics"]["success"]) for r in group)
    low, high = success_interval(successes, len(group))
    return {
        "attempts": len(group),
        "success_rate": successes / len(group),
        "success_low": low,
        "success_high": high,
    }


def summarise_push_directions(records: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per push direction (:func:`push_direction`), over every magnitude of the sweep: attempts,
    success rate and its 95 % interval. Shows which pushes a controller fails, which the per-magnitude
    rates, each of a mix of directions, do not."""
    by_direction: dict[str, list[dict[str, Any]]] = {}
    for record in records:
        by_direction.setdefault(push_direction(record), []).append(record)
    return [
        {"direction": direction, **_success(by_direction[direction])}
        for direction in PUSH_DIRECTIONS
        if direction in by_direction
    ]


def summarise_push(records: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per magnitude: success rate with its 95 % interval (:func:`success_interval`), fall rate,
    mean impulse [N·s] and Δv [m/s] of the pushes. Records of several training seeds are pooled (with equal
    attempts per seed, the rate is the mean of the seeds' rates); their rows add ``seeds`` and
    ``success_rate_seed_std``, the sample std of the seeds' rates."""
    by_magnitude: dict[float, list[dict[str, Any]]] = {}
    for record in records:
        by_magnitude.setdefault(float(record["magnitude"]), []).append(record)
    rows = []
    for magnitude in sorted(by_magnitude):
        group = by_magnitude[magnitude]
        row = {
            "magnitude": magnitude,
            **_success(group),
            "fall_rate": sum(_counts_as_fall(r["metrics"]) for r in group) / len(group),
            "impulse": statistics.fmean(r["metrics"]["push"]["impulse"] for r in group),
            "delta_v": statistics.fmean(r["metrics"]["push"]["delta_v"] for r in group),
        }
        seeds = by_seed(group)
        if len(seeds) > 1:
            rates = [_success(runs)["success_rate"] for runs in seeds.values()]
            row.update(seeds=len(seeds), success_rate_seed_std=_mean_std(rates)[1])
        rows.append(row)
    return rows


def by_seed(records: Sequence[dict[str, Any]]) -> dict[int, list[dict[str, Any]]]:
    """The records of a seed group's runs by training seed, in seed order (empty for runs of one policy)."""
    groups: dict[int, list[dict[str, Any]]] = {}
    for record in records:
        if record.get("seed") is not None:
            groups.setdefault(record["seed"], []).append(record)
    return dict(sorted(groups.items()))


def summarise_push_by_seed(records: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """:func:`summarise_push` of each training seed's attempts, each row with its ``seed``."""
    return [{"seed": seed, **row} for seed, runs in by_seed(records).items() for row in summarise_push(runs)]


def summarise_course_by_seed(records: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per training seed of a course's runs: runs, waypoints reached (mean), success and fall rate."""
    rows = []
    for seed, runs in by_seed(records).items():
        summary = summarise_course(runs)
        keep = ("runs", "targets", "targets_reached_mean", "success_rate", "fall_rate")
        rows.append({"seed": seed, **{key: summary[key] for key in keep}})
    return rows


def summarise_friction(records: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per (course, μ) of the friction sweep, courses in the records' order and μ falling: runs,
    success rate with its 95 % interval (:func:`success_interval`), fall rate (errors count as falls) and
    waypoints reached (mean). Records of several training seeds are pooled; their rows add ``seeds`` and
    ``success_rate_seed_std``, the sample std of the seeds' rates."""
    groups: dict[tuple[str, float], list[dict[str, Any]]] = {}
    for record in records:
        groups.setdefault((record["course"], float(record["friction"])), []).append(record)
    courses = list(dict.fromkeys(course for course, _ in groups))
    rows = []
    for course, friction in sorted(groups, key=lambda key: (courses.index(key[0]), -key[1])):
        group = groups[(course, friction)]
        success = _success(group)
        row = {
            "course": course,
            "friction": friction,
            "runs": success.pop("attempts"),
            **success,
            "fall_rate": sum(_counts_as_fall(r["metrics"]) for r in group) / len(group),
            "targets_reached_mean": statistics.fmean(r["metrics"]["targets_reached"] for r in group),
        }
        seeds = by_seed(group)
        if len(seeds) > 1:
            rates = [_success(runs)["success_rate"] for runs in seeds.values()]
            row.update(seeds=len(seeds), success_rate_seed_std=_mean_std(rates)[1])
        rows.append(row)
    return rows


def summarise_friction_by_seed(records: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """:func:`summarise_friction` of each training seed's runs, each row with its ``seed``."""
    return [
        {"seed": seed, **row} for seed, runs in by_seed(records).items() for row in summarise_friction(runs)
    ]
