"""``krl evaluate`` and ``krl report`` (sweep defaults: :class:`krl.eval.episodes.PushSweep` and
:class:`krl.eval.episodes.FrictionSweep`)."""

from __future__ import annotations

import argparse
import os
import shlex
import sys
from pathlib import Path
from typing import Any

from krl.cli.common import SHIPPED_AGENTS, default_of, emit, given, interrupted_status, parse_ints
from krl.eval.courses import HARDER_COURSES, SHIPPED_COURSES, THESIS_COURSES


def _magnitudes(text: str) -> tuple[float, ...]:
    """``250:900:50`` (inclusive range) or ``300,500`` -> magnitudes [N]."""
    try:
        if ":" in text:
            low, high, step = (float(part) for part in text.split(":"))
            if step <= 0 or high < low:
                raise ValueError
            count = round((high - low) / step) + 1
            return tuple(low + step * index for index in range(count))
        return tuple(float(part) for part in text.split(","))
    except ValueError:
        raise ValueError(
            f"--magnitudes expects LOW:HIGH:STEP or a comma list of forces [N], got {text!r}"
        ) from None


def _frictions(text: str) -> tuple[float, ...]:
    """``1,0.5,0.3`` -> ground friction coefficients μ [-], each checked here against the ground's range
    (:data:`krl.eval.episodes.FRICTION_RANGE`), so a bad value anywhere in the list is refused before any
    run."""
    from krl.eval.episodes import FRICTION_RANGE, friction_in_range

    parts = [part.strip() for part in text.split(",")]
    try:
        values = tuple(float(part) for part in parts)
    except ValueError:
        raise ValueError(f"--frictions expects a comma list of friction coefficients, got {text!r}") from None
    for part, mu in zip(parts, values, strict=True):
        if not friction_in_range(mu):
            raise ValueError(f"--frictions: {part} is out of range: {FRICTION_RANGE} (got {text!r})")
    return values


def add_evaluate_arguments(parser: argparse.ArgumentParser) -> None:
    from krl.eval.episodes import PUSH_DIRECTION_DRAWS, FrictionSweep, PushSweep

    magnitudes = default_of(PushSweep, "magnitudes")

    parser.add_argument(
        "--controller",
        action="append",
        required=True,
        metavar="SPEC",
        help="expert, expert:stance=0.3, kernel, kernel:ext, kernel:PATH, agent, agent:NAME (shipped: "
        f"{SHIPPED_AGENTS}), agent:NAME@SEED, agent:PATH (a policy file or a folder of per-seed ones), gait, "
        "gait:capture=1,rate=2,ride=0.18 (kernel-ext driven by a scripted rule after pushes) (repeatable; "
        "one file given several ways, by name, path or as a byte-identical copy, runs once, under its first "
        "spelling's label)",
    )
    parser.add_argument(
        "--course",
        action="append",
        metavar="NAME_OR_PATH",
        help=f"a shipped course ({', '.join(SHIPPED_COURSES)}), a course file, `thesis` (the four of "
        "Tables 5.1-5.4), `harder` (their harder variants) or `all` (repeatable; default: thesis, unless "
        "a sweep alone)",
    )
    parser.add_argument("--push-sweep", action="store_true", help="run the push robustness sweep (Table 5.5)")
    parser.add_argument(
        "--magnitudes",
        help="push sweep forces [N]: LOW:HIGH:STEP or a list "
        f"(default {len(magnitudes)} forces, {min(magnitudes):g} to {max(magnitudes):g})",
    )
    parser.add_argument(
        "--attempts",
        type=int,
        help=f"push sweep attempts per magnitude (default {default_of(PushSweep, 'attempts')})",
    )
    parser.add_argument(
        "--push-seed",
        type=int,
        help=f"seed of the push sweep's random pushes (default {default_of(PushSweep, 'seed')})",
    )
    parser.add_argument(
        "--push-directions",
        choices=PUSH_DIRECTION_DRAWS,
        help="how the push sweep draws each attempt's direction: uniform (azimuth ~ U(-π, π), the thesis's) "
        "or balanced (attempt a in quarter a mod 4 of forward, left, backward, right around the robot's "
        "heading at the push; needs --attempts divisible by 4) "
        f"(default {default_of(PushSweep, 'directions')})",
    )
    parser.add_argument(
        "--friction-sweep",
        action="store_true",
        help="run the friction sweep: the sweep's courses from every start at each ground friction μ",
    )
    parser.add_argument(
        "--frictions",
        metavar="LIST",
        help="friction sweep's ground friction coefficients μ, a comma list "
        f"(default {','.join(f'{mu:g}' for mu in default_of(FrictionSweep, 'frictions'))})",
    )
    parser.add_argument(
        "--friction-course",
        action="append",
        metavar="NAME_OR_PATH",
        help="a course of the friction sweep, a shipped one or a file (repeatable; default "
        f"{', '.join(default_of(FrictionSweep, 'courses'))})",
    )
    parser.add_argument(
        "--seeds",
        help="training seeds to score, for seed groups (the agent: one policy per seed; default: all "
        "the group holds)",
    )
    parser.add_argument(
        "--workers", type=int, default=os.cpu_count() or 1, help="processes (default: all cores)"
    )
    parser.add_argument("--out", default="runs/eval", help="results directory (resumable)")
    parser.add_argument(
        "--video", metavar="DIR", help="record MP4s of each course's first run (or of --video-all)"
    )
    parser.add_argument("--video-all", action="store_true", help="with --video: record every course run")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument("--json", action="store_true", help="print the summary as JSON")


def _courses(names: list[str] | None):
    """The courses of ``--course`` options, each once; two different courses of one name are refused."""
    from krl.eval.courses import distinct_courses, load_course

    sets = {"thesis": THESIS_COURSES, "harder": HARDER_COURSES, "all": SHIPPED_COURSES}
    expanded: list[str] = []
    for name in names or []:
        expanded += list(sets.get(name, (name,)))
    return distinct_courses([load_course(name) for name in dict.fromkeys(expanded)])


def push_sweep_from_args(args: argparse.Namespace):
    """The PushSweep of ``krl evaluate``'s push options (fields not given keep their defaults)."""
    from krl.eval.episodes import PushSweep

    magnitudes = None if args.magnitudes is None else _magnitudes(args.magnitudes)
    options = given(
        magnitudes=magnitudes, attempts=args.attempts, seed=args.push_seed, directions=args.push_directions
    )
    return PushSweep(**options)


def friction_sweep_from_args(args: argparse.Namespace):
    """The FrictionSweep of ``krl evaluate``'s friction options (fields not given keep their defaults)."""
    from krl.eval.episodes import FrictionSweep

    frictions = None if args.frictions is None else _frictions(args.frictions)
    courses = None if args.friction_course is None else tuple(args.friction_course)
    return FrictionSweep(**given(frictions=frictions, courses=courses))


def run_evaluate(args: argparse.Namespace) -> int:
    from krl.eval import evaluate, summaries
    from krl.eval.controllers import distinct_controllers, parse_controller
    from krl.util.progress import progress_bar

    specs = distinct_controllers([parse_controller(text) for text in args.controller])
    names = args.course if args.course or args.push_sweep or args.friction_sweep else ["thesis"]
    courses = _courses(names)
    seeds = None if args.seeds is None else parse_ints(args.seeds, "--seeds")
    sweep = push_sweep_from_args(args) if args.push_sweep else None
    friction = friction_sweep_from_args(args) if args.friction_sweep else None
    friction_courses = [] if friction is None else friction.load_courses()
    out = Path(args.out)
    video = Path(args.video) if args.video else None
    tasks = []
    for spec in specs:
        tasks += evaluate.course_tasks(spec, courses, seeds, video, args.video_all)
        if sweep is not None:
            tasks += evaluate.push_tasks(spec, sweep, seeds, video)
        if friction is not None:
            tasks += evaluate.friction_tasks(spec, friction, friction_courses, seeds, video)
    command = "krl " + shlex.join(args.argv)

    def remember_command() -> None:  # once every option and stored result has been checked
        for spec in specs:
            _remember_command(out / spec.label / "commands.txt", command)

    counts = dict.fromkeys(evaluate.HOW_DONE, 0)
    with progress_bar(not args.quiet, unit="runs", status=True) as bar:
        task_id = bar.add_task("evaluate", total=len(tasks), status="")

        def on_done(task, record, how: str) -> None:
            counts[how] += 1
            metrics = record["metrics"]
            status = f"{task.controller.label} {task.key}: {metrics['targets_reached']}/{metrics['targets']}"
            bar.update(task_id, advance=1, status=status + (" fell" if metrics["fell"] else ""))

        try:
            records = evaluate.execute(tasks, out, args.workers, on_done, remember_command)
        except KeyboardInterrupt as stop:
            done = sum(counts.values())
            print(
                f"krl: interrupted after {done} of {len(tasks)} runs; re-run the command to finish",
                file=sys.stderr,
            )
            return interrupted_status(stop)
    summary: dict[str, Any] = {"results": str(out), "runs": len(tasks), **counts, "controllers": {}}
    if sweep is not None:
        summary["push_sweep"] = {**sweep.to_dict(), "directions": sweep.directions}
    for spec in specs:
        mine = [r for t, r in zip(tasks, records, strict=True) if t.controller == spec]
        entry: dict[str, Any] = {}
        for course in courses:
            runs = [r for r in mine if r.get("course") == course.name and "friction" not in r]
            entry[course.name] = summaries.summarise_course(runs)
            if spec.seeded:
                entry[course.name]["by_seed"] = summaries.summarise_course_by_seed(runs)
        if sweep is not None:
            pushes = [r for r in mine if "magnitude" in r]
            entry["push"] = summaries.summarise_push(pushes)
            if spec.seeded:
                entry["push_by_seed"] = summaries.summarise_push_by_seed(pushes)
            entry["push_directions"] = summaries.summarise_push_directions(pushes)
            entry["push_left_right"] = summaries.summarise_push_left_right(pushes)
        if friction is not None:
            grounds = [r for r in mine if "friction" in r]
            entry["friction"] = summaries.summarise_friction(grounds)
            if spec.seeded:
                entry["friction_by_seed"] = summaries.summarise_friction_by_seed(grounds)
        entry["wall_seconds"] = round(sum(r["metrics"]["wall_seconds"] for r in mine), 1)
        summary["controllers"][spec.label] = entry
    emit(summary, args.json)
    return 0


def _remember_command(path: Path, command: str) -> None:
    """Append ``command`` to the controller's list of evaluate commands (once)."""
    from krl.util.output import write_atomic

    known = path.read_text().splitlines() if path.exists() else []
    if command not in known:
        write_atomic(path, "\n".join([*known, command]) + "\n")


def add_report_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--results", default="runs/eval", help="the krl evaluate results directory")
    parser.add_argument("--out", default="docs/results", help="where the tables and plots go")
    parser.add_argument(
        "--controller", action="append", metavar="LABEL", help="only these (default: all found)"
    )
    parser.add_argument("--json", action="store_true")


def run_report(args: argparse.Namespace) -> int:
    from krl.eval.report import write_report

    result = write_report(Path(args.results), Path(args.out), args.controller, "krl " + shlex.join(args.argv))
    emit({"written": result["written"]}, args.json)
    return 0


def register(subparsers) -> None:
    """Add ``krl evaluate`` and ``krl report`` to the main parser's subcommands."""
    p = subparsers.add_parser(
        "evaluate", help="score controllers on the courses, the push sweep or the friction sweep (resumable)"
    )
    add_evaluate_arguments(p)
    p.set_defaults(func=run_evaluate)
    p = subparsers.add_parser(
        "report",
        help="Tables 5.1-5.5, the friction table and the evaluation plots from krl evaluate's results",
    )
    add_report_arguments(p)
    p.set_defaults(func=run_report)
