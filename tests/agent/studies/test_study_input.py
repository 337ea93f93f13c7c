"""``krl agent study``'s input refused in one line before anything is created (issue 47): run options every
trial would fail on, bad storages, a snapshot into the study's own folder, a foreign SQLite file; a storage
password never shown or written; ``--json`` alone on stdout."""

from __future__ import annotations

import json
import os
import sqlite3
from pathlib import Path

import optuna
import pytest
from test_agent_studies import fake_train

from krl.agent.studies import runner
from krl.cli import main
from krl.util import optuna_storage
from krl.util.optuna_storage import masked


def study_cli(capsys, *argv: str) -> tuple[int, str, str]:
    """``krl agent study ARGV``: its exit status, stdout and stderr."""
    status = main(["agent", "study", *argv])
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def one_line(err: str) -> str:
    """The one error line of a refused command (fails on a traceback or several lines)."""
    assert err.count("\n") == 1, err
    return err.strip()


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--num-envs", "0"], "--workers and --num-envs must be at least 1, got 2 and 0"),
        (["--trials", "0"], "--trials must be at least 1, got 0"),
        (["--trials", "-2"], "--trials must be at least 1, got -2"),
        (["--top", "0"], "--top must be at least 1, got 0"),
        (["--heartbeat", "nan"], "--heartbeat must be a positive number of seconds, got nan"),
        (["--heartbeat", "inf"], "--heartbeat must be a positive number of seconds, got inf"),
        (["--heartbeat", "-1"], "--heartbeat must be a positive number of seconds, got -1.0"),
    ],
)
def test_run_options_every_trial_would_fail_on_are_refused_before_any_trial(
    tmp_path, capsys, options, message
):
    out = tmp_path / "study"
    status, _, err = study_cli(capsys, "ppo-search", "--out", str(out), *options)
    assert status == 2 and message in one_line(err)
    assert not out.exists()  # no storage, no trial


def optuna_database(path: Path) -> Path:
    """A real (empty) Optuna study database at ``path``."""
    optuna.create_study(study_name="other", storage=f"sqlite:///{path}")
    return path


def bad_storages(tmp_path: Path) -> dict[str, str]:
    """Storages that cannot be used, by what is wrong with them."""
    (tmp_path / "a-file").write_text("not a folder")
    (tmp_path / "garbage.db").write_bytes(b"garbage, not SQLite" * 100)
    whole = optuna_database(tmp_path / "whole.db").read_bytes()
    (tmp_path / "cut.db").write_bytes(whole[: len(whole) // 3])
    return {
        "malformed": "postgresql//krl:secret@db.example/studies",
        "no dialect": "nosuchdb://krl:secret@db.example/studies",
        "no driver": "postgresql+nosuchdriver://krl:secret@db.example/studies",
        "refused port": "postgresql://krl:secret@127.0.0.1:1/studies",
        "a password with a slash": "postgresql://krl:Top/secret@127.0.0.1:1/studies",
        "a password parameter": "postgresql://krl@127.0.0.1:1/studies?password=secret",
        "an unencoded @ in the password": "postgresql://krl:top@secret@127.0.0.1:1/studies",
        "missing folder": f"sqlite:///{tmp_path}/missing/folder/study.db",
        "a file for a folder": f"sqlite:///{tmp_path}/a-file/study.db",
        "corrupt": f"sqlite:///{tmp_path}/garbage.db",
        "truncated": f"sqlite:///{tmp_path}/cut.db",
    }


@pytest.mark.parametrize("mode", [[], ["--report"]])
def test_a_bad_storage_is_one_line_naming_it_with_its_password_masked(tmp_path, capsys, mode):
    for problem, url in bad_storages(tmp_path).items():
        status, _, err = study_cli(
            capsys, "state-space", "--out", str(tmp_path / "s"), "--storage", url, *mode
        )
        line = one_line(err)
        assert status == 2, problem
        # the storage named (a missing SQLite file to --report: "has not been started in" it)
        assert masked(url) in line and "secret" not in line, (problem, line)


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into a read-only folder")
def test_a_read_only_folder_for_the_storage_is_one_line(tmp_path, capsys):
    folder = tmp_path / "read-only"
    folder.mkdir(mode=0o555)
    url = f"sqlite:///{folder}/study.db"
    status, _, err = study_cli(capsys, "state-space", "--out", str(tmp_path / "s"), "--storage", url)
    assert status == 2 and f"cannot use study storage {url}: " in one_line(err)


@pytest.mark.parametrize("mode", [[], ["--report"]])
def test_a_foreign_sqlite_file_is_refused_without_writing_to_it(tmp_path, capsys, mode):
    foreign = tmp_path / "notes.db"
    with sqlite3.connect(foreign) as connection:
        connection.execute("CREATE TABLE notes (text TEXT)")
        connection.execute("INSERT INTO notes VALUES ('mine')")
    connection.close()
    before = foreign.read_bytes()
    url = f"sqlite:///{foreign}"
    status, _, err = study_cli(capsys, "state-space", "--out", str(tmp_path / "s"), "--storage", url, *mode)
    assert status == 2
    assert one_line(err) == (
        f"krl: error: {foreign} is not an Optuna study database (its tables: notes); give another --storage "
        "or --out"
    )
    assert foreign.read_bytes() == before


def test_a_snapshot_into_the_studys_own_folder_is_refused_and_keeps_its_files(tmp_path, capsys):
    out = tmp_path / "study"
    run = out / "trials" / "list" / "residual-seed7"
    run.mkdir(parents=True)
    events = run / "events.out.tfevents.1.host"
    events.write_bytes(b"TensorBoard's")
    (run / "progress.csv").write_text("time/total_timesteps\n1\n")
    status, _, err = study_cli(capsys, "alternative", "--out", str(out), "--snapshot", str(out))
    assert status == 2
    assert one_line(err) == (
        f"krl: error: cannot snapshot study alternative: --snapshot {out} is the study's own folder (--out): "
        "give another folder"
    )
    assert events.read_bytes() == b"TensorBoard's"


def test_masked_hides_every_urls_password_and_nothing_else():
    assert masked("postgresql://krl:s3cr%40t@db:5432/studies") == "postgresql://krl:***@db:5432/studies"
    assert masked("postgresql+psycopg://krl:p@ss@db/studies") == "postgresql+psycopg://krl:***@db/studies"
    assert masked("postgresql//krl:secret@db/studies") == "postgresql//krl:***@db/studies"  # malformed
    assert masked("krl agent study x --storage=mysql://u:pw@h/d --jobs 2") == (
        "krl agent study x --storage=mysql://u:***@h/d --jobs 2"
    )
    # issue 61: a password holding "/" or "@", given as a parameter, or in a quoted command line
    assert masked("postgresql://krl:Top/Secret99@127.0.0.1:9/x") == "postgresql://krl:***@127.0.0.1:9/x"
    assert masked("postgresql://krl:Top@Sec/ret99@127.0.0.1:9/x") == "postgresql://krl:***@127.0.0.1:9/x"
    assert masked("postgresql://krl@db/x?sslmode=require&Password=S3&a=b") == (
        "postgresql://krl@db/x?sslmode=require&Password=***&a=b"
    )
    assert masked("""krl agent study x --storage 'postgresql://krl:a/b'"'"'c@db/x' --jobs 2""") == (
        "krl agent study x --storage 'postgresql://krl:***@db/x' --jobs 2"
    )
    for plain in ("sqlite:////tmp/a:b@c/study.db", "postgresql://krl@db/studies", "sqlite:///study.db"):
        assert masked(plain) == plain


POSTGRES = "postgresql://krl:secret@db.example/krl_studies"
"""A storage URL with a password; :func:`as_sqlite` serves it from a SQLite file."""


@pytest.fixture
def as_sqlite(tmp_path, monkeypatch):
    """Every storage URL opened as one SQLite file, and training faked: a study "on PostgreSQL" runs here."""
    real = optuna_storage.study_storage
    database = f"sqlite:///{tmp_path / 'served.db'}"

    def served(url, *args, **kwargs):
        return real(database, *args, **kwargs)

    monkeypatch.setattr(optuna_storage, "study_storage", served)
    monkeypatch.setattr(runner, "study_storage", served)
    monkeypatch.setattr("krl.agent.train.train", fake_train([]))


def test_a_storage_password_is_masked_in_the_status_and_the_report(tmp_path, capsys, as_sqlite):
    argv = ["state-space", "--out", str(tmp_path / "s"), "--storage", POSTGRES, "--seeds", "7"]
    argv += ["--budget", "400", "--workers", "1", "--jobs", "1", "--quiet", "--json"]
    status, out, err = study_cli(capsys, *argv)
    assert status == 0, err
    assert json.loads(out)["storage"] == "postgresql://krl:***@db.example/krl_studies"
    assert study_cli(capsys, *argv, "--report")[0] == 0
    report = (tmp_path / "s" / "report" / "state-space.md").read_text()
    assert "--storage postgresql://krl:***@db.example/krl_studies" in report and "secret" not in report


@pytest.mark.parametrize(
    ("url", "shown"),
    [
        ("postgresql://krl:Top/secret@db.example/x", "postgresql://krl:***@db.example/x"),
        ("postgresql://krl@db.example/x?password=secret", "postgresql://krl@db.example/x?password=***"),
    ],
)
def test_a_password_with_a_slash_or_as_a_parameter_is_masked_in_the_status_and_the_report(
    tmp_path, capsys, as_sqlite, url, shown
):
    argv = ["state-space", "--out", str(tmp_path / "s"), "--storage", url, "--seeds", "7"]
    argv += ["--budget", "400", "--workers", "1", "--jobs", "1", "--quiet", "--json"]
    status, out, err = study_cli(capsys, *argv)
    assert status == 0, err
    assert json.loads(out)["storage"] == shown
    status, out, _ = study_cli(capsys, *argv, "--report")
    assert status == 0 and "secret" not in out
    report = (tmp_path / "s" / "report" / "state-space.md").read_text()
    assert shown in report and "secret" not in report


def test_json_without_quiet_is_json_alone_on_stdout_and_the_progress_goes_to_stderr(
    tmp_path, capsys, as_sqlite
):
    argv = ["state-space", "--out", str(tmp_path / "s"), "--storage", POSTGRES, "--seeds", "7"]
    status, out, err = study_cli(capsys, *argv, "--budget", "400", "--workers", "1", "--jobs", "1", "--json")
    assert status == 0, err
    assert json.loads(out)["list"]["finished"] == 8
    assert "targets reached" in err  # a line per trial, where it does not break the JSON
