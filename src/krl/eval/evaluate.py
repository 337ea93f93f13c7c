"""``krl evaluate``: run a controller on courses, the push sweep or the friction sweep, one process per
core, resumably.

Each run (a course from one start pose, with one seed where the controller depends on it; one attempt at
one push magnitude; or a course from one start pose at one ground friction) is an :class:`EvalRun`, keyed
``<course>/start<k>``, ``push/m<N>-a<k>`` or ``friction/<course>-mu<μ>-start<k>`` (``-seed<S>`` appended
for a seed group). Workers walk runs in batches of one controller and seed (:func:`batch_jobs`,
:func:`krl.eval.batch.run_batch`: the same records as each run walked alone) and return their records;
the main process writes them as Parquet
parts of ``OUT/<controller>/`` (:mod:`krl.eval.records`: atomically, in batches, merged into one part at the
end) and reads the older layout's ``OUT/<controller>/<key>.json`` too. A record stores what made it
(controller, course or sweep fingerprint, seed, friction), so a re-run skips finished runs and refuses to
mix results of a different course file or kernel into the same directory, under a label any of whose runs
is stored (:mod:`krl.eval.label_identity`), not only the runs of this call. A seed group's run records its
own seed's policy file, so adding a seed to a group keeps the other seeds' records. Every run is seeded by
its own key, so results do not depend on the number of workers or on the order in which runs finish.
"""

from __future__ import annotations

import itertools
import json
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from krl.eval.controllers import ControllerSpec
from krl.eval.courses import Course
from krl.eval.episodes import FrictionSweep, PushSweep, score_push_attempt, score_walk
from krl.eval.label_identity import check_label
from krl.eval.record_schema import FRICTION_DIR, PUSH_DIR, STAIR_DIR
from krl.eval.records import EvaluationError, RecordWriter, read_runs, remove_leftovers
from krl.eval.stair_sweep import StairSweep, trained_risers
from krl.util.machine import machine
from krl.util.output import write_atomic
from krl.util.parallel import run_jobs

__all__ = [
    "FRICTION_DIR",
    "PUSH_DIR",
    "STAIR_DIR",
    "EvaluationError",
]  # defined with the records, used from here too

RESULT_FORMAT = 1
"""Version of the per-run records' fields (the parts' layout: :data:`krl.eval.records.PART_FORMAT`)."""


BATCH_RUNS = 128
"""Most runs in one job of a worker (:func:`batch_jobs`): eight for each robot of a batch
(:data:`krl.eval.batch.BATCH_SLOTS`). A batch's robots idle while its last runs end, so longer jobs cost
less CPU per control step, and an interrupted evaluation loses at most a job per worker: the choice and its
measured cost are in benchmarks/README.md ("Idle robots, jobs and the networks' bound")."""

HOW_DONE = ("ran", "stored", "shared")
"""How a run's record became available: it ran in this call; it was stored already; or it is the
record of the same run under another label (:func:`run_identity`), made in this call or stored."""


@dataclass(frozen=True)
class EvalRun:
    """One run of an evaluation (a course from one start, one push attempt, ...; not the waypoint task,
    :class:`krl.task.waypoints.WaypointTask`, that a walk follows). Plain data: it travels to a worker
    process."""

    key: str
    """The run's key under its controller, ``<group>/<name>`` (``stairs/start0``)."""
    controller: ControllerSpec
    course: Course | None = None
    start: int = 0
    seed: int | None = None
    sweep: PushSweep | None = None
    magnitude: float = 0.0
    attempt: int = 0
    friction: float | None = None
    """The ground friction μ [-] of a friction sweep's run (``course`` is then the course at that μ)."""
    stair: dict[str, Any] | None = None
    """A stair sweep's run (``course`` is then its flight): ``riser`` [m], ``direction`` (up or down) and
    ``trained_risers`` (:func:`krl.eval.stair_sweep.trained_risers`)."""
    video: str | None = None
    """Write an MP4 of the run here."""

    def identity(self) -> dict[str, Any]:
        """What the run's result depends on; stored with it and compared on resumption."""
        controller = self.controller.describe(self.seed)
        identity: dict[str, Any] = {"format": RESULT_FORMAT, "controller": controller}
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
            if self.stair is not None:
                identity["stair"] = dict(self.stair)
        return identity

    def record(self, metrics: dict[str, Any]) -> dict[str, Any]:
        """The run's record: its identity, key and ``metrics``, and the machine that computed them
        (:func:`krl.util.machine.machine`: records of one run from two machines may differ in their last
        bits, and with them the walk)."""
        return {**self.identity(), "run": self.key, "metrics": metrics, "machine": machine()}


def run_seeds(spec: ControllerSpec, seeds: Sequence[int] | None) -> list[int | None]:
    """The seeds ``spec`` runs with: ``[None]`` for a controller that is not seeded; for a seeded one
    ``seeds`` (None: every seed it holds), each once.

    Raises :class:`ControllerSpecError` for a seed a seeded controller holds no policy for (before anything
    is written).
    """
    if not spec.seeded:
        return [None]
    for seed in seeds or ():
        spec.artifact(seed)
    return list(dict.fromkeys(spec.seeds if seeds is None else seeds))


def course_runs(
    spec: ControllerSpec,
    courses: Sequence[Course],
    seeds: Sequence[int] | None = None,
    video_dir: Path | None = None,
    video_all: bool = False,
) -> list[EvalRun]:
    """Every (course, start[, seed]) run, seeds as :func:`run_seeds`; videos are made of each course's
    first run, or of every run with ``video_all``."""
    runs = []
    seeds_run = run_seeds(spec, seeds) if courses else []
    for course in courses:
        first = True
        for start in range(len(course.starts)):
            for seed in seeds_run:
                name = f"start{start}" + ("" if seed is None else f"-seed{seed}")
                video = None
                if video_dir is not None and (first or video_all):
                    video = str(video_dir / spec.label / f"{course.name}-{name}.mp4")
                runs.append(EvalRun(f"{course.name}/{name}", spec, course, start, seed, video=video))
                first = False
    return runs


def push_runs(
    spec: ControllerSpec, sweep: PushSweep, seeds: Sequence[int] | None = None, video_dir: Path | None = None
) -> list[EvalRun]:
    """Every (magnitude, attempt[, seed]) of the sweep, seeds as :func:`run_seeds`: each seed's policy
    meets the same pushes. A video of attempt 0 at each magnitude (of the first seed) if asked."""
    runs = []
    for index, seed in enumerate(run_seeds(spec, seeds)):
        for magnitude in sweep.magnitudes:
            for attempt in range(sweep.attempts):
                name = f"m{magnitude:g}-a{attempt}" + ("" if seed is None else f"-seed{seed}")
                video = None
                if video_dir is not None and attempt == 0 and index == 0:
                    video = str(video_dir / spec.label / f"push-{name}.mp4")
                runs.append(
                    EvalRun(
                        f"{PUSH_DIR}/{name}",
                        spec,
                        seed=seed,
                        sweep=sweep,
                        magnitude=magnitude,
                        attempt=attempt,
                        video=video,
                    )
                )
    return runs


def friction_runs(
    spec: ControllerSpec,
    sweep: FrictionSweep,
    courses: Sequence[Course],
    seeds: Sequence[int] | None = None,
    video_dir: Path | None = None,
) -> list[EvalRun]:
    """Every (course, μ, start[, seed]) run of the friction sweep, seeds as :func:`run_seeds`; ``courses``
    are the sweep's (:meth:`FrictionSweep.load_courses`, loaded once for every controller). A video of
    each course's first run at each μ if asked."""
    runs = []
    seeds_run = run_seeds(spec, seeds)
    for course, friction in itertools.product(courses, sweep.frictions):
        at_mu = FrictionSweep.on(course, friction)
        for start, seed in itertools.product(range(len(course.starts)), seeds_run):
            name = f"{course.name}-mu{friction:g}-start{start}" + ("" if seed is None else f"-seed{seed}")
            first = start == 0 and seed == seeds_run[0]
            video = str(video_dir / spec.label / f"friction-{name}.mp4") if video_dir and first else None
            runs.append(
                EvalRun(f"{FRICTION_DIR}/{name}", spec, at_mu, start, seed, friction=friction, video=video)
            )
    return runs


def stair_runs(
    spec: ControllerSpec, sweep: StairSweep, seeds: Sequence[int] | None = None, video_dir: Path | None = None
) -> list[EvalRun]:
    """Every (riser, direction, start[, seed]) run of the stair sweep, seeds as :func:`run_seeds`; a video of
    each flight's first run if asked."""
    runs = []
    seeds_run = run_seeds(spec, seeds)
    trained = {seed: trained_risers(spec, seed) for seed in seeds_run}
    for riser, direction, course in sweep.courses():
        for start, seed in itertools.product(range(len(course.starts)), seeds_run):
            name = f"{course.name}-start{start}" + ("" if seed is None else f"-seed{seed}")
            first = start == 0 and seed == seeds_run[0]
            video = str(video_dir / spec.label / f"{name}.mp4") if video_dir and first else None
            stair = {"riser": riser, "direction": direction, "trained_risers": trained[seed]}
            runs.append(EvalRun(f"{STAIR_DIR}/{name}", spec, course, start, seed, stair=stair, video=video))
    return runs


def batch_jobs(runs: Sequence[EvalRun], workers: int) -> list[list[int]]:
    """``runs`` (by index) in the jobs a worker walks as one batch: consecutive runs of one controller and
    seed, at most :data:`BATCH_RUNS` each, in a multiple of ``workers`` jobs of equal size (to one run), so
    that the workers finish together where the runs allow.
    A filmed run goes alone, and so does each run of a controller without a batched form (the expert: its
    MPC, not the simulation, takes the time, and a run at a time keeps the progress bar and an interrupted
    evaluation's loss at one run)."""
    jobs: list[list[int]] = []
    for (spec, _, filmed), group in itertools.groupby(
        range(len(runs)), key=lambda i: (runs[i].controller, runs[i].seed, runs[i].video is not None)
    ):
        indices = list(group)
        alone = filmed or not spec.batched
        count = workers * -(-len(indices) // (workers * BATCH_RUNS))
        size = 1 if alone else -(-len(indices) // count)
        jobs += [indices[start : start + size] for start in range(0, len(indices), size)]
    return jobs


def run_job(runs: Sequence[EvalRun]) -> list[dict[str, Any]]:
    """Run one job of :func:`batch_jobs` (in a worker): a filmed run alone (:func:`run_one`), else the
    batch (:func:`krl.eval.batch.run_batch`); their records, in order."""
    if len(runs) == 1 and runs[0].video:
        return [run_one(runs[0])]
    from krl.eval.batch import run_batch

    return run_batch(runs)


def run_one(run: EvalRun) -> dict[str, Any]:
    """Walk one run (in a worker); returns its record (identity + metrics)."""
    from krl.sim.robot import A1Sim

    controller = run.controller.build(run.seed)
    if run.sweep is not None:
        metrics = score_push_attempt(run.sweep, controller, run.magnitude, run.attempt, video=run.video)
    else:
        course = run.course
        assert course is not None
        metrics = score_walk(
            A1Sim(course.build()),
            controller,
            np.array(course.waypoints),
            course.starts[run.start],
            course.time_limit,
            course.d_min,
            video=run.video,
        )
    return run.record(metrics)


def check_record(record: dict[str, Any], run: EvalRun, source: Path) -> dict[str, Any]:
    """``record`` (stored in ``source``) if ``run`` made it; an :class:`EvaluationError` otherwise."""
    identity = run.identity()
    stored = {key: record.get(key) for key in identity}
    if run.controller.described_as(stored["controller"], run.seed):
        stored["controller"] = identity["controller"]
    if stored != identity:
        where = f"{source}" + (f" (run {run.key})" if source.suffix != ".json" else "")
        raise EvaluationError(
            f"{where} was made by a different {_differences(stored, identity)} than this run; "
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
"""What each key of :meth:`EvalRun.identity` is, in messages."""


def _differences(a: dict[str, Any], b: dict[str, Any]) -> str:
    """What two runs' identities differ in: ``course``, ``controller and course``, ..."""
    keys = [key for key in b if a.get(key) != b[key]]
    return " and ".join(dict.fromkeys(_IDENTITY_NAMES.get(key, key) for key in keys))


def run_identity(run: EvalRun) -> str:
    """What a run computes: its identity (:meth:`EvalRun.identity`) but for the label its controller is listed
    under, with its run key and video. Two runs of one identity compute the same record (every run is
    seeded by its key), so a file listed under two labels, a seed group's file that another group or a
    variant also holds, say, runs once."""
    identity = run.identity()
    identity["controller"] = {k: v for k, v in identity["controller"].items() if k != "label"}
    return json.dumps([identity, run.key, run.video], sort_keys=True)


def _stored_records(
    out: Path, planned: dict[tuple[str, str], EvalRun]
) -> dict[tuple[str, str], dict[str, Any]]:
    """The stored record of each planned ``(label, run key)`` that has one (not one whose video is
    missing), each checked against its run; then every stored run of each label, planned or not, checked
    to be of this call's controller and courses (:func:`krl.eval.label_identity.check_label`)."""
    records = {}
    for label in dict.fromkeys(label for label, _ in planned):
        stored_runs = read_runs(out / label, label) if (out / label).is_dir() else {}
        for key, found in stored_runs.items():
            run = planned.get((label, key))
            if run is not None and not (run.video and not Path(run.video).exists()):
                records[label, key] = check_record(found.record, run, found.source)
        runs = [run for (of, _), run in planned.items() if of == label]
        courses = {t.course.name: t.course.fingerprint for t in runs if t.course and t.friction is None}
        check_label(out / label, runs[0].controller, courses, stored_runs)
    return records


def execute(
    runs: Sequence[EvalRun],
    out: Path,
    workers: int = 1,
    on_done: Callable[[EvalRun, dict[str, Any], str], None] | None = None,
    on_start: Callable[[], None] | None = None,
) -> list[dict[str, Any]]:
    """Walk the runs whose results are not stored yet; return every run's record, in the order of ``runs``.

    Everything is checked before anything is written: the worker count; that no two different runs
    would share a record (same controller label and run key, different identity: an
    :class:`EvaluationError`; equal runs are walked once); and that every stored result was made by its run.
    Runs that compute the same record under different labels (:func:`run_identity`) are walked once: each gets
    the record under its own label, copied from a stored one where there is one. Then ``on_start()`` is
    called (the CLI records its command there), and ``on_done(run, record, how)`` for each run as its
    record becomes available, ``how`` one of :data:`HOW_DONE`. Records are written in batches
    (:class:`krl.eval.records.RecordWriter`) and each controller's parts merged into one at the end. The
    runs go through :func:`krl.util.parallel.run_jobs` in batches (:func:`batch_jobs`, walked by
    :func:`krl.eval.batch.run_batch`): Ctrl-C or SIGTERM stops the workers, writes the records waiting and
    raises :class:`krl.util.parallel.Interrupted` (a ``KeyboardInterrupt``); only the batches in flight are
    lost (a killed process also loses the records not yet written, at most a write batch).
    """
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    planned: dict[tuple[str, str], EvalRun] = {}
    for run in runs:
        other = planned.setdefault((run.controller.label, run.key), run)
        if other.identity() != run.identity():
            raise EvaluationError(
                f"run {run.controller.label} {run.key} would be two different runs of this call (they "
                f"differ in {_differences(other.identity(), run.identity())}); give them different names"
            )
    keys = {where: run_identity(run) for where, run in planned.items()}
    records = _stored_records(out, planned)
    stored = {keys[where]: record for where, record in records.items()}  # by run identity
    served: dict[str, list[EvalRun]] = {}  # the runs without a record, by run identity
    for where, run in planned.items():
        if where not in records:
            served.setdefault(keys[where], []).append(run)
    to_run = [key for key in served if key not in stored]
    if on_start is not None:
        on_start()
    for label in dict.fromkeys(label for label, _ in planned) if served else ():
        for leftover in remove_leftovers(out / label):
            print(
                f"krl: removed {leftover}, a part an interrupted evaluation left half-written",
                file=sys.stderr,
            )
    writer = RecordWriter(out)

    def store(run: EvalRun, record: dict[str, Any], how: str) -> None:
        mine = {**record, **run.identity()}  # under the run's own label
        writer.add(run.controller.label, mine)
        records[run.controller.label, run.key] = mine
        if on_done is not None:
            on_done(run, mine, how)

    if on_done is not None:
        for where, record in records.items():
            on_done(planned[where], record, "stored")

    jobs = batch_jobs([served[key][0] for key in to_run], workers)

    def finish(job: int, job_records: list[dict[str, Any]]) -> None:
        for index, record in zip(jobs[job], job_records, strict=True):
            first, *others = served[to_run[index]]
            store(first, record, "ran")
            for run in others:
                store(run, record, "shared")

    try:
        for key, same in served.items():
            for run in same if key in stored else ():
                store(run, stored[key], "shared")
        run_jobs(run_job, [[served[to_run[i]][0] for i in job] for job in jobs], workers, on_result=finish)
    finally:
        writer.flush()
    writer.consolidate()
    return [records[run.controller.label, run.key] for run in runs]


@dataclass(frozen=True)
class Evaluation:
    """What one ``krl evaluate`` call scores: every controller of ``controllers`` on each course of
    ``courses``, on the push sweep ``push``, the friction sweep ``friction`` and the stair sweep ``stairs``
    where given, with results in
    ``out``. ``seeds``: the training seeds of seed groups to score (None: all a group holds); ``video``: a
    folder for MP4s of each course's first run (every run with ``video_all``); ``command``: the command line
    remembered in each controller's ``commands.txt`` (None: nothing remembered)."""

    controllers: tuple[ControllerSpec, ...]
    courses: tuple[Course, ...]
    out: Path
    push: PushSweep | None = None
    friction: FrictionSweep | None = None
    stairs: StairSweep | None = None
    seeds: tuple[int, ...] | None = None
    video: Path | None = None
    video_all: bool = False
    workers: int = 1
    command: str | None = None

    def runs(self) -> list[EvalRun]:
        """Every run of the evaluation, controller by controller: courses, then pushes, then frictions."""
        friction_courses = [] if self.friction is None else self.friction.load_courses()
        runs: list[EvalRun] = []
        for spec in self.controllers:
            runs += course_runs(spec, self.courses, self.seeds, self.video, self.video_all)
            if self.push is not None:
                runs += push_runs(spec, self.push, self.seeds, self.video)
            if self.friction is not None:
                runs += friction_runs(spec, self.friction, friction_courses, self.seeds, self.video)
            if self.stairs is not None:
                runs += stair_runs(spec, self.stairs, self.seeds, self.video)
        return runs


def run_evaluation(
    evaluation: Evaluation,
    runs: Sequence[EvalRun],
    on_done: Callable[[EvalRun, dict[str, Any], str], None] | None = None,
) -> dict[str, Any]:
    """Walk ``runs`` (:meth:`Evaluation.runs`) through :func:`execute`, remembering the command once every
    option and stored result has been checked; returns the summary
    (:func:`krl.eval.summaries.evaluation_summary`). ``on_done`` as :func:`execute`'s."""
    from krl.eval.summaries import controller_entry, evaluation_summary

    counts = dict.fromkeys(HOW_DONE, 0)

    def done(run: EvalRun, record: dict[str, Any], how: str) -> None:
        counts[how] += 1
        if on_done is not None:
            on_done(run, record, how)

    def remember_command() -> None:
        for spec in evaluation.controllers if evaluation.command else ():
            remember(evaluation.out / spec.label / "commands.txt", evaluation.command)

    records = execute(runs, evaluation.out, evaluation.workers, done, remember_command)
    courses = [course.name for course in evaluation.courses]
    entries = {
        spec.label: controller_entry(
            [r for t, r in zip(runs, records, strict=True) if t.controller == spec],
            courses,
            spec.seeded,
            evaluation.push is not None,
            evaluation.friction is not None,
            evaluation.stairs is not None,
        )
        for spec in evaluation.controllers
    }
    sweep = evaluation.push
    push = None if sweep is None else {**sweep.to_dict(), "directions": sweep.directions}
    return evaluation_summary(entries, len(runs), counts, str(evaluation.out), push)


def remember(path: Path, command: str) -> None:
    """Append ``command`` to the controller's list of evaluate commands ``path`` (once)."""
    known = path.read_text().splitlines() if path.exists() else []
    if command not in known:
        write_atomic(path, "\n".join([*known, command]) + "\n")
