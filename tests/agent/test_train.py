"""PPO training: a tiny run, its files, resumption from the checkpoint, refused mismatches."""

from __future__ import annotations

import json
from dataclasses import replace

import pytest

from krl.agent.config import AgentConfig
from krl.agent.policy import load_policy
from krl.agent.train import TrainingError, train


def test_tiny_run_writes_policy_and_resumes_from_its_checkpoint(tmp_path, small_config):
    out = tmp_path / "run"
    summary = train(out, small_config, seed=3, total_steps=256, progress=False, log=lambda _: None)
    assert summary["env_steps"] == 256
    assert (out / "checkpoints" / "latest").read_text().strip() == "00000000256"
    assert json.loads((out / "run.json").read_text())["seed"] == 3
    policy = load_policy(out / "policy.npz")
    assert policy.metadata["training"]["env_steps"] == 256
    assert policy.metadata["training"]["seed"] == 3
    run = json.loads((out / "run.json").read_text())
    run["kernel_path"] = str(tmp_path / "elsewhere" / "kernel.npz")  # the folder moved to another machine
    (out / "run.json").write_text(json.dumps(run))
    messages: list[str] = []
    summary = train(out, total_steps=512, progress=False, log=messages.append)
    assert summary["env_steps"] == 512
    assert messages == [f"resuming {out} from 00000000256 (256 env steps)"]
    from krl.agent.curves import read_progress

    kept = (out / "progress.00000000256.csv").read_text()  # the log before the resumption is kept
    assert "time/total_timesteps" in kept and "256" in kept
    read_progress(out)
    assert load_policy(out / "policy.npz").metadata["training"]["env_steps"] == 512
    messages.clear()
    train(out, total_steps=512, progress=False, log=messages.append)
    assert "nothing to do" in messages[0]


def test_a_run_folder_refuses_another_config_or_seed(tmp_path, small_config):
    out = tmp_path / "run"
    train(out, small_config, seed=1, total_steps=256, progress=False, log=lambda _: None)
    with pytest.raises(TrainingError, match="another config"):
        train(out, replace(small_config, num_envs=3), total_steps=512, progress=False)
    with pytest.raises(TrainingError, match="seed 1, not 2"):
        train(out, seed=2, total_steps=512, progress=False)


def test_a_run_can_start_from_another_runs_checkpoint(tmp_path, small_config):
    first = tmp_path / "first"
    train(first, small_config, seed=1, total_steps=256, progress=False, log=lambda _: None)
    # fine-tuning under other pushes; a zero learning rate keeps the weights it started from
    harder = replace(
        small_config,
        env=replace(small_config.env, push_magnitude=(100.0, 500.0)),
        ppo=replace(small_config.ppo, learning_rate=0.0),
    )
    second = tmp_path / "second"
    messages: list[str] = []
    train(second, harder, seed=2, total_steps=256, progress=False, log=messages.append, init_from=first)
    assert messages == [f"starting {second} from {first} (256 env steps)"]
    start = json.loads((second / "run.json").read_text())["initialized_from"]
    assert (start["run"], start["checkpoint"], start["env_steps"]) == (str(first), "00000000256", 256)
    theirs, mine = load_policy(first / "policy.npz"), load_policy(second / "policy.npz")
    assert mine.metadata["training"]["initialized_from"]["env_steps"] == 256
    for (w_theirs, b_theirs), (w_mine, b_mine) in zip(theirs.layers, mine.layers, strict=True):
        assert (w_theirs == w_mine).all() and (b_theirs == b_mine).all()
    other = replace(small_config, observation=replace(small_config.observation, features=("joint_pos",)))
    with pytest.raises(TrainingError, match=r"its observation is .*, this run's is") as caught:
        train(tmp_path / "third", other, total_steps=256, progress=False, init_from=first)
    assert "\n" not in str(caught.value) and not (tmp_path / "third").exists()
    with pytest.raises(TrainingError, match="not a run folder"):
        train(tmp_path / "fourth", small_config, total_steps=256, progress=False, init_from=tmp_path / "none")


def test_a_corrupt_checkpoint_is_a_one_line_error(tmp_path, small_config):
    out = tmp_path / "run"
    train(out, small_config, seed=1, total_steps=256, progress=False, log=lambda _: None)
    (out / "checkpoints" / "00000000256" / "model.zip").write_bytes(b"not a zip")
    with pytest.raises(TrainingError, match="corrupt") as caught:
        train(out, total_steps=512, progress=False, log=lambda _: None)
    assert "\n" not in str(caught.value)


def test_defaults_are_the_thesis_trial_3():
    ppo = AgentConfig().ppo
    assert (ppo.learning_rate, ppo.batch_size, ppo.n_epochs, ppo.rollout_steps, ppo.ent_coef) == (
        1e-3,
        4000,
        10,
        200_000,
        5e-6,
    )
    assert (ppo.shared, ppo.actor, ppo.critic) == ((128, 128), (128,), (64,))
    assert ppo.learning_rate_at(0) == 1e-3
    assert ppo.learning_rate_at(3e6) == ppo.learning_rate_at(1.9e7) == pytest.approx(1e-3 * (1 - 3e6 / 2e7))


def _children(pid: int) -> list[int]:
    try:
        text = open(f"/proc/{pid}/task/{pid}/children").read()
    except OSError:
        return []
    return [int(child) for child in text.split()]


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as handle:
            return handle.read().split(") ")[-1][0] != "Z"
    except OSError:
        return False


def test_kill_9_of_training_leaves_no_worker_and_resumes_from_the_checkpoint(tmp_path, small_config):
    import os
    import signal
    import subprocess
    import sys
    import time

    out = tmp_path / "run"
    config = replace(small_config, total_steps=1_000_000)
    (tmp_path / "config.json").write_text(json.dumps(config.to_json()))
    code = (
        "import sys; from krl.agent.config import AgentConfig; from krl.agent.train import train\n"
        f"train({str(out)!r}, AgentConfig.load({str(tmp_path / 'config.json')!r}), seed=4, progress=False)\n"
    )
    process = subprocess.Popen([sys.executable, "-c", code])
    try:
        deadline = time.monotonic() + 120
        while not (out / "checkpoints" / "latest").is_file():
            assert time.monotonic() < deadline and process.poll() is None, "no checkpoint was written"
            time.sleep(0.2)
        workers = _children(process.pid)
        assert workers, "the training has no worker process"
    finally:
        os.kill(process.pid, signal.SIGKILL)
        process.wait()
    deadline = time.monotonic() + 5
    while any(_alive(pid) for pid in workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(_alive(pid) for pid in workers), "a worker outlived its parent's kill -9"
    kept = int((out / "checkpoints" / "latest").read_text())
    messages: list[str] = []
    summary = train(out, total_steps=kept + 256, progress=False, log=messages.append)
    assert messages[0].startswith(f"resuming {out} from {kept:011d}")
    assert summary["env_steps"] == kept + 256


def test_sigterm_saves_a_checkpoint_and_stops_the_workers(tmp_path, small_config):
    import signal
    import subprocess
    import sys
    import time

    out = tmp_path / "run"
    (tmp_path / "config.json").write_text(json.dumps(replace(small_config, total_steps=1_000_000).to_json()))
    command = [sys.executable, "-m", "krl.cli", "agent", "train", "--out", str(out), "--quiet"]
    command += ["--config", str(tmp_path / "config.json")]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while not (out / "checkpoints" / "latest").is_file():
        assert time.monotonic() < deadline and process.poll() is None, "no checkpoint was written"
        time.sleep(0.2)
    time.sleep(1.0)
    workers = _children(process.pid)
    process.send_signal(signal.SIGTERM)
    printed, error = process.communicate(timeout=60)
    assert process.returncode == 143, error  # 128 + SIGTERM
    assert "interrupted: saved" in printed and error == "krl: interrupted\n"
    deadline = time.monotonic() + 5
    while any(_alive(pid) for pid in workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(_alive(pid) for pid in workers)
    kept = int((out / "checkpoints" / "latest").read_text())
    assert load_policy(out / "policy.npz").metadata["training"]["env_steps"] == kept


def test_same_seed_same_policy(tmp_path, small_config):
    import numpy as np

    policies = []
    for name in ("a", "b"):
        train(tmp_path / name, small_config, seed=9, total_steps=256, progress=False, log=lambda _: None)
        policies.append(load_policy(tmp_path / name / "policy.npz"))
    for (w1, b1), (w2, b2) in zip(policies[0].layers, policies[1].layers, strict=True):
        np.testing.assert_array_equal(w1, w2)
        np.testing.assert_array_equal(b1, b2)
    np.testing.assert_array_equal(policies[0].obs_mean, policies[1].obs_mean)


def test_a_sigterm_a_finaliser_swallowed_still_stops_training(tmp_path, small_config, monkeypatch):
    """A study job trained on after its SIGTERM: the handler's exception was raised inside a finaliser
    (SQLAlchemy's) during a garbage collection, where Python swallows it; the next env step stops, and
    nothing is reported of the swallowed exception (no "Exception ignored in ..." traceback)."""
    import os
    import signal
    import sys

    from krl.util.parallel import Interrupted, signals_raise

    class SignalledWhileCollected:
        def __del__(self) -> None:
            os.kill(os.getpid(), signal.SIGTERM)

    swallowed = []
    monkeypatch.setattr(sys, "unraisablehook", lambda unraisable: swallowed.append(unraisable.exc_type))
    config = replace(small_config, total_steps=100_000)
    with pytest.raises(Interrupted), signals_raise():
        SignalledWhileCollected()  # collected at once: the stop is lost before training starts
        train(tmp_path / "run", config, seed=3, progress=False, log=lambda _: None)
    assert swallowed == []
    assert int((tmp_path / "run" / "checkpoints" / "latest").read_text()) <= config.num_envs  # its first step


def test_a_goal_within_a_rollout_says_it_trains_the_whole_rollout(tmp_path, small_config):
    """Issue 61: ``--steps 2000`` trained a whole rollout of 200 000 env steps without a word."""
    messages: list[str] = []
    out = tmp_path / "run"
    summary = train(out, small_config, seed=1, total_steps=300, progress=False, log=messages.append)
    assert messages == ["PPO trains whole rollouts of 256 env steps: this sitting trains to 512, not 300"]
    assert summary["env_steps"] == 512


def test_a_run_resumes_with_a_config_that_names_no_worker_count(tmp_path, small_config):
    """A recipe file without ``workers`` (a new run resolves it to one per usable core) resumes the same way:
    the second sitting of such a run failed with a TypeError on ``None * num_envs``."""
    out = tmp_path / "run"
    recipe = replace(small_config, workers=None)
    train(out, recipe, seed=3, total_steps=256, progress=False, log=lambda _: None)
    summary = train(out, recipe, seed=3, total_steps=512, progress=False, log=lambda _: None)
    assert summary["env_steps"] == 512
