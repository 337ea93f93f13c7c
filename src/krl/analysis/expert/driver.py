"""The MPC expert's analysis figures: ``krl expert plot WHICH --out DIR`` (``docs/expert_analysis.md``).

``WHICH`` is one of

- ``com-variance`` (thesis Fig. 4.8): the expert walks to the same random waypoints with stance durations
  0.3, 0.25 and 0.2 s; how much does its centre of mass (CoM) wobble?
- ``ride-height`` (Fig. A.2): the same at stance 0.2 s for several ride heights;
- ``step-height`` (Fig. A.3): the same at stance 0.2 s for several step heights;
- ``velocity`` (the MPC half of Fig. 4.15): realised against commanded velocity, each component swept
  over the command generator's limits with the other two held at zero;
- ``all``: the four of them (a condition shared by two figures runs once).

Each figure gives ``WHICH.png``, ``WHICH.json`` and ``WHICH.csv`` in ``DIR``, each written atomically (temp
file + ``os.replace``). The conditions run in parallel worker processes (``--workers``); every condition
is deterministic given the seed, so the numbers do not depend on the worker count.

The CoM metric is :mod:`krl.analysis.expert.metrics`'s; the runs are
:mod:`krl.analysis.expert.runs`' jobs, planned by :mod:`krl.analysis.expert.plan`; the figures are drawn
by :mod:`krl.analysis.expert.com` and :mod:`krl.analysis.expert.velocity`.
"""

from __future__ import annotations

import math
import os
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from krl.analysis.common import (
    DEFAULT_DURATION,
    QUICK_DURATION,
    VELOCITY_COLUMNS,
    check_run_options,
    write_figure,
)
from krl.analysis.expert.com import COM_COLUMNS, com_table, plot_com
from krl.analysis.expert.plan import CHOICES, DEFAULT_TARGETS, FIGURES, QUICK_TARGETS, Settings, plan
from krl.analysis.expert.runs import HoldJob, Job, WalkJob, run_job
from krl.analysis.expert.velocity import plot_velocity, velocity_table
from krl.task.runner import HOLD_RAMP, HOLD_SETTLE
from krl.util.parallel import run_jobs


class PlotError(ValueError):
    """A bad ``krl expert plot`` argument (one-line message)."""


def _summary_line(job: Job, result: dict[str, Any]) -> str:
    if isinstance(job, WalkJob):
        detail = (
            f"com_std x/y/z = {1e3 * result['com_std_x']:.1f}/{1e3 * result['com_std_y']:.1f}/"
            f"{1e3 * result['com_std_z']:.1f} mm, reached {result['targets_reached']}/{len(job.targets)}"
        )
    else:
        detail = "realised = ({:+.3f}, {:+.3f}, {:+.3f})".format(*result["mean"])
    flags = " FELL" if result["fell"] else ""
    flags += f" ERROR {result['error']}" if result.get("error") else ""
    return f"{job.label}: {detail}{flags} ({result['wall_seconds']:.1f} s)"


def _execute(jobs: list[Job], workers: int, progress: bool) -> dict[Job, dict[str, Any]]:
    """Run each distinct job once through :func:`krl.util.parallel.run_jobs` (in this process for one worker);
    with ``progress``, a bar on a terminal and one line per finished condition on stderr either way."""
    # longest first: waypoint walks before fixed-command holds
    order = sorted(jobs, key=lambda job: isinstance(job, HoldJob))
    done = 0

    def report(index: int, result: dict[str, Any]) -> None:
        nonlocal done
        done += 1
        if progress:
            print(f"[{done}/{len(order)}] {_summary_line(order[index], result)}", file=sys.stderr, flush=True)

    results = run_jobs(
        run_job, order, workers, on_result=report, progress="expert conditions" if progress else None
    )
    return dict(zip(order, results, strict=True))


def make_figures(
    which: str,
    out: str | os.PathLike,
    seed: int = 0,
    targets: int | None = None,
    duration: float | None = None,
    workers: int | None = None,
    quick: bool = False,
    progress: bool = True,
) -> dict[str, Any]:
    """Run the conditions and write ``NAME.png``, ``NAME.json``, ``NAME.csv`` per figure into ``out``.

    Returns ``{"figures": {name: {"png", "json", "csv", "table"}}, "wall_seconds", "conditions_run"}``.

    Raises:
        PlotError: unknown ``which`` or a bad value (checked before anything runs or is written).
    """
    if which not in CHOICES:
        raise PlotError(f"unknown figure {which!r}; choose from {', '.join(CHOICES)}")
    targets = (QUICK_TARGETS if quick else DEFAULT_TARGETS) if targets is None else targets
    duration = (QUICK_DURATION if quick else DEFAULT_DURATION) if duration is None else duration
    if isinstance(targets, bool) or not isinstance(targets, int) or targets < 1:
        raise PlotError(f"--targets must be a whole number >= 1, got {targets!r}")
    minimum = HOLD_RAMP + HOLD_SETTLE
    if not (isinstance(duration, (int, float)) and math.isfinite(duration) and duration > minimum):
        raise PlotError(
            f"--duration must be a number of seconds > {minimum:g} ({HOLD_RAMP:g} s ramp + {HOLD_SETTLE:g} s "
            f"settling), got {duration!r}"
        )
    out_dir = Path(out)
    workers = check_run_options(workers, seed, out_dir, PlotError)

    settings = Settings(seed=seed, targets=targets, duration=float(duration), quick=quick)
    names = FIGURES if which == "all" else (which,)
    planned = plan(names, settings)
    jobs = list(dict.fromkeys(job for conditions in planned.values() for _, job in conditions))
    out_dir.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    results = _execute(jobs, workers, progress)
    figures: dict[str, Any] = {}
    for name, conditions in planned.items():
        if name == "velocity":
            table, rows = velocity_table(conditions, results, settings)
            fig = plot_velocity(conditions, results, settings, table["fits"])
            columns: Sequence[str] = VELOCITY_COLUMNS
        else:
            table, rows = com_table(name, conditions, results, settings)
            fig = plot_com(name, conditions, results, settings)
            columns = COM_COLUMNS
        figures[name] = write_figure(out_dir, name, fig, table, columns, rows)
    return {
        "figures": figures,
        "conditions_run": len(jobs),
        "workers": workers,
        "wall_seconds": round(time.perf_counter() - start, 2),
    }
