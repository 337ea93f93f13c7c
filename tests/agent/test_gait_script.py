"""examples/gait/agent-gait.sh and agent-gait-ground.sh, run against a stand-in ``krl`` that logs its
arguments: the steps in order, the chosen variant's seeds and recipe, one evaluation of every variant and
agent-gait, the ground study's rule deciding whether its seeds train, and one SIGTERM reaching the running
command."""

from __future__ import annotations

import signal
import subprocess
import time
from pathlib import Path

import pytest
from script_stand_in import stand_in_environment

SCRIPT = Path(__file__).resolve().parents[2] / "examples" / "gait" / "agent-gait.sh"
GROUND_SCRIPT = SCRIPT.with_name("agent-gait-ground.sh")

STAND_IN = r"""#!/usr/bin/env bash
# logs its arguments; heldout --choose writes a choice; a SLOW command waits for a signal
echo "$*" >> "$LOG"
trap 'echo "TERM $1 $2" >> "$LOG"; kill $nap; exit 130' TERM
if [ "$1 $2" = "$SLOW" ]; then sleep 60 & nap=$!; touch "$LOG.started"; wait; fi
if [ "$1 $2" = "agent heldout" ]; then
  out=$(echo "$*" | sed -E 's/.*--out ([^ ]+).*/\1/')
  mkdir -p "$out"
  echo "{\"chosen\": \"rhythm\", \"baseline\": {\"stands\": $STANDS}}" > "$out/choice.json"
  echo '{}' > "$out/chosen-config.json"
fi
"""


@pytest.fixture
def workspace(tmp_path):
    env = stand_in_environment(
        tmp_path, STAND_IN, SLOW="", STANDS="true", RUNS="runs", EVAL="evaluations/gait", REPORT="report"
    )
    return tmp_path, env


def run_pipeline(script: Path, root: Path, env: dict, trains: int) -> list[str]:
    """Run ``script`` to its end; the stand-in's log lines, checked to be the study, the held-out choice,
    ``trains`` trainings, the evaluation and the report, in that order."""
    done = subprocess.run(["bash", str(script)], cwd=root, env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    lines = (root / "krl.log").read_text().splitlines()
    assert [" ".join(line.split()[:2]) for line in lines] == [
        "agent study",
        "agent heldout",
        *(["agent train"] * trains),
        "evaluate --controller",
        "report --results",
    ]
    return lines


def test_the_pipeline_runs_its_steps_in_order_with_the_chosen_recipe(workspace):
    root, env = workspace
    lines = run_pipeline(SCRIPT, root, env, trains=2)
    assert "--choose heights,rhythm,both,steer-both" in lines[1]
    assert "--policy residual-ext=runs/agent-studies/gait-ablation/trials/list/residual-ext-seed*" in lines[1]
    trains = sorted(lines[2:4])
    assert trains[0].startswith("agent train --out runs/agent-gait/seed345 --seed 345")
    assert all("--config runs/heldout-gait/chosen-config.json" in line for line in trains)
    assert "--seed-group runs/agent-gait " in lines[1]  # the chosen variant's runs: agent-gait's seeds
    evaluate = lines[4]
    assert "--controller agent:runs/agent-gait " in evaluate and "rhythm-seed*" in evaluate
    assert evaluate.count("-seed*") == 5 and "--attempts 50 --friction-sweep" in evaluate


def test_one_sigterm_reaches_the_running_command_and_stops_the_pipeline(workspace):
    root, env = workspace
    script = subprocess.Popen(["bash", str(SCRIPT)], cwd=root, env=env | {"SLOW": "agent study"})
    started = root / "krl.log.started"
    deadline = time.monotonic() + 30
    while not started.exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert started.exists()
    script.send_signal(signal.SIGTERM)
    assert script.wait(timeout=30) == 130
    log = (root / "krl.log").read_text().splitlines()
    assert log[-1] == "TERM agent study"
    assert not any(step in line for line in log for step in ("heldout", "train", "evaluate"))


def test_the_script_runs_the_studys_variants_and_chooses_among_its_driving_ones():
    from krl.agent.studies.designs import GAIT_DRIVES

    lines = SCRIPT.read_text().splitlines()
    (variants,) = [line for line in lines if line.startswith("VARIANTS=")]
    (driving,) = [line for line in lines if line.startswith("DRIVING=")]
    names = [name for name, _, drives, _ in GAIT_DRIVES]
    assert variants == f"VARIANTS=({' '.join(names)})"
    assert driving == "DRIVING=" + ",".join(name for name, _, drives, _ in GAIT_DRIVES if drives)


@pytest.mark.parametrize("stands", [True, False])
def test_the_ground_pipeline_trains_more_seeds_only_if_its_choice_stands(workspace, stands):
    root, env = workspace
    env = env | {"STANDS": "true" if stands else "false"}
    lines = run_pipeline(GROUND_SCRIPT, root, env, trains=2 * stands)
    assert lines[0].startswith("agent study gait-ground --out runs/agent-studies/gait-ground --seeds 150,215")
    heldout = lines[1]
    for option in (
        "--policy agent-gait=runs/agent-studies/gait-ablation/trials/list/steer-both-seed*",
        "--env runs/agent-studies/gait-ground/trials/list/pyramids-pushes-seed150/config.json",
        "--choose pyramids,pyramids-pushes --baseline agent-gait",
        "--baseline-env runs/agent-studies/gait-ablation/trials/list/steer-both-seed150/config.json",
        "--seed-group runs/agent-gait-ground",
    ):
        assert option in heldout
    evaluate = lines[-2]
    assert evaluate.count("-seed*") == 2 and "--out evaluations/gait" in evaluate
    assert ("--controller agent:runs/agent-gait-ground " in evaluate) is stands
    if stands:
        assert all("--config runs/heldout-ground/chosen-config.json" in line for line in lines[2:4])


def test_the_ground_script_runs_the_studys_variants():
    from krl.agent.studies.designs import STUDIES

    lines = GROUND_SCRIPT.read_text().splitlines()
    (variants,) = [line for line in lines if line.startswith("VARIANTS=")]
    assert variants == f"VARIANTS=({' '.join(v.name for v in STUDIES['gait-ground'].variants)})"
