"""The tables of ``krl agent heldout``: ``heldout.csv`` and ``heldout.md`` (every label's and every seed's
measures, the drives' usage and the choice), from :mod:`krl.analysis.agent.heldout`'s records."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from krl.agent.action import SATURATED
from krl.agent.callbacks import SUCCESS_TARGETS
from krl.analysis.agent.heldout import DRIVE_STATISTICS, HELDOUT_SEED, METRICS
from krl.util.output import csv_bytes, write_atomic


def write_tables(
    rows: list[dict[str, Any]],
    records: dict[str, list[tuple[int | None, dict[str, Any]]]],
    out: Path,
    choice: dict[str, Any] | None = None,
    ground: str | None = None,
) -> dict[str, str]:
    """``heldout.csv`` (the group rows) and ``heldout.md`` (them, every seed's summary and ``choice``,
    :func:`choose`'s answer, when given) in ``out``; ``ground`` names the config file whose environment
    every policy walked (None: each its own)."""
    columns = ["label", "seeds", "episodes", *(f"{m}_{s}" for m in METRICS for s in ("mean", "std"))]
    write_atomic(out / "heldout.csv", csv_bytes(columns, rows))
    where, reward = (
        (
            "its own training environment",
            "each policy's own training reward: not comparable between policies trained on different rewards",
        )
        if ground is None
        else (f"the environment of `{ground}`", "that environment's reward")
    )
    lines = [
        "# Held-out episodes of the training distribution",
        "",
        f"Each policy walks the same {rows[0]['episodes']} episodes of {where}, seeded from {HELDOUT_SEED} "
        "on (never a training seed), with its deterministic action; mean ± sample std over seeds. Success: "
        f"at least {SUCCESS_TARGETS} waypoints without a fall. Reward/step is {reward}.",
        "",
        "| policy | seeds | targets reached | success rate | fall rate | reward/step |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    lines += [f"| {row['label']} | {row['seeds']} | {_cells(row)} |" for row in rows]
    lines += [
        "",
        "By seed:",
        "",
        "| policy | seed | targets reached | success rate | fall rate | reward/step |",
    ]
    lines += ["| --- | --- | --- | --- | --- | --- |"]
    for label, members in records.items():
        for seed, record in members:
            summary = record["summary"]
            cells = " | ".join(f"{summary[m]:.3g}" for m in METRICS)
            lines.append(f"| {label} | {'-' if seed is None else seed} | {cells} |")
    written = {"csv": str(out / "heldout.csv"), "md": str(out / "heldout.md")}
    drives = drive_rows(records)
    if drives:
        write_atomic(out / "heldout-drives.csv", csv_bytes(list(drives[0]), drives))
        written["drives_csv"] = str(out / "heldout-drives.csv")
        lines += ["", *_drive_lines(drives)]
    if choice is not None:
        lines += ["", *_choice_lines(choice)]
    write_atomic(out / "heldout.md", "\n".join(lines) + "\n")
    return written


def drive_rows(records: dict[str, list[tuple[int | None, dict[str, Any]]]]) -> list[dict[str, Any]]:
    """One row per label and driven number (:func:`drive_usage`), each statistic the mean over the
    label's seeds; none for labels that drive nothing (or records written before drives were counted)."""
    rows = []
    for label, members in records.items():
        usages = [record.get("drive_usage") or {} for _, record in members]
        for drive in usages[0]:
            row: dict[str, Any] = {"label": label, "drive": drive}
            for statistic in DRIVE_STATISTICS:
                row[statistic] = float(np.mean([usage[drive][statistic] for usage in usages]))
            rows.append(row)
    return rows


def _drive_lines(rows: list[dict[str, Any]]) -> list[str]:
    lines = [
        "How the gait-driving policies used their drives: what each asked for (before the drive filter) "
        f"over every step of the held-out episodes, mean over seeds; at a bound: the share of steps whose "
        f"action was at ±{SATURATED} or beyond.",
        "",
        "| policy | drive | mean | 5 % | 95 % | at low bound | at high bound |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    for row in rows:
        cells = " | ".join(f"{row[s]:.3g}" for s in DRIVE_STATISTICS)
        lines.append(f"| {row['label']} | {row['drive']} | {cells} |")
    return lines


def _choice_lines(choice: dict[str, Any]) -> list[str]:
    others = [label for label in choice["tied"] if label != choice["chosen"]]
    tie = (
        f"tied within {choice['tolerance']:.3g} with {', '.join(others)}; the most targets reached wins"
        if others
        else "no other candidate within one episode of it"
    )
    lines = [
        f"Chosen: **{choice['chosen']}**, the highest held-out success rate "
        f"({choice['best_success_rate']:.3g}) of the candidates, {tie} "
        "(`krl.analysis.agent.heldout.choose`).",
    ]
    baseline = choice.get("baseline")
    if baseline:
        for where, check in baseline["checks"].items():
            need = "better than" if check["must_beat"] else "no worse than"
            verdict = "holds" if check["holds"] else "does not hold"
            lines.append(
                f"- {need} {baseline['label']} on {where}: success {check['margin']:+.3g} against it, "
                f"one episode {check['tolerance']:.3g}: {verdict}."
            )
        lines.append(
            f"The choice **{'stands' if baseline['stands'] else 'does not stand'}** against "
            f"{baseline['label']} (`krl.analysis.agent.heldout.against_baseline`)."
        )
    return lines


def _cells(row: dict[str, Any]) -> str:
    cells = []
    for metric in METRICS:
        mean, std = row[f"{metric}_mean"], row[f"{metric}_std"]
        cells.append(f"{mean:.3g}" if math.isnan(std) else f"{mean:.3g} ± {std:.2g}")
    return " | ".join(cells)
