"""Training uses the machine it is given: one worker per usable core unless told, PPO's update on CUDA
when PyTorch sees a device; both recorded in run.json and the policy's metadata."""

from __future__ import annotations

import json
from dataclasses import replace

import pytest

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
    monkeypatch.setattr(training, "usable_cores", lambda: 1)
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
