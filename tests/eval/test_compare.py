"""krl compare-results: equal records are equal, a rounding difference is measured, a moved outcome named."""

from __future__ import annotations

import json

from eval_fakes import complete_record

from krl.cli import main
from krl.eval import records
from krl.eval.compare import compare_records, flatten


def record(run, success=True, reward=0.1, wall=1.0):
    """A complete record of agent-rp's run ``run`` on stairs."""
    metrics = {"success": success, "fell": not success, "targets_reached": 5 if success else 2}
    metrics.update(reward_per_step=reward, wall_seconds=wall, reward_terms={"gravity": reward * 10})
    return complete_record({"course": "stairs", "run": run, "metrics": metrics}, "agent-rp")


def test_fields_are_flattened_and_wall_time_ignored():
    assert flatten({"a": {"b": [1, 2]}, "c": None}) == {"a.b.0": 1, "a.b.1": 2, "c": None}
    assert compare_records(record("stairs/start0"), record("stairs/start0", wall=9.0)) == {}
    nan = record("stairs/start0", reward=float("nan"))
    assert compare_records(nan, record("stairs/start0", reward=float("nan"))) == {}


def test_a_record_older_than_its_ending_compares_by_its_outcome():
    old = record("stairs/start0")  # made before metrics.ended existed
    new = record("stairs/start0")
    new["metrics"]["ended"] = "finished"
    assert compare_records(old, new) == {}
    new["metrics"]["ended"] = "timed_out"  # a record that says otherwise still differs
    assert compare_records(old, new) == {"metrics.ended": ["finished", "timed_out"]}
    fallen = record("stairs/start0", success=False)
    assert compare_records(fallen, new)["metrics.ended"] == ["fell", "timed_out"]


def test_folders_compare_run_by_run(tmp_path, capsys):
    first, second = tmp_path / "first", tmp_path / "second"
    runs = [f"stairs/start{k}" for k in range(4)]
    records.write_part(first / "agent-rp", "agent-rp", [record(run) for run in runs])
    assert main(["compare-results", str(first), str(first), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["identical"] is True
    changed = [record(runs[0], reward=0.1 + 1e-15), record(runs[1], success=False), record(runs[2], wall=5.0)]
    records.write_part(second / "agent-rp", "agent-rp", changed)
    assert main(["compare-results", str(first), str(second), "--json"]) == 1
    comparison = json.loads(capsys.readouterr().out)
    assert (comparison["equal"], comparison["different"]) == (1, 2)
    assert comparison["only_first"] == ["agent-rp stairs/start3"] and comparison["only_second"] == []
    assert comparison["outcomes_moved"] == ["agent-rp stairs/start1"]
    assert 0 < comparison["largest_difference"]["metrics.reward_per_step"] < 0.1
    assert comparison["changed_fields"] == ["metrics.ended", "metrics.fell", "metrics.success"]  # listed
    assert comparison["identical"] is False
    assert main(["compare-results", str(first), str(tmp_path / "nowhere")]) == 2
    assert "no results folder" in capsys.readouterr().err


def test_the_machines_are_listed_not_compared(tmp_path, capsys):
    blas = {"library": "openblas", "version": "0.3.31", "architecture": "Haswell"}
    here = {"cpu": "AMD EPYC", "blas": [blas]}
    there = {**here, "blas": [{**blas, "architecture": "SkylakeX"}]}
    first, second, unsaid = tmp_path / "first", tmp_path / "second", tmp_path / "unsaid"
    records.write_part(first / "agent-rp", "agent-rp", [{**record("stairs/start0"), "machine": here}])
    records.write_part(second / "agent-rp", "agent-rp", [{**record("stairs/start0"), "machine": there}])
    records.write_part(unsaid / "agent-rp", "agent-rp", [record("stairs/start0")])  # made before records said
    assert main(["compare-results", str(first), str(second), "--json"]) == 0
    comparison = json.loads(capsys.readouterr().out)
    assert comparison["machines"] == {"first": [here], "second": [there]}
    assert comparison["same_machine"] is False and comparison["identical"] is True
    assert main(["compare-results", str(first), str(first), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["same_machine"] is True
    assert main(["compare-results", str(first), str(unsaid), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["same_machine"] is None
