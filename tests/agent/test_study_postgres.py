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
    argv += ["--storage", url, "--trials", "3", "--top", "1", "--seeds", "7", "--budget", "1024"]
    argv += ["--confirm-budget", "256", "--config", str(tmp_path / "tiny.json"), "--workers", "1"]
    return [*argv, "--jobs", "1", "--heartbeat", "1", "--quiet", "--json"]


def running_workers(url: str) -> dict[int, str]:
    """``{trial number: worker}`` of the search's running trials."""
    import optuna

    try:
        study = optuna.load_study(study_name="ppo-search", storage=url)
    except KeyError:  # not created yet
        return {}
    return {
        t.number: t.user_attrs["worker"]
        for t in study.get_trials(states=(optuna.trial.TrialState.RUNNING,))
        if "worker" in t.user_attrs
    }


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
    second = subprocess.Popen(study_argv(tmp_path, "b", url), env=env, stdout=subprocess.PIPE, text=True)
    victim = None
    deadline = time.monotonic() + 300
    while victim is None and time.monotonic() < deadline:
        workers = running_workers(url) if first.poll() is None else {}
        victim = next((n for n, w in workers.items() if w.endswith(f":{first.pid}")), None)
        time.sleep(0.2)
    assert victim is not None, "the first process never ran a trial"
    os.kill(first.pid, signal.SIGKILL)
    first.wait()
    out, _ = second.communicate(timeout=600)
    assert second.returncode == 0
    status = json.loads(out)
    assert status["search"]["finished"] == 3 and status["confirm"]["missing"] == 0
    search = optuna.load_study(study_name="ppo-search", storage=url).get_trials()
    done = [t for t in search if t.state.name == "COMPLETE"]
    names = [t.system_attrs.get("failed_trial", t.number) for t in done]
    assert len(names) == len(set(names)) == 3  # each entry completed once
    killed = next(t for t in search if t.number == victim)
    assert killed.state.name == "FAIL" and victim in names  # failed by the heartbeat, then retried
