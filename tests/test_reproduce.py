"""``krl reproduce``: every planned command parses; done steps are skipped; a failure stops and resumes;
docs/reproduce.md shows the plan as it is."""

from __future__ import annotations

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
        assert sum(step.minutes for step in steps) < 60


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
    assert (runs / "quick" / "agent-rp.json").is_file()
    assert lines[-1] == "everything is reproduced"


def test_dry_run_prints_the_plan(tmp_path, capsys):
    assert main(["reproduce", "--quick", "--dry-run", "--runs", str(tmp_path)]) == 0
    printed = capsys.readouterr().out
    assert "collect-base" in printed and "left: about" in printed
    assert not (tmp_path / "quick").exists()


@pytest.mark.parametrize("quick", [False, True])
def test_the_documented_tables_are_the_plan(quick):
    """docs/reproduce.md's table for the mode holds each step, in order, and the total of the defaults'."""
    text = (Path(__file__).resolve().parents[1] / "docs" / "reproduce.md").read_text()
    table = text.split("## Quick")[1 if quick else 0]
    rows = [line for line in table.splitlines() if line.startswith("| ") and line[2].isdigit()]
    steps = plan(Path("runs/reproduce"), Path("docs"), quick)
    assert rows == [
        f"| {number} | `{step.name}` | {step.makes} | {step.minutes:g} | `{step.command}` |"
        for number, step in enumerate(steps, start=1)
    ]
    assert f"Total: about {sum(step.minutes for step in steps):.0f} min." in table
