"""krl agent heldout: policies walk the same fresh episodes of their training distribution, never a
training seed; the records resume; the table's seed spread by hand."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from agent_fakes import make_policy

from krl.agent.action import action_parts
from krl.agent.config import AgentConfig, EnvConfig, ResidualConfig
from krl.agent.policy import load_policy
from krl.agent.process_vec_env import ProcessVecEnv
from krl.agent.train import _env_seed, train
from krl.analysis.agent import heldout, heldout_choice
from krl.analysis.agent.heldout import HELDOUT_SEED, drive_usage, group_rows
from krl.cli import main
from krl.kernel.registry import load_model


@pytest.fixture(scope="module")
def tiny_group(tmp_path_factory, small_config):
    """Two tiny policies of one recipe (seeds 1 and 2) whose episodes last 0.5 s, trained once for the
    module: tests read them and write elsewhere."""
    config = replace(small_config, env=EnvConfig(episode_time=0.5))
    folder = tmp_path_factory.mktemp("tiny-group")
    for seed in (1, 2):
        train(
            folder / f"tiny-seed{seed}",
            config,
            seed=seed,
            total_steps=256,
            progress=False,
            log=lambda _: None,
        )
    return str(folder / "tiny-seed*")


def heldout_json(capsys, *args: str) -> dict:
    assert main(["agent", "heldout", *args, "--episodes", "3", "--workers", "1", "--quiet", "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_every_seed_walks_the_same_heldout_episodes_and_a_rerun_reads_them(
    tmp_path, tiny_group, capsys, monkeypatch
):
    out = tmp_path / "heldout"
    first = heldout_json(capsys, "--policy", f"tiny={tiny_group}", "--out", str(out))
    (row,) = first["rows"]
    assert (row["label"], row["seeds"], row["episodes"]) == ("tiny", "1 2", 3)
    records = [json.loads((out / "tiny" / f"seed{seed}.json").read_text()) for seed in (1, 2)]
    terrains = [[episode["terrain"] for episode in record["episodes_walked"]] for record in records]
    assert terrains[0] == terrains[1] and len(set(terrains[0])) == 3  # the same three fresh terrains
    for record in records:
        assert record["heldout_seed"] == HELDOUT_SEED and len(record["episodes_walked"]) == 3
        assert all(0 < episode["length_s"] <= 0.5 + 1e-9 for episode in record["episodes_walked"])
    assert "| tiny | 1 2 |" in (out / "heldout.md").read_text()

    monkeypatch.setattr(heldout, "heldout_episodes", lambda *args: pytest.fail("walked again"))
    assert heldout_json(capsys, "--policy", f"tiny={tiny_group}", "--out", str(out)) == first


def test_env_walks_every_policy_in_one_given_environment(tmp_path, tiny_group, capsys, monkeypatch):
    env_file = tmp_path / "pyramids.json"
    ground = {"heightfield_probability": 0.0, "pyramids_probability": 1.0, "episode_time": 0.25}
    env_file.write_text(json.dumps({"env": ground}))
    out = tmp_path / "on-pyramids"
    args = ("--policy", f"tiny={tiny_group}", "--out", str(out))
    first = heldout_json(capsys, *args, "--env", str(env_file))
    for seed in (1, 2):
        record = json.loads((out / "tiny" / f"seed{seed}.json").read_text())
        assert record["env"]["pyramids_probability"] == 1.0
        for episode in record["episodes_walked"]:
            assert episode["terrain"].startswith("pyramids-") and episode["length_s"] <= 0.25 + 1e-9
    assert f"episodes of the environment of `{env_file}`" in (out / "heldout.md").read_text()

    def walked(*args):
        raise AssertionError("walked")

    monkeypatch.setattr(heldout, "heldout_episodes", walked)
    assert heldout_json(capsys, *args, "--env", str(env_file)) == first  # the same environment: read
    with pytest.raises(AssertionError, match="walked"):  # the policies' own environment: walked anew
        heldout_json(capsys, *args)


def test_the_heldout_environments_are_no_training_environments():
    # the largest environment seed of the recipe's runs: seed 556 resumed at its last checkpoint, last env
    recipe = replace(AgentConfig(), workers=2, num_envs=16, checkpoint_every=500_000)
    last_sitting = _env_seed(556, recipe, resumed_at=20_000_000)
    assert last_sitting + recipe.workers * recipe.num_envs < HELDOUT_SEED


def test_the_group_row_is_the_mean_and_sample_std_over_seeds():
    def record(targets, success, falls, reward):
        summary = dict(zip(heldout.METRICS, (targets, success, falls, reward), strict=True))
        return {"episodes": 4, "summary": summary}

    rows = group_rows(
        {
            "a": [(150, record(3.0, 0.5, 0.25, 0.1)), (215, record(5.0, 1.0, 0.0, 0.2))],
            "b": [(None, record(1, 0, 1, 0))],
        }
    )
    assert rows[0]["seeds"] == "150 215" and rows[0]["targets_reached_mean"] == 4.0
    assert rows[0]["targets_reached_std"] == pytest.approx(math.sqrt(2.0))
    assert rows[0]["fall_rate_std"] == pytest.approx(0.25 / math.sqrt(2.0))
    assert rows[1]["seeds"] == "-" and math.isnan(rows[1]["success_rate_std"])


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--policy", "rp", "--episodes", "0"], "--episodes must be at least 1, got 0"),
        (["--policy", "a=rp", "--policy", "a=base"], "the label 'a' is given twice"),
        (["--policy", "../x=rp"], "--policy '../x=rp': a label is letters, digits, '.', '_' or '-'"),
        (["--policy", "rp", "--env", "nowhere.json"], "--env nowhere.json: cannot read agent config"),
    ],
)
def test_bad_input_is_one_line_and_writes_nothing(tmp_path, capsys, args, message):
    assert main(["agent", "heldout", *args, "--out", str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1
    assert not (tmp_path / "out").exists()


def test_drive_usage_is_what_the_policy_asked_for_in_each_drives_unit():
    parts = action_parts(
        ResidualConfig(kernel="ext", drive_heights=True, drive_rhythm=True), load_model("ext")
    )
    actions = np.zeros((4, 15))
    actions[:, 14] = [1.0, 1.5, 0.0, -0.995]  # clock rate: 2, 2 (clipped), 1, ~0.5 (at the low bound)
    actions[:, 13] = -1.0  # ride height: its low end, 0.18 m, every step
    usage = drive_usage(parts, actions)
    assert list(usage) == ["heights.step_height", "heights.ride_height", "clock_rate.rate"]
    rate = usage["clock_rate.rate"]
    assert rate["mean"] == pytest.approx((2 + 2 + 1 + 1 - 0.995 * 0.5) / 4)
    assert (rate["at_high"], rate["at_low"]) == (0.5, 0.25)
    assert usage["heights.ride_height"]["mean"] == pytest.approx(0.18)
    assert usage["heights.ride_height"]["at_low"] == 1.0 and usage["heights.step_height"]["at_low"] == 0.0
    assert drive_usage(action_parts(ResidualConfig(), load_model("base")), np.ones((3, 12))) == {}


def test_a_gait_driving_policy_gets_its_drive_usage_table(tmp_path, capsys, small_config):
    config = replace(
        small_config,
        env=EnvConfig(episode_time=0.5),
        residual=ResidualConfig(kernel="ext", drive_heights=True, drive_rhythm=True),
    )
    path = make_policy(config, scale=0.5, seed=3).save(tmp_path / "gait.npz")
    out = tmp_path / "heldout"
    heldout_json(capsys, "--policy", f"gait={path}", "--out", str(out))
    record = json.loads((out / "gait" / "policy.json").read_text())
    assert set(record["drive_usage"]) == {"heights.step_height", "heights.ride_height", "clock_rate.rate"}
    rate = record["drive_usage"]["clock_rate.rate"]
    assert 0.5 <= rate["p5"] <= rate["mean"] <= rate["p95"] <= 2.0
    assert "| gait | clock_rate.rate |" in (out / "heldout.md").read_text()
    assert (out / "heldout-drives.csv").read_text().startswith("label,drive,mean,p5,p95,at_low,at_high")


def group_row(label, success, targets, episodes=32):
    return {
        "label": label,
        "episodes": episodes,
        "success_rate_mean": success,
        "targets_reached_mean": targets,
    }


def test_the_rule_chooses_the_highest_success_and_breaks_ties_within_one_episode_by_targets():
    rows = [
        group_row("control", 1.0, 9.0),  # not a candidate: never chosen however good
        group_row("a", 25 / 32, 4.0),
        group_row("b", 26 / 32, 4.5),
        group_row("c", 27 / 32, 4.2),
        group_row("d", 24 / 32, 6.0),  # two episodes below the best: not tied
    ]
    choice = heldout.choose(rows, ["a", "b", "c", "d"])
    assert choice["chosen"] == "b" and choice["tied"] == ["b", "c"]
    assert (choice["best_success_rate"], choice["tolerance"]) == (27 / 32, 1 / 32)
    assert heldout.choose(rows, ["a", "c"])["chosen"] == "c"  # a is one below, has fewer targets
    even = [group_row("x", 0.5, 4.0), group_row("y", 0.5, 4.0)]
    assert heldout.choose(even, ["y", "x"])["chosen"] == "y"  # a full tie: the first given
    with pytest.raises(ValueError, match="--choose 'z' is no --policy label"):
        heldout.choose(rows, ["a", "z"])
    with pytest.raises(ValueError, match="names a label twice"):
        heldout.choose(rows, ["a", "a"])


def test_choose_names_the_chosen_policy_in_json_and_table(tmp_path, tiny_group, capsys):
    out = tmp_path / "heldout"
    result = heldout_json(
        capsys,
        "--policy",
        f"p={tiny_group}",
        "--policy",
        f"q={tiny_group}",
        "--choose",
        "q,p",
        "--out",
        str(out),
    )
    assert result["choice"]["chosen"] == "q" and result["choice"]["tied"] == ["q", "p"]
    assert "Chosen: **q**" in (out / "heldout.md").read_text()
    choice = json.loads((out / "choice.json").read_text())
    assert choice["chosen"] == "q" and len(choice["policies"]) == 2
    recipe = AgentConfig.load(out / "chosen-config.json")  # what krl agent train --config reads
    assert recipe == load_policy(choice["policies"][0]).config and recipe.env.episode_time == 0.5


def test_the_chosen_runs_join_a_seed_group_and_a_different_policy_there_is_kept(tmp_path, tiny_group, capsys):
    group = tmp_path / "agent-chosen"
    args = ["--policy", f"p={tiny_group}", "--choose", "p", "--out", str(tmp_path / "heldout")]
    result = heldout_json(capsys, *args, "--seed-group", str(group))
    assert result["written"]["seed_group"] == [str(group / "seed1"), str(group / "seed2")]
    for seed in (1, 2):
        run = Path(tiny_group).parent / f"tiny-seed{seed}"
        for name in ("policy.npz", "config.json", "run.json", "progress.csv"):
            assert (group / f"seed{seed}" / name).read_bytes() == (run / name).read_bytes()
        assert not (group / f"seed{seed}" / "checkpoints").exists()
    assert heldout_json(capsys, *args, "--seed-group", str(group))["written"]["seed_group"] == []
    (group / "seed2" / "policy.npz").write_bytes((group / "seed1" / "policy.npz").read_bytes())
    (group / "seed1" / "policy.npz").unlink()
    assert main(["agent", "heldout", *args, "--seed-group", str(group), "--episodes", "3", "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert f"{group / 'seed2'} holds another policy than" in err and len(err.splitlines()) == 1
    assert not (group / "seed1" / "policy.npz").exists()  # nothing copied


def test_a_seed_group_needs_a_choice(tmp_path, capsys):
    args = ["agent", "heldout", "--policy", "a=rp", "--seed-group", str(tmp_path / "g")]
    assert main([*args, "--out", str(tmp_path), "--quiet"]) == 2
    assert "--seed-group needs --choose" in capsys.readouterr().err


def test_a_bad_choice_fails_before_walking(tmp_path, capsys):
    args = ["agent", "heldout", "--policy", "a=rp", "--choose", "a,b", "--out", str(tmp_path / "out")]
    assert main([*args, "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "--choose 'b' is no --policy label (labels: a)" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "out").exists()


def test_a_choice_of_policies_trained_differently_has_no_recipe(tmp_path, small_config):
    paths = [
        make_policy(replace(small_config, env=EnvConfig(episode_time=t)), seed=1).save(tmp_path / f"{t}.npz")
        for t in (0.5, 1.0)
    ]
    choice = {"chosen": "mixed", "tied": ["mixed"], "best_success_rate": 1.0, "tolerance": 1 / 32}
    with pytest.raises(ValueError, match="'mixed' were trained with different recipes"):
        heldout.write_choice(choice, [(1, paths[0]), (2, paths[1])], tmp_path)
    assert not (tmp_path / "choice.json").exists() and not (tmp_path / "chosen-config.json").exists()


def test_against_a_baseline_better_means_more_than_one_episode_and_no_worse_at_most_one_below():
    rows = [group_row("base", 20 / 32, 4.0), group_row("x", 21 / 32, 4.0), group_row("y", 22 / 32, 4.0)]
    assert not heldout.against_baseline(rows, "x", "base", must_beat=True)["holds"]  # one episode: a tie
    assert heldout.against_baseline(rows, "y", "base", must_beat=True)["holds"]
    assert heldout.against_baseline(rows, "base", "x", must_beat=False)["holds"]  # one below: no worse
    check = heldout.against_baseline(rows, "base", "y", must_beat=False)
    assert not check["holds"] and check["margin"] == -2 / 32 and check["tolerance"] == 1 / 32


def fake_records(success: dict[str, tuple[int, int]]):
    """A stand-in for ``policy_record``: each label's success (of 32) on its own episodes and on
    ``--baseline-env``'s, by the record's folder; nothing walked."""

    def record(path, record_path, episodes, workers, on_episode, env=None):
        label = record_path.parent.name
        on_baseline_env = env is not None  # the test gives no --env: only --baseline-env's walks have one
        assert on_baseline_env == ("baseline-env" in record_path.parts)
        rate = success[label][on_baseline_env] / 32
        summary = {
            "targets_reached": 4.0,
            "success_rate": rate,
            "fall_rate": 1 - rate,
            "reward_per_step": 0.1,
        }
        return {"episodes": 32, "summary": summary, "policy": str(path)}

    return record


@pytest.mark.parametrize(("on_baseline_env", "stands"), [(27, True), (26, False)])
def test_a_choice_stands_only_if_better_than_the_baseline_and_no_worse_on_its_ground(
    tmp_path, tiny_group, capsys, monkeypatch, on_baseline_env, stands
):
    monkeypatch.setattr(
        heldout_choice,
        "policy_record",
        fake_records({"base": (20, 28), "p": (21, 0), "q": (23, on_baseline_env)}),
    )
    own = tmp_path / "own.json"
    own.write_text(json.dumps({"env": {"episode_time": 0.5}}))
    out, group = tmp_path / "heldout", tmp_path / "agent-chosen"
    labels = [arg for label in ("base", "p", "q") for arg in ("--policy", f"{label}={tiny_group}")]
    options = [
        "--choose",
        "p,q",
        "--baseline",
        "base",
        "--baseline-env",
        str(own),
        "--seed-group",
        str(group),
    ]
    result = heldout_json(capsys, *labels, *options, "--out", str(out))
    verdict = result["choice"]["baseline"]
    assert result["choice"]["chosen"] == "q" and verdict["stands"] is stands
    here, there = verdict["checks"].values()
    assert here["margin"] == 3 / 32 and here["holds"]
    assert there["margin"] == (on_baseline_env - 28) / 32 and there["holds"] is stands
    table = (out / "baseline-env" / "heldout.md").read_text()  # the chosen and the baseline, on own.json's
    assert f"the environment of `{own}`" in table and "| base |" in table and "| q |" in table
    assert "| p |" not in table
    assert json.loads((out / "choice.json").read_text())["baseline"]["stands"] is stands
    assert (out / "chosen-config.json").exists() is stands and group.exists() is stands
    assert (
        f"The choice **{'stands' if stands else 'does not stand'}** against base"
        in (out / "heldout.md").read_text()
    )


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--baseline", "a"], "--baseline needs --choose"),
        (["--choose", "a", "--baseline-env", "x.json"], "--baseline-env needs --baseline"),
        (["--choose", "a", "--baseline", "z"], "--baseline 'z' is no --policy label"),
        (["--choose", "a", "--baseline", "a"], "--baseline 'a' is also a --choose candidate"),
        (
            ["--choose", "a", "--baseline", "b", "--baseline-env", "x.json"],
            "--baseline-env x.json: cannot read",
        ),
    ],
)
def test_bad_baseline_options_are_one_line(tmp_path, capsys, args, message):
    assert (
        main(
            [
                "agent",
                "heldout",
                "--policy",
                "a=rp",
                "--policy",
                "b=base",
                *args,
                "--out",
                str(tmp_path / "out"),
                "--quiet",
            ]
        )
        == 2
    )
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1
    assert not (tmp_path / "out").exists()


def test_a_seed_group_of_a_policy_without_a_seed_is_refused_before_anything_is_walked_or_written(
    tmp_path, capsys, small_config
):
    path = make_policy(replace(small_config, env=EnvConfig(episode_time=0.5))).save(tmp_path / "one.npz")
    out, group = tmp_path / "heldout", tmp_path / "agent-chosen"
    args = ["agent", "heldout", "--policy", f"p={path}", "--choose", "p", "--seed-group", str(group)]
    assert main([*args, "--out", str(out), "--episodes", "3", "--workers", "1", "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "'p' is one policy file without a seed" in err and len(err.splitlines()) == 1
    assert not out.exists() and not group.exists()


def test_a_refused_seed_group_writes_no_choice(tmp_path, tiny_group, capsys):
    """Issue 47: a seed group that held another policy was refused only after choice.json was written."""
    group, out = tmp_path / "agent-chosen", tmp_path / "heldout"
    (group / "seed1").mkdir(parents=True)
    (group / "seed1" / "policy.npz").write_bytes(b"another policy")
    args = ["--policy", f"p={tiny_group}", "--choose", "p", "--seed-group", str(group), "--out", str(out)]
    assert main(["agent", "heldout", *args, "--episodes", "3", "--workers", "1", "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert f"{group / 'seed1'} holds another policy than" in err and len(err.splitlines()) == 1
    assert not (out / "choice.json").exists() and not (out / "chosen-config.json").exists()
    assert sorted(path.name for path in group.rglob("*")) == ["policy.npz", "seed1"]


def test_an_absurd_episode_count_is_refused_in_one_line(tmp_path, capsys):
    """Issue 47: ``--episodes 1000000000000`` built every episode's environment at once and was killed for
    memory."""
    out = tmp_path / "out"
    argv = ["agent", "heldout", "--policy", "rp", "--episodes", "1000000000000", "--out", str(out), "--quiet"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err == f"krl: error: --episodes must be at most {heldout.MAX_EPISODES}, got 1000000000000\n"
    assert not out.exists()
    with pytest.raises(ValueError, match="at most"):
        heldout.heldout_episodes(tmp_path / "unread.npz", heldout.MAX_EPISODES + 1, 1)


def test_many_episodes_walk_in_batches_of_bounded_size_with_the_same_episodes(
    tmp_path, monkeypatch, small_config
):
    config = replace(
        small_config,
        env=EnvConfig(episode_time=0.5),
        residual=ResidualConfig(kernel="ext", drive_heights=True, drive_rhythm=True),
    )
    path = make_policy(config, scale=0.5, seed=3).save(tmp_path / "gait.npz")
    built = []

    def recording(config, workers, num_envs, seed, kernel, rowwise):
        built.append((workers * num_envs, seed, rowwise))
        return ProcessVecEnv(config, workers, num_envs, seed, kernel, rowwise)

    monkeypatch.setattr(heldout, "ProcessVecEnv", recording)
    monkeypatch.setattr(heldout, "HELDOUT_BATCH", 2)
    batched, batched_usage = heldout.heldout_episodes(path, 5, 1)
    assert built == [(2, HELDOUT_SEED, True), (2, HELDOUT_SEED + 2, True), (1, HELDOUT_SEED + 4, True)]
    monkeypatch.setattr(heldout, "HELDOUT_BATCH", 8)
    whole, whole_usage = heldout.heldout_episodes(path, 5, 1)
    assert built[3:] == [(5, HELDOUT_SEED, True)]
    assert [e["terrain"] for e in batched] == [e["terrain"] for e in whole]
    for mine, one_batch in zip(batched, whole, strict=True):
        assert (mine["targets_reached"], mine["fell"]) == (one_batch["targets_reached"], one_batch["fell"])
        assert mine["reward_per_step"] == pytest.approx(one_batch["reward_per_step"], rel=1e-9)
    for drive, usage in whole_usage.items():
        assert batched_usage[drive] == pytest.approx(usage, rel=1e-9, abs=1e-12)
