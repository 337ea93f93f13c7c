"""One command's share of an agent study: its storage checked, its jobs run, its status or report written.

``krl agent study NAME`` parses its options into a :class:`~krl.agent.studies.runner.StudySettings` and a
storage URL and calls :func:`run_study` (train) or :func:`report_study` (``--report``). :func:`run_study`
opens the storage once before anything trains (:func:`krl.util.optuna_storage.check_storage`), runs
``jobs`` study processes (this one and ``jobs - 1`` spawned; each takes trials from the shared storage
until none is left, so any number of commands on any number of machines share one study) and returns the
study's status. Ctrl-C or SIGTERM stops every job: each checkpoints its trial and queues it again.
Whatever is wrong with the storage or the request is a :class:`~krl.agent.studies.runner.StudyError` of
one line, password masked.
"""

from __future__ import annotations

import multiprocessing
import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from krl.agent.studies.designs import STUDIES, StudyDesign
from krl.agent.studies.report import open_stages, study_status, trial_errors, write_study_report
from krl.agent.studies.runner import StudyError, StudySettings, stored_settings, work
from krl.util.optuna_storage import (
    HEARTBEAT,
    SQLITE_LOCK_TIMEOUT,
    check_storage,
    database_errors,
    masked,
    storage_errors,
    storage_failure,
)
from krl.util.parallel import die_with_parent, signals_raise, stop_processes


def _job(
    name: str, settings, out: str, url: str, heartbeat: float, log_to: str, parent: int | None = None
) -> None:
    """One study process: the command's own, or a job it (pid ``parent``) spawned, which leaves Ctrl-C to
    the parent and dies with it; SIGTERM, from the start, stops such a job as Ctrl-C stops the parent (its
    trial is queued again), and it leaves the report to the parent (no traceback). Its progress lines and
    bars go to ``log_to``: ``stdout``, ``stderr`` or ``quiet`` (nowhere, and no bars)."""
    if parent is not None:
        die_with_parent(parent)
    quiet = log_to == "quiet"

    def log(line: str) -> None:
        if not quiet:
            print(line, file=sys.stderr if log_to == "stderr" else sys.stdout)

    try:
        with signals_raise():  # the parent's are already so; a job's SIGTERM would otherwise kill it
            work(STUDIES[name], settings, Path(out), url, heartbeat, log=log, progress=not quiet)
    except KeyboardInterrupt:
        if parent is None:
            raise
        raise SystemExit(130) from None  # its trial is checkpointed and queued again
    except (*database_errors(), StudyError, OSError) as error:
        if parent is None:
            raise
        reason = storage_failure(url, error) if isinstance(error, database_errors()) else masked(str(error))
        print(f"krl: error: {reason}", file=sys.stderr)  # one line, as the parent's; it counts the failure
        raise SystemExit(2) from None


def run_jobs(name: str, settings, out: Path, url: str, heartbeat: float, log_to: str, jobs: int) -> None:
    """``jobs`` study processes: this one (its lines going where ``log_to`` says) and ``jobs - 1`` spawned
    (quiet). Ctrl-C or SIGTERM of this one, while it trains or waits for the others, stops every job: each
    checkpoints its trial and queues it again.

    Raises:
        StudyError: a spawned job stopped with an error (its trials may not be stored); one line.
    """
    spawn = multiprocessing.get_context("spawn")
    others = [
        spawn.Process(target=_job, args=(name, settings, str(out), url, heartbeat, "quiet", os.getpid()))
        for _ in range(jobs - 1)
    ]
    with signals_raise():
        for process in others:
            process.start()
        try:
            _job(name, settings, str(out), url, heartbeat, log_to)
            for process in others:
                process.join()
        except KeyboardInterrupt:
            # each job checkpoints its trial and queues it again: as long as a SQLite write may wait
            stop_processes(others, SQLITE_LOCK_TIMEOUT)
            raise
    failed = [str(process.exitcode) for process in others if process.exitcode != 0]
    if failed:
        raise StudyError(
            f"{len(failed)} of study {name}'s {jobs} processes stopped with an error (exit status "
            f"{', '.join(failed)}): run the same command again to resume the trials they held"
        )


def run_study(
    design: StudyDesign,
    settings: StudySettings,
    out: Path,
    url: str,
    heartbeat: float = HEARTBEAT,
    log_to: str = "stdout",
    jobs: int = 1,
) -> tuple[dict[str, Any], list[str]]:
    """Run ``jobs`` processes of the study until it has no trial left (see the module), its trial folders
    under ``out``, its trials in the storage at ``url``. Returns its status
    (:func:`~krl.agent.studies.report.study_status`) and its failed trials' errors (empty: all finished).

    Raises:
        StudyError: a bad storage, a read-only ``out``, or settings other than the stored ones; one line.
    """
    out.mkdir(parents=True, exist_ok=True)
    if not os.access(out, os.W_OK | os.X_OK):  # every trial would fail writing its run folder
        raise StudyError(f"the study folder {out} is read-only: give another --out")
    try:  # opened once before anything trains or is spawned
        check_storage(url, heartbeat)
    except ValueError as error:
        raise StudyError(str(error)) from None
    try:
        run_jobs(design.name, settings, out, url, heartbeat, log_to, jobs)
        stages = open_stages(design, settings, url)
        return study_status(design, settings, url, stages), trial_errors(stages)
    except database_errors() as error:
        raise StudyError(storage_failure(url, error)) from None


MeasuredSections = Callable[[StudyDesign, StudySettings, Path, str], list[str]]
"""Sections a study's report adds from measurements of its own (design, settings, report folder, command:
the paths written), as :func:`krl.analysis.agent.commands.alternative_measurement` does."""


def report_study(
    design: StudyDesign,
    settings: StudySettings | None,
    url: str,
    out: Path,
    command: str,
    measured: MeasuredSections | None = None,
) -> dict[str, Any]:
    """Write the tables and figures of what has finished into ``out``, with ``settings`` (None: those the
    study started with; given ones must be the same), and the sections ``measured`` adds; ``command`` is
    written beside them (mask its password: :func:`~krl.util.optuna_storage.masked`). Returns the paths
    written.

    Raises:
        StudyError: the storage is bad or foreign, the study was never started there, or ``settings``
            differ from the stored ones; one line, nothing written to the storage.
    """
    try:
        stored = stored_settings(design, url)
    except ValueError as error:  # a foreign SQLite file: nothing written to it
        raise StudyError(str(error)) from None
    except storage_errors() as error:
        raise StudyError(storage_failure(url, error)) from None
    if stored is None:
        raise StudyError(f"study {design.name} has not been started in {masked(url)}: nothing to report")
    settings = stored if settings is None else settings
    try:
        extra = [] if measured is None else measured(design, settings, out, command)
        return write_study_report(design, settings, url, out, command, extra)
    except database_errors() as error:
        raise StudyError(storage_failure(url, error)) from None
