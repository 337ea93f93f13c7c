"""``krl evaluate`` and ``krl report`` (sweep defaults: :class:`krl.eval.episodes.PushSweep` and
:class:`krl.eval.episodes.FrictionSweep`)."""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path

from krl.cli.common import (
    SHIPPED_AGENTS,
    add_field_option,
    default_of,
    emit,
    given,
    interrupted_status,
    parse_ints,
    process_count,
)
from krl.eval.courses import SHIPPED_COURSES
from krl.util.parallel import usable_cores


def _magnitudes(text: str) -> tuple[float, ...]:
    """``250:900:50`` (inclusive range) or ``300,500`` -> magnitudes [N], each once (``300,300`` is one
    magnitude: its runs are stored once, so the summary counts them once)."""
    try:
        if ":" in text:
            low, high, step = (float(part) for part in text.split(":"))
            if step <= 0 or high < low:
                raise ValueError
            count = round((high - low) / step) + 1
            return tuple(low + step * index for index in range(count))
        return tuple(dict.fromkeys(float(part) for part in text.split(",")))
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


def _risers(text: str) -> tuple[float, ...]:
    """``4,6,8`` -> riser heights [m] of the stair sweep, given in centimetres."""
    try:
        return tuple(round(float(part) / 100.0, 6) for part in text.split(","))
    except ValueError:
        raise ValueError(f"--risers expects a comma list of riser heights in cm, got {text!r}") from None


def add_evaluate_arguments(parser: argparse.ArgumentParser) -> None:
    """``krl evaluate``'s options: what to score, the sweeps, where results and videos go."""
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
    _add_push_arguments(parser)
    _add_friction_arguments(parser)
    parser.add_argument(
        "--stair-sweep",
        action="store_true",
        help="run the stair sweep: flights up and down of each riser height from 4 starts each "
        "(krl.eval.stair_sweep)",
    )
    from krl.eval.stair_sweep import STAIR_SWEEP_RISERS

    parser.add_argument(
        "--risers",
        metavar="LIST",
        help="stair sweep's riser heights in cm, a comma list "
        f"(default {','.join(f'{riser * 100:g}' for riser in STAIR_SWEEP_RISERS)})",
    )
    _add_output_arguments(parser)


def _add_push_arguments(parser: argparse.ArgumentParser) -> None:
    """The push sweep's options (defaults: :class:`krl.eval.episodes.PushSweep`)."""
    from krl.eval.episodes import PUSH_DIRECTION_DRAWS, PushSweep

    magnitudes = default_of(PushSweep, "magnitudes")
    parser.add_argument("--push-sweep", action="store_true", help="run the push robustness sweep (Table 5.5)")
    parser.add_argument(
        "--magnitudes",
        help="push sweep forces [N]: LOW:HIGH:STEP or a list "
        f"(default {len(magnitudes)} forces, {min(magnitudes):g} to {max(magnitudes):g})",
    )
    add_field_option(parser, "--attempts", PushSweep, help="push sweep attempts per magnitude", type=int)
    add_field_option(
        parser, "--push-seed", PushSweep, "seed", help="seed of the push sweep's random pushes", type=int
    )
    add_field_option(
        parser,
        "--push-directions",
        PushSweep,
        "directions",
        choices=PUSH_DIRECTION_DRAWS,
        help="how the push sweep draws each attempt's direction: uniform (azimuth ~ U(-π, π), the thesis's) "
        "or balanced (attempt a in quarter a mod 4 of forward, left, backward, right around the robot's "
        "heading at the push; needs --attempts divisible by 4)",
    )


def _add_friction_arguments(parser: argparse.ArgumentParser) -> None:
    """The friction sweep's options (defaults: :class:`krl.eval.episodes.FrictionSweep`)."""
    from krl.eval.episodes import FrictionSweep

    parser.add_argument(
        "--friction-sweep",
        action="store_true",
        help="run the friction sweep: the sweep's courses from every start at each ground friction μ",
    )
    add_field_option(
        parser,
        "--frictions",
        FrictionSweep,
        metavar="LIST",
        help="friction sweep's ground friction coefficients μ, a comma list",
    )
    parser.add_argument(
        "--friction-course",
        action="append",
        metavar="NAME_OR_PATH",
        help="a course of the friction sweep, a shipped one or a file (repeatable; default "
        f"{', '.join(default_of(FrictionSweep, 'courses'))})",
    )


def _add_output_arguments(parser: argparse.ArgumentParser) -> None:
    """Seeds, processes, the results folder, videos and the summary's form."""
    parser.add_argument(
        "--seeds",
        help="training seeds to score, for seed groups (the agent: one policy per seed; default: all "
        "the group holds)",
    )
    parser.add_argument(
        "--workers",
        type=process_count,
        default=usable_cores(),
        help="processes (default: one per usable core)",
    )
    parser.add_argument("--out", default="runs/eval", help="results directory (resumable)")
    parser.add_argument(
        "--video", metavar="DIR", help="record MP4s of each course's first run (or of --video-all)"
    )
    parser.add_argument("--video-all", action="store_true", help="with --video: record every course run")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument("--json", action="store_true", help="print the summary as JSON")


def summary_epilog() -> str:
    """``krl evaluate --help``'s list of the summary's fields (:data:`krl.eval.summaries.SUMMARY_FIELDS`)."""
    from krl.eval.summaries import SUMMARY_FIELDS
    from krl.util.rounding import RULE

    fields = [f"{name}: {text}" for name, text in SUMMARY_FIELDS.items()]
    return "\n\n".join(
        ["The summary (text, or JSON with --json) holds:", *fields, f"Numbers are rounded: {RULE}."]
    )


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


def evaluation_from_args(args: argparse.Namespace):
    """The :class:`krl.eval.evaluate.Evaluation` that ``krl evaluate``'s options describe."""
    from krl.eval.controllers import distinct_controllers, parse_controller
    from krl.eval.courses import courses_named
    from krl.eval.evaluate import Evaluation
    from krl.eval.stair_sweep import StairSweep

    sweeps = args.push_sweep or args.friction_sweep or args.stair_sweep
    names = args.course if args.course or sweeps else ["thesis"]
    stairs = None
    if args.stair_sweep:
        stairs = StairSweep() if args.risers is None else StairSweep(_risers(args.risers))
    return Evaluation(
        controllers=tuple(distinct_controllers([parse_controller(text) for text in args.controller])),
        courses=tuple(courses_named(names or [])),
        out=Path(args.out),
        push=push_sweep_from_args(args) if args.push_sweep else None,
        friction=friction_sweep_from_args(args) if args.friction_sweep else None,
        stairs=stairs,
        seeds=None if args.seeds is None else tuple(parse_ints(args.seeds, "--seeds")),
        video=Path(args.video) if args.video else None,
        video_all=args.video_all,
        workers=args.workers,
        command="krl " + shlex.join(args.argv),
    )


def run_evaluate(args: argparse.Namespace) -> int:
    """``krl evaluate``: runs the evaluation with a progress bar and prints its summary."""
    from krl.eval.evaluate import run_evaluation
    from krl.util.progress import progress_bar

    evaluation = evaluation_from_args(args)
    runs = evaluation.runs()
    done = 0
    with progress_bar(not args.quiet, unit="runs", status=True) as bar:
        task_id = bar.add_task("evaluate", total=len(runs), status="")

        def on_done(run, record, how: str) -> None:
            nonlocal done
            done += 1
            metrics = record["metrics"]
            status = f"{run.controller.label} {run.key}: {metrics['targets_reached']}/{metrics['targets']}"
            bar.update(task_id, advance=1, status=status + (" fell" if metrics["fell"] else ""))

        try:
            summary = run_evaluation(evaluation, runs, on_done)
        except KeyboardInterrupt as stop:
            print(
                f"krl: interrupted after {done} of {len(runs)} runs; re-run the command to finish",
                file=sys.stderr,
            )
            return interrupted_status(stop)
    emit(summary, args.json)
    return 0


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


def run_convert(args: argparse.Namespace) -> int:
    """``krl convert-results``: a results folder of per-run JSON files as one Parquet part per controller."""
    from krl.eval.records import controller_labels, convert
    from krl.util.progress import progress_bar

    results = Path(args.results)
    labels = controller_labels(results, args.controller)
    with progress_bar(not args.quiet, unit="controllers", status=True) as bar:
        task = bar.add_task("convert", total=len(labels), status="")
        converted = convert(results, labels, lambda label: bar.update(task, advance=1, status=label))
    runs = sum(entry["runs"] for entry in converted.values())
    removed = sum(entry["json_removed"] for entry in converted.values())
    summary = {"results": str(results), "runs": runs, "json_removed": removed, "controllers": converted}
    emit(summary, args.json)
    return 0


def run_compare(args: argparse.Namespace) -> int:
    """``krl compare-results``: exit status 0 when the folders hold equal records, 1 when not (as diff)."""
    from krl.eval.compare import compare_results

    comparison = compare_results(Path(args.first), Path(args.second), args.controller)
    emit(comparison, args.json)
    return 0 if comparison["identical"] else 1


def register(subparsers) -> None:
    """Add ``krl evaluate``, ``krl report``, ``krl convert-results`` and ``krl compare-results`` to the main
    parser's subcommands."""
    p = subparsers.add_parser(
        "evaluate",
        help="score controllers on the courses, the push sweep or the friction sweep (resumable)",
        epilog=summary_epilog(),
    )
    add_evaluate_arguments(p)
    p.set_defaults(func=run_evaluate)
    p = subparsers.add_parser(
        "report",
        help="Tables 5.1-5.5, the friction table and the evaluation plots from krl evaluate's results",
    )
    add_report_arguments(p)
    p.set_defaults(func=run_report)
    p = subparsers.add_parser(
        "convert-results",
        help="rewrite a krl evaluate folder of per-run JSON files as one Parquet part per controller "
        "(each part read back before a file is removed; resumable)",
    )
    p.add_argument("results", help="the krl evaluate results folder")
    p.add_argument("--controller", action="append", metavar="LABEL", help="only these (default: all found)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(func=run_convert)
    p = subparsers.add_parser(
        "compare-results",
        help="two krl evaluate folders run by run: runs only one holds, equal records, the largest "
        "difference of each metric and the runs whose outcome moved (exit status 1 when they differ)",
    )
    p.add_argument("first", help="a krl evaluate results folder")
    p.add_argument("second", help="another")
    p.add_argument("--controller", action="append", metavar="LABEL", help="only these (default: all found)")
    p.add_argument("--json", action="store_true", help="print the comparison as JSON")
    p.set_defaults(func=run_compare)
