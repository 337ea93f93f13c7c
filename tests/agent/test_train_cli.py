"""``krl agent train`` refusals: one line on stderr, exit status 2, nothing written; a resume without
``--config`` continues with the run's stored config."""

from __future__ import annotations

import hashlib
import json
from dataclasses import replace
from pathlib import Path

import pytest

from krl.agent.config import AgentConfig
from krl.agent.policy import load_policy
from krl.cli import main


def _snapshot(folder: Path) -> dict[str, str]:
    """SHA-256 of every file under ``folder`` by relative path (empty when it does not exist)."""
    if not folder.exists():
        return {}
    return {
        str(path.relative_to(folder)): hashlib.sha256(path.read_bytes()).hexdigest()
        for path in sorted(folder.rglob("*"))
        if path.is_file()
    }


def _config_file(folder: Path, config: AgentConfig, name: str = "config.json") -> Path:
    path = folder / name
    path.write_text(json.dumps(config.to_json()))
    return path


def _refused(capsys, argv: list[str], folder: Path, message: str) -> None:
    """``krl agent train ARGV`` exits 2 with one line naming ``message`` and leaves ``folder`` as it was."""
    before = _snapshot(folder)
    assert main(["agent", "train", "--quiet", *argv]) == 2
    error = capsys.readouterr().err
    assert error.startswith("krl: error: ") and error.count("\n") == 1, error
    assert message in error
    assert _snapshot(folder) == before


def test_training_errors_are_one_line_and_write_nothing(tmp_path, small_config, capsys):
    run = tmp_path / "run"
    config = _config_file(tmp_path, small_config)
    assert main(["agent", "train", "--out", str(run), "--seed", "1", "--config", str(config), "--quiet"]) == 0
    capsys.readouterr()
    fresh = tmp_path / "fresh"
    _refused(capsys, ["--out", str(fresh), "--init-from", str(tmp_path)], fresh, "not a run folder")
    _refused(capsys, ["--out", str(run), "--seed", "2", "--steps", "768"], run, "seed 1, not 2")
    pushes = replace(small_config, env=replace(small_config.env, push_magnitude=(100.0, 500.0)))
    other = _config_file(tmp_path, pushes, "other.json")
    _refused(capsys, ["--out", str(run), "--config", str(other), "--steps", "768"], run, "another config")
    (tmp_path / "kernel.json").write_text('{"residual": {"kernel": "nosuchkernel"}}')
    argv = ["--out", str(fresh), "--config", str(tmp_path / "kernel.json")]
    _refused(capsys, argv, fresh, "nosuchkernel")
    for model in (run / "checkpoints").glob("*/model.zip"):  # both it keeps: none to resume from
        model.write_bytes(model.read_bytes()[:1000])
    _refused(capsys, ["--out", str(run), "--steps", "768"], run, "corrupt")


@pytest.mark.parametrize("steps", ["0", "-5"])
def test_steps_below_one_are_refused(tmp_path, small_config, capsys, steps):
    config = _config_file(tmp_path, small_config)
    out = tmp_path / "run"
    _refused(capsys, ["--out", str(out), "--config", str(config), "--steps", steps], out, "--steps")


def test_update_threads_below_one_are_refused(tmp_path, small_config, capsys):
    config = _config_file(tmp_path, small_config)
    out = tmp_path / "run"
    _refused(
        capsys, ["--out", str(out), "--config", str(config), "--update-threads", "0"], out, "--update-threads"
    )


def test_a_resume_without_config_uses_the_stored_one_and_may_change_the_workers(
    tmp_path, small_config, capsys
):
    run = tmp_path / "run"
    config = _config_file(tmp_path, small_config)
    assert main(["agent", "train", "--out", str(run), "--seed", "1", "--config", str(config), "--quiet"]) == 0
    stored = (run / "config.json").read_text()
    capsys.readouterr()
    assert main(["agent", "train", "--out", str(run), "--workers", "2", "--steps", "768", "--quiet"]) == 0
    assert capsys.readouterr().out.startswith(f"resuming {run} from 00000000512")
    assert (run / "config.json").read_text() == stored  # the run's config is the one it started with
    training = load_policy(run / "policy.npz").metadata["training"]
    assert (training["workers"], training["num_envs"], training["env_steps"]) == (2, 2, 768)
    assert main(["agent", "train", "--out", str(run), "--steps", "1024", "--quiet", "--json"]) == 0
    printed = capsys.readouterr()
    assert json.loads(printed.out)["env_steps"] == 1024  # --json prints JSON alone; the note goes to stderr
    assert printed.err.startswith(f"resuming {run} from 00000000768")
    _refused(capsys, ["--out", str(run), "--num-envs", "3", "--steps", "1024"], run, "num_envs")


def test_a_folder_of_other_files_is_refused_and_left_as_it_was(tmp_path, small_config, capsys):
    config = _config_file(tmp_path, small_config)
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "policy.npz").write_bytes(b"the user's own policy")
    (mine / "progress.csv").write_text("the user's own log\n")
    _refused(capsys, ["--out", str(mine), "--config", str(config)], mine, "not a run folder")
    a_file = tmp_path / "a-file"
    a_file.write_text("not a folder")
    _refused(capsys, ["--out", str(a_file), "--config", str(config)], tmp_path, "not a run folder")


@pytest.mark.parametrize("seed", ["-1", str(2**32)])
def test_a_seed_numpy_cannot_take_is_refused_before_anything_is_written(tmp_path, small_config, capsys, seed):
    config = _config_file(tmp_path, small_config)
    out = tmp_path / "run"
    _refused(capsys, ["--out", str(out), "--config", str(config), "--seed", seed], out, f"got {seed}")
    assert not out.exists()  # so that the same folder takes a valid seed next
