"""Which pushes of a push sweep some controller survives: the headroom above a controller's push row.

Attempt ``a`` of ``krl evaluate --push-sweep`` draws its push (its start time, the point on the trunk, its
direction relative to the walk) from the sweep's settings alone, whatever the force, the controller or its
training seed, so every record of one results folder with the same sweep settings meets the same pushes.
Counting per push which controller seeds survived it (success: no fall and the walk's waypoint reached)
splits a controller's misses into pushes that another seed of the same agent survived, pushes that only
another controller survived, and pushes that no controller in the folder survived. The last are a bound on
what the controllers at hand reach, not a proof of a physical limit: a better controller may survive them.

"Some seed" of an agent is an optimistic figure (the best of k tries); beside it, ``independent`` is what
"some seed" would be if each seed survived each push independently at its own rate, 1 - Π_s (1 - p_s):
an observed share below it says the same pushes defeat the seeds together.

``krl analyze push-sweep`` writes its table.
"""

from __future__ import annotations

import json
import math
import statistics
from collections.abc import Sequence
from typing import Any

from krl.eval.evaluate import PUSH_DIR

SAME_PUSH_SETTINGS: tuple[str, ...] = ("seed", "directions", "window", "target", "d_min")
"""The push sweep's settings (a record's ``sweep``) that decide attempt ``a``'s push or the walk it meets
(``attempts`` does not: docs/evaluation.md); records that differ in any of them met other pushes under
the same attempt number."""

Outcomes = dict[tuple[float, int], dict[tuple[str, int | None], bool]]
"""``{(magnitude [N], attempt): {(controller label, training seed or None): success}}``."""


def push_outcomes(found: dict[str, dict[str, list[dict[str, Any]]]]) -> Outcomes:
    """Each push attempt's success per controller seed, from :func:`krl.eval.report.collect`'s records.

    Raises:
        ValueError: no controller has push records, or two controllers' sweeps drew different pushes.
    """
    outcomes: Outcomes = {}
    settings: dict[str, tuple[Any, ...]] = {}
    for label, groups in found.items():
        for record in groups.get(PUSH_DIR, []):
            settings[label] = tuple(json.dumps(record["sweep"].get(key)) for key in SAME_PUSH_SETTINGS)
            key = (float(record["magnitude"]), int(record["attempt"]))
            outcomes.setdefault(key, {})[(label, record.get("seed"))] = bool(record["metrics"]["success"])
    if not outcomes:
        raise ValueError("no push-sweep records in these results (run `krl evaluate --push-sweep` first)")
    if len(set(settings.values())) > 1:
        first, *others = settings
        other = next(label for label in others if settings[label] != settings[first])
        raise ValueError(
            f"{first} and {other} walked push sweeps with other settings ({', '.join(SAME_PUSH_SETTINGS)}): "
            "their attempts are not the same pushes"
        )
    return outcomes


def headroom_rows(outcomes: Outcomes, controllers: Sequence[str]) -> list[dict[str, Any]]:
    """One row per magnitude: ``pushes`` (distinct attempts), ``controller_seeds`` (how many controller
    seeds walked them), ``some_controller`` (the share of them that at least one of those survived) and,
    per label in ``controllers``, ``<label>/seeds``, ``<label>/mean`` (success pooled over its seeds),
    ``<label>/some_seed``, ``<label>/every_seed`` and ``<label>/independent`` (see the module's
    docstring); a last row ``magnitude: "mean"`` averages the rates over the magnitudes, as the push row's
    mean does.

    Raises:
        ValueError: a label in ``controllers`` has no push records at a magnitude, or a seed of it lacks an
            attempt that another controller seed walked.
    """
    rows = []
    for magnitude in sorted({m for m, _ in outcomes}):
        attempts = {a: survivors for (m, a), survivors in outcomes.items() if m == magnitude}
        pushes = [attempts[a] for a in sorted(attempts)]
        row: dict[str, Any] = {
            "magnitude": magnitude,
            "pushes": len(pushes),
            "controller_seeds": len({walker for survivors in pushes for walker in survivors}),
            "some_controller": statistics.fmean(any(survivors.values()) for survivors in pushes),
        }
        for label in controllers:
            seeds = sorted({seed for survivors in pushes for (c, seed) in survivors if c == label}, key=str)
            if not seeds:
                raise ValueError(f"--controller {label!r}: no push records at {magnitude:g} N")
            for attempt, survivors in attempts.items():
                missing = [seed for seed in seeds if (label, seed) not in survivors]
                if missing:
                    raise ValueError(
                        f"{label} (seed {missing[0]}) has no record of attempt {attempt} at {magnitude:g} N "
                        "(an unfinished evaluation?): every seed must meet every push"
                    )
            outcome = [[survivors[(label, seed)] for seed in seeds] for survivors in pushes]
            rates = [statistics.fmean(push[s] for push in outcome) for s in range(len(seeds))]
            row |= {
                f"{label}/seeds": len(seeds),
                f"{label}/mean": statistics.fmean(rates),
                f"{label}/some_seed": statistics.fmean(any(push) for push in outcome),
                f"{label}/every_seed": statistics.fmean(all(push) for push in outcome),
                f"{label}/independent": 1.0 - math.prod(1.0 - rate for rate in rates),
            }
        rows.append(row)
    mean_row: dict[str, Any] = {"magnitude": "mean"}
    for column in rows[0]:
        if column not in {"magnitude", "pushes", "controller_seeds"} and not column.endswith("/seeds"):
            mean_row[column] = statistics.fmean(row[column] for row in rows)
    return [*rows, mean_row]


def headroom_markdown(rows: list[dict[str, Any]], controllers: Sequence[str]) -> str:
    """The rows as a markdown section, one column group per controller."""
    header = [
        "force [N]",
        "pushes",
        f"survived by some of the {rows[0]['controller_seeds']} controller seeds",
    ]
    for label in controllers:
        seeds = rows[0][f"{label}/seeds"]
        header += [f"{label} ({seeds} seed{'s' if seeds > 1 else ''}): mean"]
        header += ["some seed", "every seed", "some seed if independent"] if seeds > 1 else []
    lines = ["| " + " | ".join(header) + " |", "|" + " --- |" * len(header)]
    for row in rows:
        force = row["magnitude"] if row["magnitude"] == "mean" else f"{row['magnitude']:g}"
        cells = [force, str(row.get("pushes", "")), f"{row['some_controller']:.2f}"]
        for label in controllers:
            names = (
                ("mean", "some_seed", "every_seed", "independent")
                if rows[0][f"{label}/seeds"] > 1
                else ("mean",)
            )
            cells += [f"{row[f'{label}/{name}']:.2f}" for name in names]
        lines.append("| " + " | ".join(cells) + " |")
    return (
        "## Headroom\n\nShare of the sweep's distinct pushes survived (success), per force: by some "
        "controller seed in the folder, and per controller its mean over seeds, by some seed, by every seed "
        "and by some seed were each seed's survival independent at its rate (`krl.analysis.push_headroom`)."
        "\n\n" + "\n".join(lines) + "\n"
    )
