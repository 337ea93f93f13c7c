"""Storages a study cannot keep its trials in (issue 61, M1 and M2): a SQLite URL without a file, a read-only
database, file or folder, a spawned job that failed; each refused or reported in one line, never a
traceback and an exit status of 0."""

from __future__ import annotations

import os
import warnings
from pathlib import Path
from types import SimpleNamespace

import pytest
from optuna.exceptions import ExperimentalWarning
from test_agent_studies import fake_train
from test_study_input import one_line, optuna_database, study_cli

from krl.agent.studies import jobs
from krl.agent.studies.runner import StudyError, StudySettings
from krl.util.optuna_storage import study_storage

TINY_RUN = ["--seeds", "7", "--budget", "400", "--workers", "1", "--jobs", "1", "--quiet"]
"""Options of a study whose trials (faked) finish at once."""


@pytest.fixture
def trainings(monkeypatch) -> list:
    """Training faked (:func:`fake_train`); the list of its calls."""
    calls: list = []
    monkeypatch.setattr("krl.agent.train.train", fake_train(calls))
    return calls


@pytest.mark.parametrize("url", ["sqlite://", "sqlite:///", "sqlite:///:memory:"])
@pytest.mark.parametrize("mode", [[], ["--report"]])
def test_a_sqlite_storage_without_a_file_is_refused_before_any_trial(tmp_path, capsys, trainings, url, mode):
    status, _, err = study_cli(
        capsys, "state-space", "--out", str(tmp_path / "s"), "--storage", url, *TINY_RUN, *mode
    )
    assert status == 2
    assert one_line(err) == (
        f"krl: error: cannot use study storage {url}: it names no file (a database in memory loses its "
        "trials): give sqlite:///FILE"
    )
    assert trainings == []


def test_a_read_only_database_is_one_line_naming_it(tmp_path, capsys, trainings):
    database = optuna_database(tmp_path / "study.db")
    url = f"sqlite:///file:{database}?mode=ro&uri=true"  # SQLite refuses writes, to root too
    status, _, err = study_cli(
        capsys, "state-space", "--out", str(tmp_path / "s"), "--storage", url, *TINY_RUN
    )
    assert status == 2
    assert one_line(err) == (
        f"krl: error: cannot use study storage {url}: (sqlite3.OperationalError) attempt to write a readonly "
        "database"
    )
    assert trainings == []


@pytest.fixture
def read_only(monkeypatch):
    """Make ``os.access`` answer as for a non-root user: the folders and files added to the returned set
    cannot be written (root may write into a chmod'ed folder, so chmod alone proves nothing here)."""
    paths: set[Path] = set()
    access = os.access

    def answer(path, mode, *args, **kwargs):
        if mode & os.W_OK and Path(path).absolute() in paths:
            return False
        return access(path, mode, *args, **kwargs)

    monkeypatch.setattr(os, "access", answer)
    return paths


@pytest.mark.parametrize("mode", [[], ["--report"]])
def test_a_storage_in_a_read_only_folder_or_file_is_refused_naming_it(
    tmp_path, capsys, trainings, read_only, mode
):
    folder = tmp_path / "read-only"
    folder.mkdir()
    database = optuna_database(tmp_path / "kept.db")
    read_only.update({folder, database})
    for url, problem in (
        (f"sqlite:///{folder}/study.db", f"its folder {folder} is read-only"),
        (f"sqlite:///{database}", f"its file {database} is read-only"),
    ):
        argv = ["state-space", "--out", str(tmp_path / "s"), "--storage", url, *TINY_RUN, *mode]
        status, _, err = study_cli(capsys, *argv)
        assert status == 2
        assert one_line(err) == f"krl: error: cannot use study storage {url}: {problem}"
    assert trainings == []


def test_a_read_only_study_folder_is_refused_before_any_trial(tmp_path, capsys, trainings, read_only):
    out = tmp_path / "s"
    out.mkdir()
    read_only.add(out)
    url = f"sqlite:///{tmp_path / 'study.db'}"
    status, _, err = study_cli(capsys, "state-space", "--out", str(out), "--storage", url, *TINY_RUN)
    assert status == 2
    assert one_line(err) == f"krl: error: the study folder {out} is read-only: give another --out"
    assert trainings == []


def test_a_spawned_job_that_failed_fails_the_study(tmp_path, monkeypatch):
    class FailedJob:
        """A spawned job that stopped with exit status 1 (its trials perhaps not stored)."""

        exitcode = 1

        def __init__(self, target, args):
            pass

        def start(self):
            pass

        def join(self):
            pass

    monkeypatch.setattr(
        jobs.multiprocessing, "get_context", lambda method: SimpleNamespace(Process=FailedJob)
    )
    monkeypatch.setattr(jobs, "_job", lambda *args: None)  # this process's own job: all its trials stored
    settings = StudySettings(seeds=(7,), budget=400, workers=1)
    with pytest.raises(StudyError) as refused:
        jobs.run_jobs("state-space", settings, tmp_path, f"sqlite:///{tmp_path / 'x.db'}", 60.0, "quiet", 3)
    assert str(refused.value) == (
        "2 of study state-space's 3 processes stopped with an error (exit status 1, 1): run the same command "
        "again to resume the trials they held"
    )


def test_the_storage_opens_without_optunas_experimental_warning(tmp_path):
    """``--report`` opened it without the filter of the study's own processes: two warning lines on stderr."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        study_storage(f"sqlite:///{tmp_path / 'study.db'}").remove_session()
    assert [str(w.message) for w in caught if issubclass(w.category, ExperimentalWarning)] == []
