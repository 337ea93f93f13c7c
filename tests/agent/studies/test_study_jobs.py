"""SIGTERM of a ``krl agent study`` running two jobs (tiny real trainings, SQLite): both jobs stop, and
their trials are checkpointed and queued again, none left running, and no job prints a traceback."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

from agent_fakes import TINY_STUDY


def test_sigterm_stops_every_job_and_queues_their_trials_again(tmp_path):
    import optuna

    (tmp_path / "tiny.json").write_text(json.dumps(TINY_STUDY))
    argv = [sys.executable, "-m", "krl.cli", "agent", "study", "ppo-search", "--out", str(tmp_path / "s")]
    argv += ["--trials", "2", "--seeds", "7", "--budget", "10000000", "--config", str(tmp_path / "tiny.json")]
    argv += ["--workers", "1", "--jobs", "2", "--quiet"]
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "osmesa")}
    study = subprocess.Popen(argv, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    url = f"sqlite:///{tmp_path / 's' / 'study.db'}"
    deadline, workers = time.monotonic() + 300, set()
    while len(workers) < 2 and time.monotonic() < deadline and study.poll() is None:
        time.sleep(0.5)
        try:
            trials = optuna.load_study(study_name="ppo-search", storage=url).get_trials()
        except Exception:  # not created yet, or the database is locked for a moment
            continue
        workers = {
            t.user_attrs["worker"] for t in trials if t.state.name == "RUNNING" and "worker" in t.user_attrs
        }
    if len(workers) < 2:  # say why: what the study and its jobs printed
        study.kill()
        printed = study.communicate()[1]
        raise AssertionError(f"running trials of {sorted(workers)} only; the study printed: {printed}")
    time.sleep(3)  # both inside their trainings
    study.send_signal(signal.SIGTERM)
    assert study.wait(timeout=180) != 0
    assert "Traceback" not in study.stderr.read()  # the spawned job stops as quietly as the parent
    for worker in workers:  # the spawned job is gone too
        pid = int(worker.rsplit(":", 1)[1])
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            continue
        raise AssertionError(f"job {pid} outlived the study's SIGTERM")
    trials = optuna.load_study(study_name="ppo-search", storage=url).get_trials()
    assert not [t for t in trials if t.state.name == "RUNNING"]
    assert len([t for t in trials if t.state.name == "WAITING"]) == 2  # both queued again
