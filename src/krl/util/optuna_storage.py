"""The Optuna storage every krl search and study uses (``krl kernel tune``, ``krl agent study``)."""

from __future__ import annotations

SQLITE_LOCK_TIMEOUT: float = 120.0
"""How long a SQLite study's process waits for the file's write lock before it fails [s]."""


def study_storage(url: str, heartbeat: float = 60.0, retries: int = 2):
    """An Optuna storage for ``url``. A database URL (``sqlite``, ``postgresql``, ``mysql``) gets heartbeats
    every ``heartbeat`` seconds: a running trial silent for three beats (its process died) is failed and
    enqueued again, up to ``retries`` times; SQLite waits up to :data:`SQLITE_LOCK_TIMEOUT` for its write
    lock rather than fail when several processes share the file. Any other URL is handed to Optuna as it
    is."""
    import optuna
    from optuna.storages import RDBStorage, RetryHeartbeatStaleTrialCallback

    if not url.startswith(("sqlite", "postgresql", "mysql")):
        return optuna.storages.get_storage(url)
    sqlite = {"connect_args": {"timeout": SQLITE_LOCK_TIMEOUT}}
    return RDBStorage(
        url,
        engine_kwargs=sqlite if url.startswith("sqlite") else None,
        heartbeat_interval=max(1, round(heartbeat)),
        grace_period=max(3, round(3 * heartbeat)),
        heartbeat_stale_trial_callback=RetryHeartbeatStaleTrialCallback(max_retry=retries),
    )
