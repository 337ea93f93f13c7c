"""examples/perceptive/agent-perceptive.sh against a stand-in ``krl`` that logs its arguments: committed runs
restored, the six runs two at a time in docs/agent-perceptive.md's order, the held-out rule deciding whether
the winner's other two seeds train, then the evaluation of every run, the report and the push faces."""

from __future__ import annotations

import itertools
from pathlib import Path

import pytest
from script_stand_in import check_restore, run_logged
from script_stand_in import line_index as _index

SCRIPT = Path(__file__).resolve().parents[2] / "examples" / "perceptive" / "agent-perceptive.sh"

STAND_IN = r"""#!/usr/bin/env bash
# logs its arguments; train makes its --out; heldout writes a choice that stands where $STANDS is true
echo "$*" >> "$LOG"
out=$(echo "$*" | sed -E 's/.*--out ([^ ]+).*/\1/')
if [ "$1 $2" = "agent train" ]; then mkdir -p "$out"; fi
if [ "$1 $2" = "agent heldout" ]; then
  mkdir -p "$out"
  echo "{\"chosen\": \"scan-critic\", \"baseline\": {\"stands\": $STANDS}}" > "$out/choice.json"
  echo "{}" > "$out/chosen-config.json"
fi
"""


def _run(tmp_path: Path, stands: str) -> list[str]:
    return run_logged(
        SCRIPT,
        tmp_path,
        STAND_IN,
        STANDS=stands,
        RUNS="runs",
        EVAL="evals",
        REPORT="report",
        COMMITTED=str(tmp_path / "committed"),
    )


def test_committed_run_folders_go_on_from_where_they_stopped(tmp_path):
    check_restore(
        tmp_path,
        lambda: _run(tmp_path, "true"),
        "perceptive",
        "agent-perceptive",
        "scan-seed150",
        "scan-critic-seed150",
    )


@pytest.mark.parametrize("stands", ["true", "false"])
def test_the_pipeline_runs_the_pre_registered_steps_in_order(tmp_path, stands):
    lines = _run(tmp_path, stands)

    def run(arm: str, seed: int) -> int:
        return _index(lines, "agent train", f"--out runs/perceptive/{arm}-seed{seed} ", f"{arm}.json")

    pairs = [
        sorted([run("scan-critic", 150), run("scan", 150)]),
        sorted([run("blind-curriculum", 150), run("scan-critic", 215)]),
        sorted([run("scan", 215), run("blind-curriculum", 215)]),
    ]
    choose = "--choose blind-curriculum,scan,scan-critic"
    rule = _index(lines, "agent heldout", choose, "--baseline agent-robust")
    assert "heldout-ground.json" in lines[rule] and "--seed-group runs/agent-perceptive" in lines[rule]
    winner = [i for i, line in enumerate(lines) if "--out runs/agent-perceptive/seed" in line]
    assert len(winner) == (2 if stands == "true" else 0)
    evaluation = _index(lines, "evaluate", "--out evals ")
    balanced = _index(lines, "evaluate", "--push-directions balanced --attempts 48", "--out evals-balanced ")
    steps = [*pairs, [rule, rule], *([sorted(winner)] if winner else []), [evaluation, evaluation]]
    assert all(earlier[1] < later[0] for earlier, later in itertools.pairwise(steps))
    reports = [_index(lines, "report --results evals --out report"), _index(lines, "--out report-balanced")]
    faces = _index(lines, "analyze push-sweep evals-balanced --out report-balanced/push-faces")
    assert evaluation < balanced < reports[0] < reports[1] < faces == len(lines) - 1
    line = lines[evaluation]
    sweeps = ("--course thesis --course harder --stair-sweep", "--push-sweep --attempts 50", "--friction")
    assert all(part in line for part in sweeps)
    for arm in ("blind-curriculum", "scan", "scan-critic"):
        assert f"--controller agent:runs/perceptive/{arm}-seed*" in line
    for baseline in ("agent:robust", "--controller agent ", "kernel:ext", "--controller expert"):
        assert baseline in line
    assert ("--controller agent:runs/agent-perceptive " in line) == (stands == "true")
    assert line.count("--controller") == lines[balanced].count("--controller")
