"""A study's snapshot: what it needs to resume on another machine, small enough to commit or copy.

``krl agent study NAME --snapshot DIR`` copies, from the study's folder ``OUT``:

* its SQLite storage ``study.db``, through SQLite's backup API, so the copy is consistent while the
  study's jobs write (a PostgreSQL storage stays in its server: ``pg_dump`` is its tool);
* each trial's run folder ``trials/<stage>/<entry>/`` as :func:`krl.agent.run_folder.snapshot_run` copies
  it: without TensorBoard's event files, which repeat the training log.

Every file is written through a temporary name and renamed, so a snapshot stopped halfway leaves each file
whole, old or new; files of the snapshot's run folders that the study no longer has (an older checkpoint)
are removed once the new ones are in place. Copying ``DIR`` back into ``OUT`` (``cp -r DIR/. OUT/``) and
running the study command again resumes it (``docs/studies.md``).
"""

from __future__ import annotations

import sqlite3
from pathlib import Path
from typing import Any

from krl.agent.run_folder import snapshot_run
from krl.util.output import write_atomic

DATABASE = "study.db"
"""A study's default SQLite storage file in its folder (``krl agent study``'s ``--storage`` default)."""


def _backup_database(source: Path, target: Path) -> None:
    """A consistent copy of the SQLite database ``source`` (others may be writing) at ``target``."""
    for left in target.parent.glob(f".{target.name}.*.tmp"):  # of a snapshot stopped halfway
        left.unlink()
    reader, memory = sqlite3.connect(source), sqlite3.connect(":memory:")
    try:
        reader.backup(memory)
        data = memory.serialize()
    finally:
        reader.close()
        memory.close()
    write_atomic(target, data)


def snapshot_study(out: Path, url: str, dest: Path) -> dict[str, Any]:
    """Snapshot the study whose folder is ``out`` and storage ``url`` into ``dest`` (module docstring).

    Returns ``database`` (the copy's path, or None for a server storage), ``runs`` (the run folders
    copied, as ``stage/entry``) and ``bytes`` (what the run folders' copies hold).

    Raises:
        FileNotFoundError: ``out`` holds no trial run folder and the storage no SQLite file to copy.
        ValueError: ``dest`` is the study's own folder (its run folders would be cut down to the snapshot's
            files, TensorBoard's deleted).
    """
    if dest.resolve() == out.resolve():
        raise ValueError(f"--snapshot {dest} is the study's own folder (--out): give another folder")
    database = None
    if url.startswith("sqlite:///"):
        source = Path(url.removeprefix("sqlite:///"))
        if source.is_file():
            database = (
                dest / DATABASE if source.resolve() == (out / DATABASE).resolve() else dest / source.name
            )
            _backup_database(source, database)
    runs = sorted(path for path in (out / "trials").glob("*/*") if path.is_dir())
    if database is None and not runs:
        raise FileNotFoundError(f"nothing to snapshot: no study database and no trial run folder in {out}")
    copied = sum(snapshot_run(run, dest / run.relative_to(out)) for run in runs)
    return {
        "database": None if database is None else str(database),
        "runs": [str(run.relative_to(out / "trials")) for run in runs],
        "bytes": copied,
    }
