"""The Optuna storage every krl search and study uses (``krl kernel tune``, ``krl agent study``)."""

from __future__ import annotations

import time

SQLITE_LOCK_TIMEOUT: float = 120.0
"""How long a SQLite study's process waits for the file's write lock before it fails [s]."""

HEARTBEAT: float = 60.0
"""Seconds between a running trial's heartbeats unless given; a trial silent for three is retried."""

CREATION_TRIES: int = 5
"""How many times a process opens a database storage whose first creation it lost to another process."""


def study_storage(url: str, heartbeat: float = HEARTBEAT, retries: int = 2):
    """An Optuna storage for ``url``. A database URL (``sqlite``, ``postgresql``, ``mysql``) gets heartbeats
    every ``heartbeat`` seconds: a running trial silent for three beats (its process died) is failed and
    enqueued again, up to ``retries`` times; SQLite waits up to :data:`SQLITE_LOCK_TIMEOUT` for its write
    lock rather than fail when several processes share the file. Any other URL is handed to Optuna as it
    is.

    Several processes may open a new database at once (a study's jobs, machines started together): Optuna
    creates its tables and version row when they are missing, a check-then-create that one of them loses
    (``table ... already exists``, a duplicate version row); the loser opens it again and finds them made."""
    import optuna

    if not url.startswith(("sqlite", "postgresql", "mysql")):
        return optuna.storages.get_storage(url)
    for attempt in range(CREATION_TRIES - 1):
        try:
            return _database_storage(url, heartbeat, retries)
        except Exception as error:
            if not _lost_creation_race(error):
                raise
            time.sleep(0.2 * (attempt + 1))
    return _database_storage(url, heartbeat, retries)


def _database_storage(url: str, heartbeat: float, retries: int):
    from optuna.storages import RDBStorage, RetryHeartbeatStaleTrialCallback

    sqlite = {"connect_args": {"timeout": SQLITE_LOCK_TIMEOUT}}
    return RDBStorage(
        url,
        engine_kwargs=sqlite if url.startswith("sqlite") else None,
        heartbeat_interval=max(1, round(heartbeat)),
        grace_period=max(3, round(3 * heartbeat)),
        heartbeat_stale_trial_callback=RetryHeartbeatStaleTrialCallback(max_retry=retries),
    )


def _lost_creation_race(error: Exception) -> bool:
    """Whether opening a storage failed because another process was creating the same tables (a duplicate
    table or version row), not for a reason a second try cannot mend (a bad URL, a refused connection)."""
    from sqlalchemy.exc import IntegrityError, OperationalError, ProgrammingError

    if isinstance(error, IntegrityError):
        return True
    return isinstance(error, (OperationalError, ProgrammingError)) and "already exists" in str(error)
