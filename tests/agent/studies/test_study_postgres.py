"""Many machines on one study: two ``krl agent study`` processes against one PostgreSQL study (tiny real
trainings), one of them SIGKILLed while it trains. Every entry is trained to completion exactly once, the
killed trial is retried by the other process, and the report sees them all.

Needs a server: ``.ci/run`` starts one (``.ci/start-postgres``) and exports ``KRL_TEST_POSTGRES_URL``;
without it the test is skipped."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
import uuid

import pytest
from agent_fakes import TINY_STUDY

URL = os.environ.get("KRL_TEST_POSTGRES_URL")
pytestmark = pytest.mark.skipif(URL is None, reason="no PostgreSQL server (KRL_TEST_POSTGRES_URL unset)")


def study_argv(tmp_path, out: str, url: str) -> list[str]:
    argv = [sys.executable, "-m", "krl.cli", "agent", "study", "ppo-search", "--out", str(tmp_path / out)]
    argv += ["--storage", url, "--trials", "3", "--top", "1", "--seeds", "7", "--budget", "2048"]
    argv += ["--confirm-budget", "256", "--config", str(tmp_path / "tiny.json"), "--workers", "1"]
    return [*argv, "--jobs", "1", "--heartbeat", "1", "--quiet", "--json"]


STAGES = ("ppo-search", "ppo-search:confirm")
"""The Optuna studies of the search and of its confirming runs."""


def running_trial(url: str, process: subprocess.Popen) -> tuple[str, int] | None:
    """``(stage, trial number)`` of a trial ``process`` is training now, or None."""
    import optuna

    for stage in STAGES:
        try:
            study = optuna.load_study(study_name=stage, storage=url)
        except KeyError:  # not created yet
            continue
        for trial in study.get_trials(states=(optuna.trial.TrialState.RUNNING,)):
            if trial.user_attrs.get("worker", "").endswith(f":{process.pid}"):
                return stage, trial.number
    return None


def wait_for_trial(url: str, process: subprocess.Popen, seconds: float = 300) -> tuple[str, int]:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline and process.poll() is None:
        found = running_trial(url, process)
        if found is not None:
            return found
        time.sleep(0.1)
    raise AssertionError(f"process {process.pid} ran no trial (exit status {process.poll()})")


def test_two_processes_share_one_postgres_study_and_a_killed_ones_trial_is_retried(tmp_path):
    import optuna
    import sqlalchemy

    database = f"krl_{uuid.uuid4().hex[:12]}"  # a fresh database per run
    with sqlalchemy.create_engine(URL, isolation_level="AUTOCOMMIT").connect() as connection:
        connection.execute(sqlalchemy.text(f"CREATE DATABASE {database}"))
    url = URL.rsplit("/", 1)[0] + "/" + database
    (tmp_path / "tiny.json").write_text(json.dumps(TINY_STUDY))
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "osmesa")}
    first = subprocess.Popen(study_argv(tmp_path, "a", url), env=env, stdout=subprocess.PIPE, text=True)
    wait_for_trial(url, first)
    second = subprocess.Popen(study_argv(tmp_path, "b", url), env=env, stdout=subprocess.PIPE, text=True)
    wait_for_trial(url, second)  # both now train trials of one study
    stage, victim = wait_for_trial(url, first)
    os.kill(first.pid, signal.SIGKILL)
    first.wait()
    out, _ = second.communicate(timeout=600)
    assert second.returncode == 0
    status = json.loads(out)
    assert status["search"]["finished"] == 3 and status["confirm"]["missing"] == 0
    for name in STAGES:
        trials = optuna.load_study(study_name=name, storage=url).get_trials()
        done = [t for t in trials if t.state.name == "COMPLETE"]
        entries = [t.user_attrs.get("key", t.system_attrs.get("failed_trial", t.number)) for t in done]
        assert len(entries) == len(set(entries)) == (3 if name == STAGES[0] else 1)  # each entry once
        if name == stage:
            killed = next(t for t in trials if t.number == victim)
            retried = [t for t in done if t.system_attrs.get("failed_trial") == victim]
            assert killed.state.name == "FAIL" and len(retried) == 1  # failed by the heartbeat, then retried
