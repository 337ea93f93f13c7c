"""examples/robust/agent-robust.sh against a stand-in ``krl`` that logs its arguments: the pilot and its
choice, the winner's run going on as sym's seed 150, the arms' configs and runs in order, the held-out
rule deciding whether agent-robust's seeds train, both evaluations and the sample-efficiency curves, then
rp-sym and its evaluation."""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import pytest
from script_stand_in import check_restore, run_logged
from script_stand_in import line_index as _index

SCRIPT = Path(__file__).resolve().parents[2] / "examples" / "robust" / "agent-robust.sh"

STAND_IN = r"""#!/usr/bin/env bash
# logs its arguments; heldout --choose writes a choice (the pilot's: $PILOT_CHOICE); train makes its --out
echo "$*" >> "$LOG"
out=$(echo "$*" | sed -E 's/.*--out ([^ ]+).*/\1/')
if [ "$1 $2" = "agent train" ]; then mkdir -p "$out"; fi
if [ "$1 $2" = "agent heldout" ]; then
  mkdir -p "$out"
  chosen=sym-curriculum; case "$out" in *pilot) chosen=$PILOT_CHOICE;; esac
  echo "{\"chosen\": \"$chosen\", \"baseline\": {\"stands\": $STANDS}}" > "$out/choice.json"
  echo "{\"ppo\": {\"symmetry\": \"$PILOT_CHOICE\"}, \"env\": {\"pushes\": true}}" > "$out/chosen-config.json"
fi
"""


def _run(tmp_path: Path, stands: str) -> list[str]:
    return run_logged(
        SCRIPT,
        tmp_path,
        STAND_IN,
        PILOT_CHOICE="loss",
        STANDS=stands,
        RUNS="runs",
        EVAL="evals",
        REPORT="report",
        COMMITTED=str(tmp_path / "committed"),
    )


def test_committed_run_folders_go_on_from_where_they_stopped(tmp_path):
    check_restore(
        tmp_path, lambda: _run(tmp_path, "true"), "robust", "agent-robust", "sym-seed215", "sym-seed150"
    )


@pytest.mark.parametrize("stands", ["true", "false"])
def test_the_pipeline_runs_the_pre_registered_steps_in_order(tmp_path, stands):
    lines = _run(tmp_path, stands)
    pilot = _index(lines, "agent heldout", "--choose augment,loss")
    assert _index(lines, "pilot-augment-seed150", "--steps 4000000") < pilot
    assert not (tmp_path / "runs/robust/pilot-loss-seed150").exists()  # the winner goes on as sym's 150
    assert (tmp_path / "runs/robust/sym-seed150").is_dir()

    def pair(out: str) -> list[int]:
        return sorted(_index(lines, f"--out {out}{seed} ") for seed in (150, 215))

    candidates = [pair(f"runs/robust/{arm}-seed") for arm in ("sym", "curriculum", "sym-curriculum")]
    assert pilot < candidates[0][0]
    configs = tmp_path / "runs/robust/configs"
    assert json.loads((configs / "rp-sym.json").read_text())["ppo"]["symmetry"] == "loss"
    assert json.loads((configs / "sym-curriculum.json").read_text())["env"]["push_curriculum"] is True
    rule = _index(lines, "--choose sym,curriculum,sym-curriculum", "--baseline baseline", "broad-pushes.json")
    robust_seeds = [i for i, line in enumerate(lines) if "--out runs/agent-robust/seed" in line]
    assert len(robust_seeds) == (2 if stands == "true" else 0)
    # a pair at a time: the candidates, the rule, agent-robust's seeds where it stands, the evaluation; then
    # rp-sym, which nothing before reads, and its evaluation
    steps = [*candidates, [rule, rule], *([robust_seeds] if robust_seeds else [])]
    assert all(earlier[1] < later[0] for earlier, later in itertools.pairwise(steps))
    evaluations = [i for i, line in enumerate(lines) if "evaluate" in line and "--out evals " in line]
    balanced = [i for i, line in enumerate(lines) if "--push-directions balanced --attempts 48" in line]
    reports = [
        i for i, line in enumerate(lines) if "report --results evals-balanced --out report-balanced" in line
    ]
    assert len(evaluations) == len(balanced) == len(reports) == 2
    curves = _index(lines, "agent curves", "--reach baseline", "--group sym=runs/robust/sym-seed150,")
    rp_sym = pair("runs/robust/rp-sym-seed")
    curves_rp = _index(
        lines, "agent curves", "--reach agent-rp", "--group rp-sym=runs/robust/rp-sym-seed150,"
    )
    assert steps[-1][1] < evaluations[0] < balanced[0] < reports[0] < curves < rp_sym[0]
    assert rp_sym[1] < evaluations[1] < balanced[1] < reports[1] < curves_rp
    assert ("--controller agent:runs/agent-robust " in lines[evaluations[0]]) == (stands == "true")
    assert "rp-sym" not in lines[evaluations[0]] and "rp-sym" not in lines[balanced[0]]
    assert "agent:runs/robust/rp-sym-seed*" in lines[evaluations[1]]
    assert "--out report/curves" in lines[curves]
    assert "pyramids-pushes-seed215 " in lines[curves] and "agent-rp-seed556 " in lines[curves_rp]
    # 7. where agent-robust was trained, left and right again with 100 distinct pushes per quarter, last
    left_right = [i for i, line in enumerate(lines) if "--out evals-left-right " in line]
    assert len(left_right) == (1 if stands == "true" else 0)
    if left_right:
        line = lines[left_right[0]]
        assert (
            "--controller agent:runs/agent-robust --controller agent:gait-ground --controller expert " in line
        )
        assert "--push-directions balanced --magnitudes 350:600:50 --attempts 400 " in line
        assert (
            curves_rp
            < left_right[0]
            < _index(lines, "report --results evals-left-right --out report-left-right")
        )
