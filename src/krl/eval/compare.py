"""``krl compare-results``: the records of two ``krl evaluate`` folders, run by run.

A change to the episode engine must keep every record (issue 46): every metric equal, or where the order
of floating-point operations had to change, the differences stated and shown to move no outcome. This
compares two results folders (either layout, :mod:`krl.eval.records`) controller by controller and run by
run: the runs only one folder holds, the runs whose records are equal (but for
:data:`~krl.eval.records.VOLATILE`, which differ between any two repeats of one run), and for the others the
largest absolute difference of each numeric field, the other fields that changed and the runs whose outcome
(:data:`OUTCOMES`) moved. A record made before ``metrics.ended`` existed is compared with the ending its
other outcome fields give (:func:`krl.task.episode.ending`), so its age alone moves no outcome.

A record's ``machine`` (:func:`krl.util.machine.machine`) is not compared; the comparison lists the machines
each folder's records were made on instead, since two machines whose BLAS sums in another order need not
give equal records (docs/sim.md, "Across machines"): ``same_machine`` is true when both folders' compared
records come from one and the same machine, false when they do not, null when a record does not say.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from krl.eval.records import MACHINE, VOLATILE, controller_labels, read_runs, result_of
from krl.task.episode import ending

OUTCOMES: tuple[str, ...] = (
    "metrics.success",
    "metrics.fell",
    "metrics.timed_out",
    "metrics.error",
    "metrics.ended",
    "metrics.targets_reached",
)
"""Fields whose change is a changed result, not a rounding difference."""

EXAMPLES = 10
"""Differing runs listed in full."""


def flatten(value: Any, prefix: str = "") -> dict[str, Any]:
    """Nested dicts and lists as one dict with dotted keys (``metrics.push.force.0``)."""
    if isinstance(value, dict):
        items = value.items()
    elif isinstance(value, list):
        items = ((str(index), item) for index, item in enumerate(value))
    else:
        return {prefix[:-1]: value}
    flat: dict[str, Any] = {}
    for key, item in items:
        flat.update(flatten(item, f"{prefix}{key}."))
    return flat


def _difference(a: Any, b: Any) -> float | None:
    """``|a - b|`` for two numbers (0 for two NaNs), None when either is not a number."""
    numbers = (int, float)
    if isinstance(a, bool) or isinstance(b, bool) or not (isinstance(a, numbers) and isinstance(b, numbers)):
        return None
    if math.isnan(a) and math.isnan(b):
        return 0.0
    return abs(a - b)


def compare_records(
    a: dict[str, Any], b: dict[str, Any], ignored: Sequence[str] = VOLATILE
) -> dict[str, Any]:
    """The fields in which two records of one run differ: ``{field: [a's, b's]}`` (missing: None)."""
    flat_a, flat_b = (flatten(_with_ending(result_of(record, ignored))) for record in (a, b))
    keys = list(dict.fromkeys([*flat_a, *flat_b]))
    differing = {}
    for key in keys:
        x, y = flat_a.get(key), flat_b.get(key)
        if x != y and _difference(x, y) != 0.0:
            differing[key] = [x, y]
    return differing


def _with_ending(record: dict[str, Any]) -> dict[str, Any]:
    """``record`` with ``metrics.ended`` (an older record's from its outcome fields)."""
    metrics = record.get("metrics")
    if not isinstance(metrics, dict) or "ended" in metrics or "fell" not in metrics:
        return record
    derived = ending(metrics.get("error"), metrics["fell"], metrics.get("timed_out", False))
    return {**record, "metrics": {**metrics, "ended": derived}}


def _same_machine(machines: list[list[Any]]) -> bool | None:
    """Whether the two folders' records (their distinct machines, None for a record that does not say)
    were all made on one machine: None when a record does not say."""
    if any(machine is None for side in machines for machine in side):
        return None
    return len(machines[0]) == 1 and machines[0] == machines[1]


def compare_results(
    first: Path, second: Path, labels: Sequence[str] | None = None, ignored: Sequence[str] = VOLATILE
) -> dict[str, Any]:
    """Compare two results folders (module docstring); ``labels``: only these controllers (default: every
    one either folder holds). :class:`krl.eval.records.EvaluationError` for a missing folder or controller."""
    found = [controller_labels(folder, labels) for folder in (first, second)]
    names = list(dict.fromkeys([*found[0], *found[1]]))
    only: dict[str, list[str]] = {"first": [], "second": []}
    equal = different = 0
    largest: dict[str, float] = {}  # numeric fields: the largest absolute difference
    changed: dict[str, None] = {}  # other fields that differ somewhere (booleans, strings, missing)
    moved: list[str] = []
    examples: list[dict[str, Any]] = []
    machines: list[list[Any]] = [[], []]  # each folder's distinct machines among the compared records
    for label in names:
        runs = [read_runs(f / label, label) if (f / label).is_dir() else {} for f in (first, second)]
        only["first"] += [f"{label} {run}" for run in runs[0] if run not in runs[1]]
        only["second"] += [f"{label} {run}" for run in runs[1] if run not in runs[0]]
        for run in (run for run in runs[0] if run in runs[1]):
            for side, seen in zip(runs, machines, strict=True):
                if (machine := side[run].record.get(MACHINE)) not in seen:
                    seen.append(machine)
            differing = compare_records(runs[0][run].record, runs[1][run].record, ignored)
            if not differing:
                equal += 1
                continue
            different += 1
            for key, (x, y) in differing.items():
                gap = _difference(x, y)
                if gap is None:
                    changed.setdefault(key, None)
                else:
                    largest[key] = max(largest.get(key, 0.0), gap)
            if any(key in differing for key in OUTCOMES):
                moved.append(f"{label} {run}")
            if len(examples) < EXAMPLES:
                examples.append({"controller": label, "run": run, "fields": differing})
    return {
        "first": str(first),
        "second": str(second),
        "controllers": names,
        "only_first": only["first"],
        "only_second": only["second"],
        "equal": equal,
        "different": different,
        "outcomes_moved": moved,
        "largest_difference": dict(sorted(largest.items())),
        "changed_fields": sorted(changed),
        "examples": examples,
        "machines": {"first": machines[0], "second": machines[1]},
        "same_machine": _same_machine(machines),
        "identical": not (only["first"] or only["second"] or largest or changed),
    }
