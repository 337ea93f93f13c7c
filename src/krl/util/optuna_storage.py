"""The Optuna storage every krl search and study uses (``krl kernel tune``, ``krl agent study``): opened
(:func:`study_storage`), checked before anything trains (:func:`check_storage`), and shown.

A PostgreSQL URL carries its password (``postgresql://USER:PASSWORD@HOST/DB`` or ``...?password=...``):
:func:`masked` is the one helper through which every status, error and report shows or writes a URL or a
command line holding one. :func:`study_storage` refuses, before opening it, a URL it cannot use safely
(:func:`url_problem`: a SQLite storage without a file, a password with an unencoded ``@``, a read-only
SQLite file or folder); :func:`check_study_database` refuses a SQLite file that is no Optuna study database
before Optuna would create its tables in it, and :func:`storage_failure` words a storage that cannot be
opened or written (a malformed URL, a missing driver, a refused connection, a missing folder, a corrupt
file).
"""

from __future__ import annotations

import os
import re
import sqlite3
import time
import warnings
from pathlib import Path

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

    Raises ``ValueError`` (one line, password masked) for a database URL :func:`url_problem` refuses.

    Several processes may open a new database at once (a study's jobs, machines started together): Optuna
    creates its tables and version row when they are missing, a check-then-create that one of them loses
    (``table ... already exists``, a duplicate version row); the loser opens it again and finds them made."""
    import optuna

    if not url.startswith(("sqlite", "postgresql", "mysql")):
        return optuna.storages.get_storage(url)
    check_url(url)
    for attempt in range(CREATION_TRIES - 1):
        try:
            return _database_storage(url, heartbeat, retries)
        except Exception as error:
            if not _lost_creation_race(error):
                raise
            time.sleep(0.2 * (attempt + 1))
    return _database_storage(url, heartbeat, retries)


def _database_storage(url: str, heartbeat: float, retries: int):
    from optuna.exceptions import ExperimentalWarning
    from optuna.storages import RDBStorage, RetryHeartbeatStaleTrialCallback

    sqlite = {"connect_args": {"timeout": SQLITE_LOCK_TIMEOUT}}
    with warnings.catch_warnings():  # Optuna's heartbeat is "experimental": no warning lines on stderr
        warnings.simplefilter("ignore", ExperimentalWarning)
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


PASSWORD = re.compile(
    r"""(?:(?<=\w://)|(?<=\w//)|(?<![^\s='"])(?![^\s:/@'"]*://))(?P<user>[^\s:/@'"]*):\S*@"""
)
"""A URL's ``user:password@`` (after ``SCHEME://`` or ``SCHEME//``, or starting a word that is no
``SCHEME://``: a malformed URL too), the password up to the last ``@`` of the word: a password may hold
``/``, quotes or an unencoded ``@`` (not whitespace, which a URL holds only percent-encoded)."""

PASSWORD_PARAMETER = re.compile(r"""(?<![^\s?&;'"])(?P<key>password=)[^\s&;'"]*""", re.IGNORECASE)
"""A ``password=VALUE`` query parameter (``...?password=...``, ``&password=...``) or connection-string
word."""

MASK = "***"
"""What a password is shown as."""

SQLITE_PREFIX = "sqlite:///"
"""The start of a SQLite file storage's URL (the path follows)."""

OPTUNA_TABLES: frozenset[str] = frozenset({"studies", "trials", "version_info"})
"""Tables every Optuna database storage holds."""

BACKGROUND = re.compile(r"\s*\(Background on this error at: [^)]*\)")
"""SQLAlchemy's link appended to its errors."""


def masked(text: str) -> str:
    """``text`` (a URL, a command line or a message holding one) with every URL's password shown as
    :data:`MASK`, as its userinfo (``postgresql://krl:***@db/studies``) or a ``password=`` parameter
    (``postgresql://krl@db/studies?password=***``)."""
    return PASSWORD_PARAMETER.sub(rf"\g<key>{MASK}", PASSWORD.sub(rf"\g<user>:{MASK}@", text))


IN_MEMORY = ("", ":memory:")
"""The SQLite database names that open a database in memory (lost with its process, not shared)."""


def url_problem(url: str) -> str | None:
    """Why the database storage ``url`` cannot be used safely, or None: a SQLite storage without a file
    (``sqlite://``, ``sqlite:///``, ``sqlite:///:memory:``: each process and connection would get its own
    database in memory and the trials would be lost), more than one ``@`` before the host (an unencoded
    ``@`` in the password, which the driver would split there and show the rest as the host), or a SQLite
    file or its folder that cannot be written."""
    scheme, _, rest = url.partition("://")
    if scheme.split("+")[0] == "sqlite":
        database = rest.removeprefix("/").partition("?")[0] if rest.startswith("/") else ""
        if database in IN_MEMORY:
            return f"it names no file (a database in memory loses its trials): give {SQLITE_PREFIX}FILE"
        return read_only_problem(Path(database))
    if rest.partition("?")[0].count("@") > 1:
        return "it holds more than one '@': write an '@' of the password as %40"
    return None


def check_url(url: str) -> None:
    """Raise ``ValueError`` in one line naming the storage (password masked) if :func:`url_problem` refuses
    the database URL ``url``."""
    problem = url_problem(url)
    if problem is not None:
        raise ValueError(f"cannot use study storage {masked(url)}: {problem}")


def read_only_problem(path: Path) -> str | None:
    """Why SQLite cannot write its database file ``path`` (a read-only file, or a read-only folder, where
    SQLite writes its journal beside it), or None."""
    folder = path.absolute().parent
    if path.exists() and not os.access(path, os.W_OK):
        return f"its file {path} is read-only"
    if folder.is_dir() and not os.access(folder, os.W_OK | os.X_OK):
        return f"its folder {folder} is read-only"
    return None


def sqlite_path(url: str) -> Path | None:
    """The file of a ``sqlite:///FILE`` storage URL; None for any other storage."""
    return Path(url.removeprefix(SQLITE_PREFIX)) if url.startswith(SQLITE_PREFIX) else None


def storage_failure(url: str, error: BaseException) -> str:
    """One line naming the storage (password masked) and why it cannot be used: the error's first line,
    without SQLAlchemy's background link."""
    from optuna.exceptions import StorageInternalError

    while isinstance(error, StorageInternalError) and error.__cause__ is not None:
        error = error.__cause__  # Optuna's "exception during the commit": the database's own is the reason
    text = str(error).strip()
    cause = BACKGROUND.sub("", text.splitlines()[0]) if text else type(error).__name__
    return f"cannot use study storage {masked(url)}: {masked(cause)}"


def database_errors() -> tuple[type[BaseException], ...]:
    """The errors of a storage that opened but fails later (a lost connection, a file gone bad, a read-only
    database): SQLAlchemy's, SQLite's and Optuna's failed commit."""
    from optuna.exceptions import StorageInternalError
    from sqlalchemy.exc import SQLAlchemyError

    return (SQLAlchemyError, sqlite3.Error, StorageInternalError)


def storage_errors() -> tuple[type[BaseException], ...]:
    """The errors opening or querying a storage raises for a bad storage rather than a bug:
    :func:`database_errors` and Optuna's missing driver (an ``ImportError``)."""
    return (*database_errors(), ImportError)


def database_tables(path: Path) -> set[str]:
    """The tables of the SQLite file ``path``, read without writing to it.

    Raises:
        sqlite3.Error: ``path`` is no SQLite database (garbage, truncated) or cannot be read.
    """
    connection = sqlite3.connect(f"{path.resolve().as_uri()}?mode=ro", uri=True)
    try:
        rows = connection.execute("SELECT name FROM sqlite_master WHERE type = 'table'").fetchall()
    finally:
        connection.close()
    return {name for (name,) in rows}


def check_study_database(url: str) -> None:
    """Raise ``ValueError`` (one line) for a SQLite storage whose file exists and is not an Optuna
    database: no SQLite file at all, or one holding other tables (Optuna would add its own to it). A
    missing or empty file, or another kind of storage, passes: Optuna creates what a new study needs."""
    path = sqlite_path(url)
    if path is None or not path.is_file() or path.stat().st_size == 0:
        return
    try:
        tables = database_tables(path)
    except sqlite3.Error as error:
        raise ValueError(storage_failure(url, error)) from None
    if tables and not OPTUNA_TABLES <= tables:
        raise ValueError(
            f"{path} is not an Optuna study database (its tables: {', '.join(sorted(tables)[:5])}); "
            "give another --storage or --out"
        )


def check_storage(url: str, heartbeat: float = HEARTBEAT) -> None:
    """Open the storage at ``url`` once, before anything is trained or spawned: a bad one (malformed URL, no
    driver, refused connection, one :func:`url_problem` refuses, missing folder, corrupt file, a foreign
    SQLite file) raises ``ValueError`` in one line naming it, password masked."""
    try:
        check_study_database(url)
        study_storage(url, heartbeat).remove_session()
    except storage_errors() as error:
        raise ValueError(storage_failure(url, error)) from None
