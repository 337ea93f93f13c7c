"""A stand-in ``krl`` for the tests of the pipeline scripts under examples/: a shell script on PATH that
logs its arguments (and does what each test's script text says)."""

from __future__ import annotations

import os
import subprocess
from collections.abc import Callable
from pathlib import Path


def stand_in_environment(folder: Path, script: str, **variables: str) -> dict[str, str]:
    """The environment in which ``krl`` is ``script`` (written to ``folder/bin/krl``), logging to
    ``folder/krl.log`` (``LOG``), with ``variables`` set."""
    bin_dir = folder / "bin"
    bin_dir.mkdir()
    (bin_dir / "krl").write_text(script)
    (bin_dir / "krl").chmod(0o755)
    return (
        os.environ | {"PATH": f"{bin_dir}:{os.environ['PATH']}", "LOG": str(folder / "krl.log")} | variables
    )


def run_logged(script: Path, folder: Path, stand_in: str, **variables: str) -> list[str]:
    """Run the pipeline ``script`` to its end in ``folder`` with ``stand_in`` as ``krl`` (and ``variables``
    set); the stand-in's log, one line per ``krl`` command."""
    env = stand_in_environment(folder, stand_in, **variables)
    subprocess.run(["bash", str(script)], cwd=folder, env=env, check=True, capture_output=True, timeout=60)
    return (folder / "krl.log").read_text().splitlines()


def line_index(lines: list[str], *parts: str) -> int:
    """The first of ``lines`` that holds every one of ``parts``."""
    return next(i for i, line in enumerate(lines) if all(part in line for part in parts))


def check_restore(
    folder: Path, run: Callable[[], list[str]], family: str, group: str, stopped: str, newer: str
) -> None:
    """A pipeline that trains runs under ``RUNS/family`` and an agent's seed group ``RUNS/group`` goes on
    from what a session committed (``COMMITTED``, in ``folder``): the committed run ``stopped`` is copied
    to RUNS and trained on, a run ``newer`` already in RUNS is kept as it is, and the group's committed
    seed lands in RUNS/group, not among the runs. ``run`` runs the pipeline; returns nothing."""
    committed = folder / "committed"
    (committed / stopped).mkdir(parents=True)
    (committed / stopped / "config.json").write_text('{"run": "stopped"}')
    (folder / "runs" / family / newer).mkdir(parents=True)
    (committed / newer).mkdir()
    (committed / newer / "config.json").write_text("{}")
    (committed / group / "seed345").mkdir(parents=True)
    (committed / group / "seed345" / "config.json").write_text('{"seed": 345}')
    lines = run()
    assert (folder / "runs" / family / stopped / "config.json").read_text() == '{"run": "stopped"}'
    assert not list((folder / "runs" / family / newer).iterdir())
    assert any(f"--out runs/{family}/{stopped} " in line for line in lines)
    assert (folder / "runs" / group / "seed345" / "config.json").read_text() == '{"seed": 345}'
    assert not (folder / "runs" / family / group).exists()
