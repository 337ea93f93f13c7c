"""The shared Optuna storage: processes that open a new database at the same moment all get it (Optuna's
check-then-create of its tables lost in about 4 of 10 two-process openings without the retry), and an
error a second try cannot mend is raised at once."""

from __future__ import annotations

import multiprocessing

import pytest

PROCESSES, ROUNDS = 3, 3


def _open_at_once(url: str, barrier, results) -> None:
    import optuna

    from krl.util.optuna_storage import study_storage

    optuna.logging.set_verbosity(optuna.logging.ERROR)
    barrier.wait()  # every process imported: they open the file together
    try:
        optuna.create_study(study_name="race", storage=study_storage(url), load_if_exists=True)
        results.put("opened")
    except Exception as error:  # reported to the test, which names it
        results.put(f"{type(error).__name__}: {str(error).splitlines()[0]}")


@pytest.mark.filterwarnings("ignore::optuna.exceptions.ExperimentalWarning")
def test_processes_opening_a_new_sqlite_study_at_once_all_get_it(tmp_path):
    spawn = multiprocessing.get_context("spawn")
    for round_ in range(ROUNDS):
        url = f"sqlite:///{tmp_path / f'study{round_}.db'}"
        barrier, results = spawn.Barrier(PROCESSES), spawn.Queue()
        args = (url, barrier, results)
        processes = [spawn.Process(target=_open_at_once, args=args) for _ in range(PROCESSES)]
        for process in processes:
            process.start()
        outcomes = [results.get(timeout=120) for _ in processes]
        for process in processes:
            process.join()
        assert outcomes == ["opened"] * PROCESSES, f"round {round_}: {outcomes}"


def test_a_refused_connection_is_not_tried_again():
    from sqlalchemy.exc import IntegrityError, OperationalError, ProgrammingError

    from krl.util.optuna_storage import _lost_creation_race

    def error(kind, message: str):
        return kind("SQL", {}, Exception(message))

    assert not _lost_creation_race(error(OperationalError, "connection refused"))
    assert not _lost_creation_race(ValueError("table studies already exists"))
    assert _lost_creation_race(error(OperationalError, "table studies already exists"))  # SQLite
    assert _lost_creation_race(error(ProgrammingError, 'relation "studies" already exists'))  # PostgreSQL
    assert _lost_creation_race(error(IntegrityError, "UNIQUE constraint failed"))
