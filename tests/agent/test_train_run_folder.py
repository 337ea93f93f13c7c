"""What a run folder holds and how it is read back: no pickle from a run folder runs code, committed runs
(whose normaliser is a pickle) still load, and a resumption's log holds every env step once."""

from __future__ import annotations

import base64
import csv
import json
import pickle
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest

from krl.agent.policy import load_policy
from krl.agent.train import TrainingError, train

COMMITTED = Path(__file__).resolve().parents[2] / "training" / "agent-rp-seed215"
"""A committed run folder of krl's first checkpoint format (``normaliser.pkl``)."""


class _Payload:
    """A pickle that creates the file ``marker`` when unpickled (as a malicious file would run code)."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return (open, (str(self.marker), "w"))


def _checkpoint(run: Path) -> Path:
    return run / "checkpoints" / (run / "checkpoints" / "latest").read_text().strip()


def _rewrite_model_data(model: Path, name: str, payload: bytes) -> None:
    """Replace the field ``name`` of an SB3 archive's ``data`` by a cloudpickled ``payload``."""
    with zipfile.ZipFile(model) as archive:
        entries = {entry: archive.read(entry) for entry in archive.namelist()}
    data = json.loads(entries["data"])
    data[name] = {":type:": "<class 'object'>", ":serialized:": base64.b64encode(payload).decode()}
    entries["data"] = json.dumps(data).encode()
    with zipfile.ZipFile(model, "w") as archive:
        for entry, content in entries.items():
            archive.writestr(entry, content)


def test_a_crafted_normaliser_pickle_runs_nothing_on_init_from(tmp_path, small_config):
    first = tmp_path / "first"
    train(first, small_config, seed=1, total_steps=256, progress=False, log=lambda _: None)
    checkpoint = _checkpoint(first)
    (checkpoint / "normaliser.npz").unlink(missing_ok=True)
    marker = tmp_path / "ran"
    (checkpoint / "normaliser.pkl").write_bytes(pickle.dumps(_Payload(marker)))
    with pytest.raises(TrainingError) as caught:
        train(tmp_path / "second", small_config, total_steps=256, progress=False, init_from=first)
    assert not marker.exists()
    assert "refers to io.open" in str(caught.value) and "\n" not in str(caught.value)


def test_a_crafted_model_archive_runs_nothing_on_resume(tmp_path, small_config):
    out = tmp_path / "run"
    train(out, small_config, seed=1, total_steps=256, progress=False, log=lambda _: None)
    marker = tmp_path / "ran"
    model = _checkpoint(out) / "model.zip"
    _rewrite_model_data(model, "observation_space", pickle.dumps(_Payload(marker)))
    train(out, total_steps=512, progress=False, log=lambda _: None)  # a field krl does not need: unread
    assert not marker.exists()
    for model in (out / "checkpoints").glob("*/model.zip"):  # both it keeps: none to resume from
        _rewrite_model_data(model, "ep_info_buffer", pickle.dumps(_Payload(marker)))
    with pytest.raises(TrainingError) as caught:
        train(out, total_steps=768, progress=False, log=lambda _: None)
    assert not marker.exists()
    assert "refers to io.open" in str(caught.value) and "\n" not in str(caught.value)


def test_checkpoints_hold_no_pickle_of_krl(tmp_path, small_config):
    out = tmp_path / "run"
    train(out, small_config, seed=1, total_steps=256, progress=False, log=lambda _: None)
    names = sorted(path.name for path in _checkpoint(out).iterdir())
    assert names == ["model.zip", "normaliser.npz", "state.json"]
    with np.load(_checkpoint(out) / "normaliser.npz", allow_pickle=False) as arrays:
        policy = load_policy(out / "policy.npz")
        np.testing.assert_array_equal(arrays["obs_mean"], policy.obs_mean)
        np.testing.assert_array_equal(arrays["obs_var"], policy.obs_var)


def test_a_committed_checkpoint_is_read_without_unpickling_code():
    from krl.agent.checkpoint import read_checkpoint

    checkpoint = read_checkpoint(_checkpoint(COMMITTED))
    policy = load_policy(COMMITTED / "policy.npz")
    state = checkpoint.normaliser  # from its normaliser.pkl
    np.testing.assert_array_equal(state.obs_mean, policy.obs_mean)
    np.testing.assert_array_equal(state.obs_var, policy.obs_var)
    assert state.obs_count > 2e7 and state.clip_obs == policy.obs_clip
    assert checkpoint.num_timesteps == policy.metadata["training"]["env_steps"]
    assert len(checkpoint.episodes) == 100 and checkpoint.n_updates > 0


def _logged_steps(path: Path) -> list[int]:
    with open(path, newline="") as handle:
        return [int(float(row["time/total_timesteps"])) for row in csv.DictReader(handle)]


def test_a_resume_drops_the_log_rows_past_its_checkpoint(tmp_path, small_config):
    out = tmp_path / "run"
    train(out, small_config, seed=1, total_steps=512, progress=False, log=lambda _: None)
    log = out / "progress.csv"
    with open(log, newline="") as handle:
        rows = list(csv.DictReader(handle))
    # what a kill -9 after a rollout is logged but before its checkpoint is written leaves behind
    with open(log, "a", newline="") as handle:
        csv.DictWriter(handle, fieldnames=list(rows[0])).writerow({**rows[-1], "time/total_timesteps": "768"})
    train(out, total_steps=768, progress=False, log=lambda _: None)
    assert _logged_steps(out / "progress.00000000512.csv") == [256, 512]
    assert _logged_steps(out / "progress.00000000512.csv") + _logged_steps(log) == [256, 512, 768]


def test_every_sitting_records_its_machine_in_the_run_and_the_policy(tmp_path, small_config):
    out = tmp_path / "run"
    train(out, small_config, seed=1, total_steps=256, progress=False, log=lambda _: None)
    train(out, total_steps=512, progress=False, log=lambda _: None)  # resumed
    sittings = json.loads((out / "run.json").read_text())["sittings"]
    assert [sitting["env_steps"] for sitting in sittings] == [0, 256]
    for sitting in sittings:
        assert sitting["machine"]["cpu"] and sitting["machine"]["torch_cpu"] and sitting["software"]["torch"]
        assert sitting["started"].endswith("Z")
    assert load_policy(out / "policy.npz").metadata["training"]["sittings"] == sittings
    train(out, total_steps=512, progress=False, log=lambda _: None)  # nothing to do: no sitting
    assert json.loads((out / "run.json").read_text())["sittings"] == sittings


def _joined_log(run: Path) -> list[int]:
    """The env steps of a run's log segments joined in the order ``krl agent curves`` joins them."""
    return [
        step
        for path in [*sorted(run.glob("progress.*.csv")), run / "progress.csv"]
        for step in _logged_steps(path)
    ]


def _checkpoint_names(run: Path) -> list[str]:
    return sorted(path.name for path in (run / "checkpoints").iterdir() if path.is_dir())


def test_a_run_keeps_two_checkpoints_and_resumes_from_the_newest_readable(tmp_path, small_config):
    """Issue 61, M8: with one checkpoint kept, a damaged one (deleted) sent the run back to step 0, over
    its log, and ``krl agent curves`` drew those env steps twice."""
    out = tmp_path / "run"
    train(out, small_config, seed=1, total_steps=768, progress=False, log=lambda _: None)
    assert _checkpoint_names(out) == ["00000000512", "00000000768"]
    train(out, total_steps=1024, progress=False, log=lambda _: None)  # resumed at 768: a log segment
    assert _checkpoint_names(out) == ["00000000768", "00000001024"]
    (out / "checkpoints" / "00000001024" / "model.zip").write_bytes(b"damaged")
    messages: list[str] = []
    train(out, total_steps=1280, progress=False, log=messages.append)
    assert "00000001024 is corrupt" in messages[0] and "\n" not in messages[0]
    assert messages[1] == f"resuming {out} from 00000000768 (768 env steps)"
    assert _joined_log(out) == [256 * k for k in range(1, 6)]  # each env step once
    assert _checkpoint_names(out) == ["00000001024", "00000001280"]  # the damaged one trained again


def test_a_run_started_again_from_step_0_keeps_no_log_of_the_first_start(tmp_path, small_config):
    out = tmp_path / "run"
    train(out, small_config, seed=1, total_steps=512, progress=False, log=lambda _: None)
    train(out, total_steps=768, progress=False, log=lambda _: None)  # progress.00000000512.csv
    shutil.rmtree(out / "checkpoints")  # what a user does with checkpoints that cannot be read
    train(out, total_steps=768, progress=False, log=lambda _: None)  # from step 0 again
    assert [path.name for path in out.glob("progress*.csv")] == ["progress.csv"]
    assert _joined_log(out) == [256, 512, 768]


def test_a_sitting_from_an_earlier_checkpoint_drops_the_log_segments_past_it(tmp_path, small_config):
    out = tmp_path / "run"
    train(out, small_config, seed=1, total_steps=768, progress=False, log=lambda _: None)
    # what a sitting resumed at 768 and killed before its next checkpoint leaves, with 768 damaged since
    log = out / "progress.csv"
    log.rename(out / "progress.00000000768.csv")
    with open(out / "progress.00000000768.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    with open(log, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerow({**rows[-1], "time/total_timesteps": "1024"})
    (out / "checkpoints" / "00000000768" / "model.zip").write_bytes(b"damaged")
    train(out, total_steps=1024, progress=False, log=lambda _: None)  # from 512
    assert sorted(path.name for path in out.glob("progress*.csv")) == [
        "progress.00000000512.csv",
        "progress.csv",
    ]
    assert _logged_steps(out / "progress.00000000512.csv") == [256, 512]
    assert _logged_steps(log) == [768, 1024]


def test_a_crafted_weights_file_is_refused_without_a_librarys_advice_to_load_it_unsafely(
    tmp_path, small_config
):
    """Issue 61: the error repeated PyTorch's advice to load the file with ``weights_only=False``."""
    import io

    import torch

    from krl.agent.checkpoint import CheckpointError, read_checkpoint

    out = tmp_path / "run"
    train(out, small_config, seed=1, total_steps=256, progress=False, log=lambda _: None)
    model = _checkpoint(out) / "model.zip"
    marker = tmp_path / "ran"
    crafted = io.BytesIO()
    torch.save({"weights": _Payload(marker)}, crafted)
    with zipfile.ZipFile(model) as archive:
        entries = {entry: archive.read(entry) for entry in archive.namelist()}
    entries["policy.pth"] = crafted.getvalue()
    with zipfile.ZipFile(model, "w") as archive:
        for entry, content in entries.items():
            archive.writestr(entry, content)
    with pytest.raises(CheckpointError) as caught:
        read_checkpoint(_checkpoint(out))
    message = str(caught.value)
    assert not marker.exists()
    assert message == f"checkpoint {_checkpoint(out)}: model.zip refers to io.open, which krl refuses to load"
