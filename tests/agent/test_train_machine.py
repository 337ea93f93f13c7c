"""Training uses the machine it is given: one worker per usable core unless told, PPO's update on CUDA
when PyTorch sees a device (both recorded in run.json and the policy's metadata), and on one CPU thread
unless told (recorded in the policy's metadata)."""

from __future__ import annotations

import json
from dataclasses import replace

import pytest

from krl.agent import run_folder
from krl.agent import train as training
from krl.agent.policy import load_policy
from krl.agent.train import TrainingError, train, training_device


@pytest.mark.parametrize(
    ("asked", "cuda", "device"),
    [("auto", False, "cpu"), ("auto", True, "cuda"), ("cpu", True, "cpu"), ("cuda", True, "cuda")],
)
def test_the_device_follows_what_pytorch_sees(monkeypatch, asked, cuda, device):
    monkeypatch.setattr(training.torch.cuda, "is_available", lambda: cuda)
    assert training_device(asked) == device


def test_cuda_where_there_is_none_and_unknown_devices_are_one_line_errors(monkeypatch):
    monkeypatch.setattr(training.torch.cuda, "is_available", lambda: False)
    with pytest.raises(TrainingError, match="PyTorch sees no CUDA device"):
        training_device("cuda")
    with pytest.raises(TrainingError, match="unknown device 'tpu'"):
        training_device("tpu")


def test_a_run_takes_one_worker_per_usable_core_and_records_it(tmp_path, small_config, monkeypatch):
    monkeypatch.setattr(run_folder, "usable_cores", lambda: 1)
    monkeypatch.setattr(training.torch.cuda, "is_available", lambda: False)
    out = tmp_path / "run"
    train(
        out, replace(small_config, workers=None), seed=3, total_steps=256, progress=False, log=lambda _: None
    )
    run = json.loads((out / "run.json").read_text())
    assert (run["workers"], run["device"]) == (1, "cpu")
    assert json.loads((out / "config.json").read_text())["workers"] == 1  # resolved, so a resume keeps it
    training_record = load_policy(out / "policy.npz").metadata["training"]
    assert (training_record["workers"], training_record["device"]) == (1, "cpu")


def test_ppo_updates_on_its_update_threads_and_collects_on_one(monkeypatch):
    seen = []
    monkeypatch.setattr(training.PPO, "train", lambda self: seen.append(training.torch.get_num_threads()))
    model = training.ThreadedPPO.__new__(training.ThreadedPPO)  # the thread switch needs no network
    training.torch.set_num_threads(1)
    for threads in (1, 2):
        model.update_threads = threads
        model.train()
        assert training.torch.get_num_threads() == 1
    assert seen == [1, 2]


def test_update_threads_below_one_are_a_one_line_error_that_writes_nothing(tmp_path, small_config):
    with pytest.raises(TrainingError, match="update_threads must be at least 1, got 0"):
        train(tmp_path / "run", small_config, total_steps=256, progress=False, update_threads=0)
    assert not (tmp_path / "run").exists()


def test_the_policy_records_the_update_threads_of_its_sitting(tmp_path, small_config, monkeypatch):
    monkeypatch.setattr(training.torch.cuda, "is_available", lambda: False)
    out = tmp_path / "run"
    train(out, small_config, seed=3, total_steps=256, progress=False, log=lambda _: None, update_threads=2)
    assert load_policy(out / "policy.npz").metadata["training"]["update_threads"] == 2
