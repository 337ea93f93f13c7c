"""``krl reproduce``: every planned command parses; done steps are skipped; a failure stops and resumes;
docs/reproduce.md shows the plan as it is."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from krl.apps.reproduce import plan, reproduce
from krl.cli import build_parser, main


@pytest.mark.parametrize("quick", [False, True])
def test_every_planned_command_is_a_valid_krl_command(tmp_path, quick):
    parser = build_parser()
    steps = plan(tmp_path / "runs", tmp_path / "docs", quick)
    assert len({step.name for step in steps}) == len(steps)
    for step in steps:
        parser.parse_args(list(step.argv))  # exits (SystemExit) on an unknown option
    if quick:
        assert all(str(tmp_path / "docs") not in step.command for step in steps)
        assert sum(step.minutes for step in steps) < 80  # about 75 min, docs/reproduce.md


def test_done_steps_are_skipped_and_a_failure_resumes_there(tmp_path):
    runs, docs = tmp_path / "runs", tmp_path / "docs"
    calls: list[list[str]] = []
    steps = plan(runs, docs, quick=True)

    def failing_at_third(argv: list[str]) -> int:
        calls.append(argv)
        return 3 if len(calls) == 3 else 0

    assert reproduce(runs, docs, True, failing_at_third, log=lambda _: None) == 3
    assert calls == [list(step.argv) for step in steps[:3]]
    calls.clear()
    lines: list[str] = []
    assert reproduce(runs, docs, True, lambda argv: calls.append(argv) or 0, log=lines.append) == 0
    assert calls[0] == list(steps[2].argv) and len(calls) == len(steps) - 2
    assert (runs / "quick" / "agent-rp-seed150.json").is_file()
    assert lines[-1] == "everything is reproduced"


def test_dry_run_prints_the_plan(tmp_path, capsys):
    assert main(["reproduce", "--quick", "--dry-run", "--runs", str(tmp_path)]) == 0
    printed = capsys.readouterr().out
    assert "collect-base" in printed and "left: about" in printed
    assert not (tmp_path / "quick").exists()


@pytest.mark.parametrize("quick", [False, True])
def test_the_documented_tables_are_the_plan(quick):
    """docs/reproduce.md's table for the mode holds each step, in order, and the total of the defaults'."""
    text = (Path(__file__).resolve().parents[2] / "docs" / "reproduce.md").read_text()
    table = text.split("## Quick")[1 if quick else 0]
    rows = [line for line in table.splitlines() if line.startswith("| ") and line[2].isdigit()]
    steps = plan(Path("runs/reproduce"), Path("docs"), quick)
    assert rows == [
        f"| {number} | `{step.name}` | {step.makes} | {step.minutes:g} | `{step.command}` |"
        for number, step in enumerate(steps, start=1)
    ]
    assert f"Total: about {sum(step.minutes for step in steps):.0f} min." in table


def test_both_agents_are_trained_and_scored_from_each_chosen_seed(tmp_path):
    steps = {step.name: step for step in plan(tmp_path, tmp_path / "docs", seeds=[345, 150])}
    trained = [name for name in steps if name.startswith("agent-") and "seed" in name]
    assert trained == ["agent-rp-seed345", "agent-rp-seed150", "agent-base-seed345", "agent-base-seed150"]
    base = steps["agent-base-seed150"]
    assert f"--out {tmp_path}/agent-base/seed150 --seed 150" in base.command
    config = json.loads(base.config[1])
    assert config["env"] == {"reward": "base"} and (config["num_envs"], config["workers"]) == (16, 2)
    assert "env" not in json.loads(steps["agent-rp-seed150"].config[1])
    courses = steps["evaluate-courses"].command
    assert f"--controller agent:{tmp_path}/agent-rp --controller agent:{tmp_path}/agent-base" in courses
    assert "--seeds 345,150" in courses and "--seeds 345,150" in steps["evaluate-pushes"].command
    assert "--seeds 345,150" in steps["study-variants"].command
    assert [step.name for step in plan(tmp_path, tmp_path, quick=True)].count("agent-rp-seed150") == 1
    with pytest.raises(ValueError, match="seeds must differ"):
        plan(tmp_path, tmp_path, seeds=[150, 150])


def test_agent_gait_is_chosen_from_the_ablation_on_the_pipelines_kernel_and_trained_for_the_other_seeds(
    tmp_path,
):
    steps = {step.name: step for step in plan(tmp_path, tmp_path / "docs", seeds=[345, 150, 215])}
    ablation = steps["gait-ablation"]
    assert "--seeds 345,150 --jobs 2" in ablation.command
    assert json.loads(ablation.config[1]) == {"residual": {"kernel": f"{tmp_path}/kernel-ext/kernel.npz"}}
    trials = f"{tmp_path}/agent-studies/gait-ablation/trials/list"
    heldout = steps["heldout-gait"].command
    assert f"--policy heights={trials}/heights-seed*" in heldout
    assert "--choose heights,rhythm,both,steer-both" in heldout
    assert f"--seed-group {tmp_path}/agent-gait" in heldout
    assert [name for name in steps if name.startswith("agent-gait-seed")] == ["agent-gait-seed215"]
    assert f"--config {tmp_path}/heldout-gait/chosen-config.json" in steps["agent-gait-seed215"].command
    scoring = steps["evaluate-gait"].command
    groups = f"--controller agent:{tmp_path}/agent-gait --controller agent:{tmp_path}/agent-gait-ground"
    assert f"{groups} --controller agent:{trials}/residual-ext-seed*" in scoring
    assert "--course harder --push-sweep --attempts 50 --friction-sweep" in scoring
    names = list(steps)
    assert names[names.index("evaluate-gait") + 1] == "report-gait"
    ground = f"{tmp_path}/agent-studies/gait-ground/trials/list"
    assert "--seeds 345,150 --jobs 2" in steps["gait-ground"].command
    assert json.loads(steps["gait-ground"].config[1]) == json.loads(ablation.config[1])
    rule = steps["heldout-ground"].command
    assert f"--policy agent-gait={trials}/steer-both-seed* --policy pyramids={ground}/pyramids-seed*" in rule
    assert f"--env {ground}/pyramids-pushes-seed345/config.json --choose pyramids,pyramids-pushes" in rule
    assert f"--baseline agent-gait --baseline-env {trials}/steer-both-seed345/config.json" in rule
    more = [name for name in steps if name.startswith("agent-gait-ground-seed")]
    assert more == ["agent-gait-ground-seed215"]
    assert f"--config {tmp_path}/heldout-ground/chosen-config.json" in steps[more[0]].command
    assert f"--controller agent:{ground}/pyramids-pushes-seed*" in scoring
    quick = {step.name: step for step in plan(tmp_path, tmp_path / "docs", quick=True)}
    assert (
        "--seeds 150 --jobs 2" in quick["gait-ablation"].command
        and "--budget" in quick["gait-ablation"].command
    )
    assert not [name for name in quick if name.startswith("agent-gait-seed")]
    assert "agent-gait-ground" not in quick["evaluate-gait"].command  # no seed group from 8 000-step runs
    quick_ground = f"{tmp_path}/quick/agent-studies/gait-ground/trials/list"
    assert f"--controller agent:{quick_ground}/pyramids-seed*" in quick["evaluate-gait"].command


def test_agent_robust_is_chosen_among_its_arms_and_trained_for_the_other_seeds(tmp_path):
    steps = {step.name: step for step in plan(tmp_path, tmp_path / "docs", seeds=[345, 150, 215])}
    names = list(steps)
    robust = f"{tmp_path}/robust"
    recipe = f"{tmp_path}/agent-studies/gait-ground/trials/list/pyramids-pushes-seed345/config.json"
    augment = steps["robust-config-augment"]
    assert augment.command.startswith(
        f"krl agent config {recipe} {tmp_path}/robust-config-augment.json --out"
    )
    assert json.loads(augment.config[1]) == {"ppo": {"symmetry": "augment"}}
    pilot = steps["robust-pilot-loss-seed345"].command
    assert f"--out {robust}/pilot-loss-seed345 --seed 345 --config {robust}/configs/loss.json" in pilot
    assert "--steps 4000000" in pilot
    chosen = f"{robust}/heldout-pilot/chosen-config.json"
    assert steps["robust-config-sym"].command == f"krl agent config {chosen} --out {robust}/configs/sym.json"
    assert (
        f"agent config {chosen} {tmp_path}/robust-config-sym-curriculum.json"
        in steps["robust-config-sym-curriculum"].command
    )
    arms = [name for name in names if name.startswith(("robust-sym", "robust-curriculum"))]
    assert arms == [
        f"robust-{arm}-seed{seed}" for arm in ("sym", "curriculum", "sym-curriculum") for seed in (345, 150)
    ]
    rule = steps["robust-heldout"].command
    assert f"--env {robust}/configs/broad-pushes.json --choose sym,curriculum,sym-curriculum" in rule
    assert (
        f"--baseline baseline --baseline-env {recipe}" in rule
        and f"--seed-group {tmp_path}/agent-robust" in rule
    )
    order = [
        "robust-pilot-augment-seed345",
        "robust-heldout-pilot",
        "robust-config-sym-curriculum",
        *arms,
        "robust-heldout",
        "agent-robust-seed215",
        "robust-evaluate",
        "robust-evaluate-balanced",
        "robust-report",
        "robust-curves",
        "robust-evaluate-left-right",
        "robust-report-left-right",
    ]
    assert [names.index(name) for name in order] == sorted(names.index(name) for name in order)
    assert [name for name in names if name.startswith("agent-robust-seed")] == ["agent-robust-seed215"]
    assert f"--config {robust}/heldout-robust/chosen-config.json" in steps["agent-robust-seed215"].command
    assert (
        f"--controller agent:{tmp_path}/agent-robust --controller agent:{robust}/sym-seed*"
        in steps["robust-evaluate-balanced"].command
    )
    assert "--push-directions balanced --attempts 48" in steps["robust-evaluate-balanced"].command
    left_right = steps["robust-evaluate-left-right"].command
    assert (
        f"--controller agent:{tmp_path}/agent-robust --controller agent:{tmp_path}/agent-gait-ground "
        "--controller expert --push-sweep --push-directions balanced --magnitudes 350:600:50 --attempts 400"
    ) in left_right
    assert steps["robust-report-left-right"].command.endswith(
        f"--results {tmp_path}/eval-robust-left-right --out {tmp_path}/docs/results/robust-left-right"
    )
    quick = {step.name: step for step in plan(tmp_path, tmp_path / "docs", quick=True)}
    assert "--steps 8000" in quick["robust-sym-curriculum-seed150"].command
    assert "--attempts 4 --magnitudes 350,600" in quick["robust-evaluate-balanced"].command  # 1 per quarter
    assert not [name for name in quick if name.startswith("agent-robust-seed")]
    assert "agent-robust" not in quick["robust-evaluate"].command  # no seed group from 8 000-step runs
    quick_arm = f"--controller agent:{tmp_path}/quick/robust/sym-curriculum-seed*"
    assert quick_arm in quick["robust-evaluate-left-right"].command


def test_reproduce_seeds_option_reaches_the_plan(tmp_path, capsys):
    assert main(["reproduce", "--dry-run", "--seeds", "215", "--runs", str(tmp_path)]) == 0
    printed = capsys.readouterr().out
    assert "agent-base-seed215" in printed and "seed150" not in printed
    assert main(["reproduce", "--dry-run", "--seeds", "x", "--runs", str(tmp_path)]) == 2
    assert "--seeds expects comma-separated integers" in capsys.readouterr().err
