"""Markdown and CSV helpers shared by ``krl report``'s sections (``krl.eval.report`` and
``krl.eval.sweep_report``)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

from krl.util.output import csv_bytes


def controller_table(
    rows: list[dict[str, Any]],
    key: str,
    columns: Sequence[Any],
    headers: Sequence[str],
    cell: Callable[[dict[str, Any]], str],
) -> list[str]:
    """Markdown table lines: one row per controller (in ``rows``' order), one column per value of
    ``row[key]`` in ``columns`` (headed ``headers``) holding ``cell(row)``, or "–" where it has no row."""
    lines = [
        "| controller | " + " | ".join(headers) + " |",
        "| --- | " + " | ".join("---" for _ in columns) + " |",
    ]
    for controller in dict.fromkeys(r["controller"] for r in rows):
        mine = {r[key]: r for r in rows if r["controller"] == controller}
        cells = [cell(mine[column]) if column in mine else "–" for column in columns]
        lines.append(f"| {controller} | " + " | ".join(cells) + " |")
    return lines


def rows_csv(rows: list[dict[str, Any]]) -> bytes:
    """CSV of ``rows`` in which every key of any row is a column (the thesis's rows lack some of ours)."""
    columns: list[str] = []
    for row in rows:
        columns += [key for key in row if key not in columns]
    return csv_bytes(columns, [{c: row.get(c) for c in columns} for row in rows])
