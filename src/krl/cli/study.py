"""``krl agent study NAME``: the thesis's agent studies on Optuna, one machine or many (docs/studies.md)."""

from __future__ import annotations

import argparse
import math
import shlex
import sqlite3
import sys
from pathlib import Path

from krl.cli.common import CliError, emit, labelled_policies, parse_ints, process_count
from krl.util.optuna_storage import HEARTBEAT, masked


def _settings(args: argparse.Namespace, design):
    from krl.agent.config import AgentConfigError
    from krl.agent.studies.runner import StudyError, StudySettings

    shared = None
    if args.config:
        import json

        try:
            shared = json.loads(Path(args.config).read_text())
        except (OSError, ValueError) as error:
            raise CliError(f"--config {args.config}: {error}") from None
    try:
        settings = StudySettings.of(
            design,
            budget=args.budget,
            confirm_budget=args.confirm_budget,
            seeds=None if args.seeds is None else tuple(parse_ints(args.seeds, "--seeds")),
            trials=args.trials,
            top=args.top,
            sampler=args.sampler,
            pruner=args.pruner,
            workers=args.workers,
            num_envs=args.num_envs,
            shared=shared,
        )
        from krl.agent.studies.runner import trial_config

        trial_config(design, settings, {}, settings.budget)  # a bad --config: one line, before any trial
    except (StudyError, AgentConfigError) as error:
        raise CliError(str(error)) from None
    return settings


SETTINGS_OPTIONS: tuple[str, ...] = (
    "budget",
    "confirm_budget",
    "seeds",
    "trials",
    "top",
    "sampler",
    "pruner",
    "config",
)
"""The options a study records and refuses to change. ``--report`` without any of them reports the study
with the settings it was started with."""

LEVEL_POLICIES: tuple[str, ...] = ("agent-base=base@150", "agent-rp=rp@150")
"""The policies ``level-base`` compares unless ``--policy`` is given: seed 150 of the shipped agent-base and
of the shipped agent-rp (one recipe, so the pair differs in the reward alone)."""


def run_level_base(args: argparse.Namespace) -> int:
    """``krl agent study level-base``: Fig. 4.22 from trained policies (no training, no storage)."""
    from krl.agent.policy import one_policy
    from krl.analysis.agent.level import LEVEL_COURSES, level_runs, write_level_report
    from krl.eval.courses import load_course

    policies = labelled_policies(args.policy or LEVEL_POLICIES, one_policy)
    runs = level_runs(policies, [load_course(name) for name in LEVEL_COURSES])
    out = Path(args.report_out or args.out or "runs/agent-studies/level-base")
    command = "krl " + shlex.join(args.argv)
    emit({"written": write_level_report(runs, out, command)}, args.json)
    return 0


def _log(args: argparse.Namespace) -> str:
    """Where a study's progress lines go: ``quiet`` (nowhere), ``stderr`` with ``--json`` (stdout holds
    the JSON alone) or ``stdout``."""
    return "quiet" if args.quiet else "stderr" if args.json else "stdout"


def _check_run_options(args: argparse.Namespace) -> None:
    """One-line errors for a study's run options that every trial would fail on, before any is created."""
    if not (math.isfinite(args.heartbeat) and args.heartbeat > 0):
        raise CliError(f"--heartbeat must be a positive number of seconds, got {args.heartbeat}")


def _snapshot(design, out: Path, url: str, args: argparse.Namespace) -> int:
    """``--snapshot DIR``: copy what resuming the study needs into DIR."""
    from krl.agent.studies.snapshot import snapshot_study

    try:
        emit(snapshot_study(out, url, Path(args.snapshot)), args.json)
    except (FileNotFoundError, ValueError, sqlite3.Error) as error:
        raise CliError(f"cannot snapshot study {design.name}: {masked(str(error))}") from None
    return 0


def run_study(args: argparse.Namespace) -> int:
    from krl.agent.studies import jobs as study_jobs
    from krl.agent.studies.designs import STUDIES
    from krl.agent.studies.runner import StudyError
    from krl.agent.studies.snapshot import DATABASE
    from krl.analysis.agent.commands import alternative_measurement
    from krl.util.parallel import usable_cores

    if args.name == "level-base":
        return run_level_base(args)
    if args.name not in STUDIES:
        raise CliError(f"unknown study {args.name!r}; known: {', '.join([*STUDIES, 'level-base'])}")
    design = STUDIES[args.name]
    settings = _settings(args, design)
    _check_run_options(args)
    out = Path(args.out or f"runs/agent-studies/{design.name}")
    url = args.storage or f"sqlite:///{(out / DATABASE).resolve()}"
    if args.snapshot:
        return _snapshot(design, out, url, args)
    try:
        if args.report:  # with the settings the study started with unless some are given
            given = any(getattr(args, name) is not None for name in SETTINGS_OPTIONS)
            command = "krl " + masked(shlex.join(args.argv))
            report_out = Path(args.report_out or out / "report")
            asked = settings if given else None
            emit(
                study_jobs.report_study(design, asked, url, report_out, command, alternative_measurement),
                args.json,
            )
            return 0
        jobs = args.jobs or max(1, usable_cores() // max(1, settings.workers))
        status, errors = study_jobs.run_study(design, settings, out, url, args.heartbeat, _log(args), jobs)
    except StudyError as error:
        raise CliError(str(error)) from None
    emit(status, args.json)
    if errors:  # a pipeline must not go on from a study whose runs did not finish
        print(
            f"krl: {len(errors)} trial(s) of study {design.name} failed, first {errors[0]}", file=sys.stderr
        )
        return 1
    return 0


def register(group) -> None:
    """``krl agent study`` under the ``krl agent`` group."""
    p = group.add_parser(
        "study",
        help="one of the thesis's agent studies (ppo-search, state-space, ...) on Optuna; resumable, "
        "and shared by every process given the same --storage",
    )
    p.add_argument("name", help="the study (docs/studies.md lists them)")
    p.add_argument(
        "--out", help="trial run folders and the default storage (default runs/agent-studies/NAME)"
    )
    p.add_argument(
        "--storage",
        help="Optuna storage URL: sqlite:///FILE (default OUT/study.db) or postgresql://USER:PASS@HOST/DB "
        "for many machines",
    )
    p.add_argument("--budget", type=int, help="env steps per trial (default: the thesis's)")
    p.add_argument("--confirm-budget", type=int, help="env steps of a search's confirming runs")
    p.add_argument("--trials", type=int, help="a search's random trials (default: the thesis's 100)")
    p.add_argument("--top", type=int, help="a search's best trials trained from every seed (default 5)")
    p.add_argument("--seeds", help="training seeds (default: the thesis's 150,215,345,556)")
    p.add_argument("--sampler", choices=("random", "tpe"), help="a search's sampler (default random)")
    p.add_argument(
        "--pruner", choices=("median", "halving", "none"), help="a search's pruner (default median)"
    )
    p.add_argument("--config", help="JSON settings every trial shares (e.g. num_envs), under the trial's own")
    p.add_argument("--jobs", type=process_count, help="trainings at once (default: usable cores / --workers)")
    p.add_argument("--workers", type=process_count, help="environment processes per training (default 2)")
    p.add_argument("--num-envs", type=int, help="environments per worker (default: the config's)")
    p.add_argument(
        "--heartbeat",
        type=float,
        default=HEARTBEAT,
        help="seconds between a running trial's heartbeats; a trial silent for 3 is retried "
        "(default %(default)g)",
    )
    p.add_argument(
        "--report",
        action="store_true",
        help="write the tables and figures of what has finished (with the settings the study started with)",
    )
    p.add_argument(
        "--policy",
        action="append",
        help="level-base only: LABEL=POLICY to compare (default agent-base=base@150, agent-rp=rp@150)",
    )
    p.add_argument("--report-out", help="where --report writes (default OUT/report)")
    p.add_argument(
        "--snapshot",
        metavar="DIR",
        help="copy what the study needs to resume elsewhere into DIR (its SQLite database, consistent while "
        "jobs write, and its run folders without TensorBoard files); nothing is trained",
    )
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=run_study)
