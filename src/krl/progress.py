"""Progress bars for long commands (rich), silent when disabled or when output is not a terminal."""

from __future__ import annotations

import sys
from contextlib import contextmanager

from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)


@contextmanager
def progress_bar(enabled: bool = True):
    """A ``rich.progress.Progress`` (use ``add_task`` / ``update``), drawn on stderr when ``enabled`` and
    stderr is a terminal; otherwise it records progress without printing anything."""
    show = enabled and sys.stderr.isatty()
    with Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        disable=not show,
        transient=False,
    ) as bar:
        yield bar
