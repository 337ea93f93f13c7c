"""Running the pipeline: :func:`plan` (the steps for a run folder, a mode and the seeds), the markers of
finished steps, and :func:`reproduce`."""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from pathlib import Path

from krl.apps.reproduce.pipeline import QUICK_SEEDS, pipeline, places
from krl.apps.reproduce.table import Step
from krl.util.output import write_atomic
from krl.util.thesis import THESIS_SEEDS


def plan(runs: Path, docs: Path, quick: bool = False, seeds: Sequence[int] | None = None) -> list[Step]:
    """The steps, in order, for the run folder ``runs``, the documents folder ``docs`` and the training
    ``seeds`` (default: the thesis's four, :data:`QUICK_SEEDS` with ``quick``)."""
    if quick:
        runs, docs = runs / "quick", runs / "quick" / "docs"
    seeds = tuple(seeds or (QUICK_SEEDS if quick else THESIS_SEEDS))
    if len(set(seeds)) != len(seeds):
        raise ValueError(f"seeds must differ, got {list(seeds)}")
    filled = places(str(runs), str(docs), seeds)
    return [row.step(filled, quick) for row in pipeline(seeds)]


def _marker(runs: Path, quick: bool, step: Step) -> Path:
    return (runs / "quick" if quick else runs) / ".reproduce" / f"{step.name}.json"


def is_done(runs: Path, quick: bool, step: Step) -> bool:
    """Whether ``step`` finished (its marker exists and records the same command)."""
    marker = _marker(runs, quick, step)
    try:
        return json.loads(marker.read_text()).get("argv") == list(step.argv)
    except (OSError, ValueError):
        return False


def describe(steps: Sequence[Step], runs: Path, quick: bool) -> list[str]:
    """The plan as text lines: per step whether it is done, its estimated time and its command."""
    lines = []
    left = 0.0
    for number, step in enumerate(steps, start=1):
        done = is_done(runs, quick, step)
        left += 0.0 if done else step.minutes
        status = "done" if done else f"~{step.minutes:g} min"
        lines.append(f"{number:2d}. {step.name:18s} {status:>10s}  {step.makes}\n      {step.command}")
    lines.append(f"left: about {left:.0f} min ({left / 60:.1f} h) on a 2-core machine")
    return lines


def reproduce(
    runs: Path,
    docs: Path,
    quick: bool,
    run: Callable[[list[str]], int],
    log=print,
    dry_run: bool = False,
    seeds: Sequence[int] | None = None,
) -> int:
    """Print the plan (for ``seeds``, as :func:`plan`), then run each step that is not done with
    ``run(argv) -> exit status``; stops at the first failing step (its exit status), returns 0 when
    everything is done."""
    steps = plan(runs, docs, quick, seeds)
    for line in describe(steps, runs, quick):
        log(line)
    if dry_run:
        return 0
    for number, step in enumerate(steps, start=1):
        if is_done(runs, quick, step):
            continue
        log(f"[{number}/{len(steps)}] {step.name}: {step.command}")
        if step.config is not None:
            write_atomic(Path(step.config[0]), step.config[1])
        status = run(list(step.argv))
        if status != 0:
            log(f"step {step.name} failed (exit status {status}); fix it and run krl reproduce to resume")
            return status
        write_atomic(_marker(runs, quick, step), json.dumps({"argv": list(step.argv)}) + "\n")
    log("everything is reproduced")
    return 0
