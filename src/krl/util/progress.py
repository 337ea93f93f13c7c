"""Progress bars for long commands (rich on stderr), silent when disabled or when stderr is no terminal."""

from __future__ import annotations

import sys

from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)


def progress_bar(
    enabled: bool = True, unit: str = "", status: bool = False, transient: bool = False
) -> Progress:
    """A ``rich.progress.Progress`` to use as a context manager (``add_task`` / ``update``).

    Args:
        enabled: draw it (only if stderr is a terminal as well).
        unit: text shown after the ``done/total`` count (e.g. ``"targets"``).
        status: show each task's ``status`` field (pass ``status=...`` to ``add_task``/``update``).
        transient: remove the bar when done.
    """
    columns = [TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn()]
    if unit:
        columns.append(TextColumn(unit))
    columns += [TimeElapsedColumn(), TimeRemainingColumn()]
    if status:
        columns.append(TextColumn("{task.fields[status]}"))
    return Progress(
        *columns,
        console=Console(stderr=True),
        disable=not (enabled and sys.stderr.isatty()),
        transient=transient,
    )
