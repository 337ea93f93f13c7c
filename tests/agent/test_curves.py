"""Seed groups of training curves (Fig. 4.23): mean and spread over runs on a common env-step grid."""

from __future__ import annotations

import csv
import json
import shutil

import numpy as np
from agent_fakes import LOG_COLUMNS

from krl.agent.curves import group_curve
from krl.cli import main

COLUMNS = LOG_COLUMNS


def fake_run(folder, steps, targets, success=None):
    """A run folder whose progress.csv logs ``targets`` (and ``success``, if given) at ``steps``."""
    folder.mkdir(parents=True)
    columns = COLUMNS if success is not None else COLUMNS[:-1]
    with open(folder / "progress.csv", "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(columns)
        for i, step in enumerate(steps):
            row = [step, 100.0, targets[i], 0.2]
            writer.writerow(row + ([success[i]] if success is not None else []))
    return folder


def test_a_group_is_the_mean_and_spread_of_its_runs_on_a_common_grid(tmp_path):
    a = fake_run(tmp_path / "a", [0, 400_000, 800_000], [1.0, 3.0, 5.0], [0.0, 0.5, 1.0])
    b = fake_run(tmp_path / "b", [200_000, 600_000], [2.0, 4.0], [0.2, 0.6])
    curve = group_curve([a, b], "episode/targets_reached")
    # the grid spans the steps every run logs (2e5 to 6e5), every 2e5; a is interpolated linearly
    np.testing.assert_allclose(curve["steps"], [200_000, 400_000, 600_000])
    np.testing.assert_allclose(curve["mean"], [2.0, 3.0, 4.0])
    np.testing.assert_allclose(curve["std"], [0.0, 0.0, 0.0], atol=1e-12)
    success = group_curve([a, b], "episode/success_rate")
    np.testing.assert_allclose(success["mean"], [0.225, 0.45, 0.675])
    np.testing.assert_allclose(success["std"], [0.025, 0.05, 0.075])


def test_runs_shorter_than_a_grid_step_meet_at_their_common_end(tmp_path):
    """Smoke runs (``krl reproduce --quick``'s 8 000 steps) have no grid point: they compare at their end."""
    a = fake_run(tmp_path / "a", [4000, 8000], [1.0, 3.0], [0.0, 0.5])
    b = fake_run(tmp_path / "b", [4000, 6000], [1.0, 2.0], [0.0, 0.25])
    curve = group_curve([a, b], "episode/success_rate")
    np.testing.assert_allclose(curve["steps"], [6000])
    np.testing.assert_allclose(curve["mean"], [0.25])  # a's 0.25 at 6 000 (interpolated) and b's


def test_runs_that_never_logged_a_column_are_left_out(tmp_path):
    old = fake_run(tmp_path / "old", [0, 200_000], [1.0, 2.0])
    new = fake_run(tmp_path / "new", [0, 200_000], [1.0, 4.0], [0.0, 1.0])
    assert group_curve([old, new], "episode/success_rate")["runs"] == 1
    assert group_curve([old, new], "episode/targets_reached")["runs"] == 2
    assert group_curve([old], "episode/success_rate")["runs"] == 0


def test_krl_agent_curves_draws_groups_and_refuses_bad_ones(tmp_path, capsys):
    a = fake_run(tmp_path / "a", [0, 200_000, 400_000], [1.0, 2.0, 3.0], [0.0, 0.5, 1.0])
    b = fake_run(tmp_path / "b", [0, 200_000, 400_000], [2.0, 3.0, 4.0], [0.5, 0.5, 0.5])
    out = tmp_path / "figures"
    out.mkdir()
    assert main(["agent", "curves", "--group", f"agent-rp={a},{b}", "--out", str(out), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["figures"] == [str(out / "seed-groups.png")]
    assert (out / "seed-groups.png").stat().st_size > 0
    group = tmp_path / "agent-base"
    for seed, run in ((150, a), (215, b)):
        shutil.copytree(run, group / f"seed{seed}")
    assert main(["agent", "curves", "--group", f"agent-base={group}", "--out", str(out), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["figures"] == [str(out / "seed-groups.png")]
    for argv, message in (
        (["--out", str(out)], "give run folders, or --group"),
        (["--group", "agent-rp", "--out", str(out)], "expected LABEL=RUN"),
        (["--group", f"x={tmp_path / 'none'}", "--out", str(out)], "no training log"),
    ):
        assert main(["agent", "curves", *argv]) == 2
        error = capsys.readouterr().err
        assert message in error and error.count("\n") == 1


def test_reach_gives_the_steps_each_group_needs_to_reach_the_reference_level(tmp_path, capsys):
    """Issue 45, item 7: the reference ends at 0.6; a faster group reaches it at 2e5 steps, a slower one
    never, and a group trained on other ground is marked so."""
    ref = [fake_run(tmp_path / f"ref{i}", [0, 200_000, 400_000], [1, 2, 3], [0.0, 0.3, 0.6]) for i in (1, 2)]
    fast = fake_run(tmp_path / "fast", [0, 200_000, 400_000], [1, 2, 3], [0.0, 0.7, 0.9])
    slow = fake_run(tmp_path / "slow", [0, 200_000, 400_000], [1, 2, 3], [0.0, 0.1, 0.5])
    other = fake_run(tmp_path / "other", [0, 200_000, 400_000], [1, 2, 3], [0.6, 0.6, 0.6])
    for run in (*ref, fast, slow):
        (run / "config.json").write_text(json.dumps({"env": {"heightfield_probability": 0.5}}))
    (other / "config.json").write_text(json.dumps({"env": {"heightfield_probability": 0.25}}))
    out = tmp_path / "figures"
    groups = [f"ref={ref[0]},{ref[1]}", f"fast={fast}", f"slow={slow}", f"other={other}"]
    argv = ["agent", "curves", *(arg for group in groups for arg in ("--group", group)), "--out", str(out)]
    assert main([*argv, "--reach", "ref", "--json"]) == 0
    rows = {row["label"]: row for row in json.loads(capsys.readouterr().out)["reach"]}
    assert {label: row["steps_to_level"] for label, row in rows.items()} == {
        "ref": 400_000.0,
        "fast": 200_000.0,
        "slow": None,
        "other": 0.0,
    }
    assert rows["ref"]["level"] == 0.6 and rows["ref"]["runs"] == 2
    assert [label for label, row in rows.items() if not row["same_env"]] == ["other"]
    table = (out / "reach.md").read_text()
    assert "| slow | 1 | 0.50 | 0.4 | not reached | same |" in table and "| other |" in table
    assert json.loads((out / "reach.json").read_text())["reference"] == "ref"
    for extra, message in ((["--reach", "nobody"], "--reach 'nobody' is no --group label"),):
        assert main([*argv, *extra]) == 2
        error = capsys.readouterr().err
        assert message in error and error.count("\n") == 1
    assert main(["agent", "curves", str(fast), "--out", str(out), "--reach", "ref"]) == 2
    assert "--reach needs --group" in capsys.readouterr().err


def test_the_log_records_the_rollouts_success_rate():
    from types import SimpleNamespace

    from krl.agent.callbacks import Clock, EpisodeLog

    recorded = {}
    log = EpisodeLog(Clock(0.0))
    log.model = SimpleNamespace(logger=SimpleNamespace(record=recorded.__setitem__), num_timesteps=0)
    episodes = [(2, False), (1, False), (5, True), (3, False)]  # succeed: >= 2 targets and no fall
    log.locals = {
        "infos": [
            {"episode": {"r": 1.0, "l": 200, "targets_reached": n, "fell": fell, "terms": {"fall": 0.0}}}
            for n, fell in episodes
        ]
    }
    log._on_step()
    log._on_rollout_end()
    assert recorded["episode/success_rate"] == 0.5 and recorded["episode/fall_rate"] == 0.25


def test_reach_over_a_window_reads_each_curve_as_its_trailing_mean(tmp_path, capsys):
    """Single rollouts swing: a run that touches the level once, then falls back, reaches it there; read
    over a window of two grid points it reaches the level only where its two-point mean does, and the
    reference's level is its own mean over its last window. Bad windows are refused in one line."""
    steps = [0, 200_000, 400_000, 600_000, 800_000]
    ref = fake_run(tmp_path / "ref", steps, [1] * 5, [0.0, 0.2, 0.4, 0.6, 0.6])
    spiky = fake_run(tmp_path / "spiky", steps, [1] * 5, [0.0, 0.6, 0.0, 0.5, 0.7])
    for run in (ref, spiky):
        (run / "config.json").write_text(json.dumps({"env": {}}))
    out = tmp_path / "figures"
    argv = ["agent", "curves", "--group", f"ref={ref}", "--group", f"spiky={spiky}", "--reach", "ref"]
    assert main([*argv, "--out", str(out), "--json"]) == 0
    single = {row["label"]: row for row in json.loads(capsys.readouterr().out)["reach"]}
    assert single["spiky"]["steps_to_level"] == 200_000.0 and single["spiky"]["window_steps"] is None
    assert main([*argv, "--out", str(out), "--window", "4e5", "--json"]) == 0
    windowed = {row["label"]: row for row in json.loads(capsys.readouterr().out)["reach"]}
    assert windowed["ref"]["level"] == 0.6 and windowed["ref"]["steps_to_level"] == 800_000.0
    assert windowed["spiky"]["steps_to_level"] == 800_000.0 and windowed["spiky"]["final_success"] == 0.6
    assert windowed["spiky"]["window_steps"] == 400_000.0
    assert (out / "reach.md").exists() and "mean over the last 0.4e6 env steps" in (
        out / "reach-window-400000.md"
    ).read_text()
    for extra, message in (
        (["--window", "3e5"], "--window 300000: not a positive multiple of the 200000-step grid"),
        (["--window", "0"], "--window 0: not a positive multiple"),
        (["--window", "nan"], "--window nan: not a positive multiple"),
        (["--window", "2e6"], "--window 2000000: longer than --group ref's curve (5 grid points"),
    ):
        assert main([*argv, "--out", str(out), *extra]) == 2
        error = capsys.readouterr().err
        assert message in error and error.count("\n") == 1
    assert main(["agent", "curves", "--group", f"ref={ref}", "--out", str(out), "--window", "4e5"]) == 2
    assert "--window needs --reach" in capsys.readouterr().err
