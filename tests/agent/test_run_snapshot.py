"""``krl agent snapshot``: a run folder copied without TensorBoard's events, kept in step with the run, and
resumed from the copy; bad input refused in one line before anything is written."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from krl.agent.run_folder import snapshot_runs
from krl.agent.train import train
from krl.cli import main


def _fake_run(folder: Path, checkpoints: tuple[str, ...]) -> Path:
    """A run folder's files as krl agent train leaves them (contents stand-ins)."""
    (folder / "checkpoints").mkdir(parents=True, exist_ok=True)
    for name in ("config.json", "run.json", "progress.csv", "policy.npz", "events.out.tfevents.1.vm.2.0"):
        (folder / name).write_text(name)
    for step in checkpoints:
        (folder / "checkpoints" / step).mkdir(exist_ok=True)
        (folder / "checkpoints" / step / "state.json").write_text(step)
    (folder / "checkpoints" / "latest").write_text(checkpoints[-1])
    return folder


def _files(folder: Path) -> set[str]:
    return {str(path.relative_to(folder)) for path in folder.rglob("*") if path.is_file()}


def test_a_snapshot_leaves_out_the_events_and_follows_the_run(tmp_path):
    run = _fake_run(tmp_path / "runs" / "arm-seed150", ("00001", "00002"))
    result = snapshot_runs([run], tmp_path / "committed")
    copy = tmp_path / "committed" / "arm-seed150"
    assert result["runs"] == [str(copy)]
    assert _files(copy) == _files(run) - {"events.out.tfevents.1.vm.2.0"}
    assert result["bytes"] == sum((run / name).stat().st_size for name in _files(copy))
    shutil.rmtree(run / "checkpoints" / "00001")  # the run trains on: its oldest checkpoint goes
    _fake_run(run, ("00002", "00003"))
    snapshot_runs([run], tmp_path / "committed")
    assert sorted(p.name for p in (copy / "checkpoints").iterdir()) == ["00002", "00003", "latest"]
    assert (copy / "checkpoints" / "latest").read_text() == "00003"


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        (["runs/none", "--out", "committed"], "runs/none is not a run folder of krl agent train"),
        (["runs/a/x", "runs/b/x", "--out", "committed"], "two runs are named x"),
        (["runs/a/x", "--out", "runs/a/x/inside"], "lies in the run runs/a/x"),
        (["runs/a/x", "--out", "runs/a"], "already holds the run runs/a/x itself"),
    ],
)
def test_bad_input_is_refused_in_one_line_before_anything_is_written(
    tmp_path, monkeypatch, capsys, arguments, message
):
    monkeypatch.chdir(tmp_path)
    for run in ("runs/a/x", "runs/b/x"):
        _fake_run(tmp_path / run, ("00001",))
    before = {path: path.read_bytes() for path in tmp_path.rglob("*") if path.is_file()}
    assert main(["agent", "snapshot", *arguments]) == 2
    error = capsys.readouterr().err.strip()
    assert message in error and "\n" not in error
    assert {path: path.read_bytes() for path in tmp_path.rglob("*") if path.is_file()} == before


def test_a_run_resumes_from_its_snapshot(tmp_path, small_config):
    """A tiny training stops at its first checkpoint; its snapshot, in another runs folder, trains on from
    that checkpoint there."""
    run = tmp_path / "here" / "tiny-seed3"
    train(run, small_config, seed=3, total_steps=256, progress=False, log=lambda _: None)
    assert main(["agent", "snapshot", str(run), "--out", str(tmp_path / "there"), "--json"]) == 0
    copy = tmp_path / "there" / "tiny-seed3"
    assert not list(copy.glob("events.out*")) and list(run.glob("events.out*"))
    messages: list[str] = []
    summary = train(copy, total_steps=512, progress=False, log=messages.append)
    assert messages == [f"resuming {copy} from 00000000256 (256 env steps)"]
    assert summary["env_steps"] == 512
