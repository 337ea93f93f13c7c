"""Push headroom: which pushes of a sweep some controller seed survives, from a results folder's records."""

from __future__ import annotations

import math

import pytest

from krl.analysis.push_headroom import headroom_rows, main, push_outcomes
from krl.eval.records import write_part

SWEEP = {
    "attempts": 2,
    "seed": 0,
    "directions": "uniform",
    "window": [2.0, 5.0],
    "target": [3.0, 0.0],
    "d_min": 0.5,
}


def push_record(label, magnitude, attempt, seed, success, sweep=SWEEP):
    """A push-sweep record as krl evaluate writes it, reduced to what the headroom reads."""
    return {
        "format": 1,
        "controller": {"kind": "agent", "label": label},
        "sweep": dict(sweep),
        "magnitude": magnitude,
        "attempt": attempt,
        "seed": seed,
        "run": f"push/m{magnitude:g}-a{attempt}" + ("" if seed is None else f"-seed{seed}"),
        "metrics": {"success": success, "fell": not success},
    }


def found_of(outcomes):
    """``{label: {"push": [records]}}`` from ``{(label, seed): {(magnitude, attempt): success}}``."""
    found = {}
    for (label, seed), runs in outcomes.items():
        records = [push_record(label, m, a, seed, ok) for (m, a), ok in runs.items()]
        found.setdefault(label, {"push": []})["push"] += records
    return found


# At 400 N: push 0 survived by both agent seeds, push 1 by seed 2 only; the expert survives push 1 only.
# At 800 N: push 0 survived by nobody, push 1 by the expert only.
OUTCOMES = {
    ("agent", 1): {(400.0, 0): True, (400.0, 1): False, (800.0, 0): False, (800.0, 1): False},
    ("agent", 2): {(400.0, 0): True, (400.0, 1): True, (800.0, 0): False, (800.0, 1): False},
    ("expert", None): {(400.0, 0): False, (400.0, 1): True, (800.0, 0): False, (800.0, 1): True},
}


def test_each_push_counts_which_seeds_survived_it():
    rows = headroom_rows(push_outcomes(found_of(OUTCOMES)), ["agent", "expert"])
    low, high, mean = rows
    assert low["magnitude"] == 400.0 and low["pushes"] == 2 and low["controller_seeds"] == 3
    assert low["some_controller"] == 1.0 and high["some_controller"] == 0.5
    assert low["agent/seeds"] == 2 and low["agent/mean"] == 0.75
    assert low["agent/some_seed"] == 1.0 and low["agent/every_seed"] == 0.5
    assert math.isclose(low["agent/independent"], 1.0 - (1.0 - 0.5) * (1.0 - 1.0))
    assert high["agent/some_seed"] == 0.0 and high["expert/mean"] == 0.5
    assert mean["magnitude"] == "mean" and mean["some_controller"] == 0.75 and mean["agent/mean"] == 0.375


def test_pushes_of_other_sweeps_or_missing_records_are_refused():
    found = found_of(OUTCOMES)
    for record in found["expert"]["push"]:
        record["sweep"]["seed"] = 1
    with pytest.raises(ValueError, match="agent and expert walked push sweeps with other settings"):
        push_outcomes(found)
    found = found_of(OUTCOMES)
    found["agent"]["push"].pop()  # seed 2's attempt 1 at 800 N
    with pytest.raises(ValueError, match=r"agent \(seed 2\) has no record of attempt 1 at 800 N"):
        headroom_rows(push_outcomes(found), ["agent"])
    with pytest.raises(ValueError, match="no push-sweep records"):
        push_outcomes({"agent": {"flat": []}})


def test_the_command_reads_a_results_folder_and_writes_its_table(tmp_path, capsys):
    for label, records in found_of(OUTCOMES).items():
        write_part(tmp_path / "results" / label, label, records["push"])
    out = tmp_path / "headroom.md"
    main([str(tmp_path / "results"), "--controller", "agent", "--controller", "expert", "--out", str(out)])
    table = out.read_text()
    assert "survived by some of the 3 controller seeds | agent (2 seeds): mean | some seed |" in table
    assert "| 400 | 2 | 1.00 | 0.75 | 1.00 | 0.50 | 1.00 | 0.50 |" in table
    assert "| mean |  | 0.75 | 0.38 | 0.50 | 0.25 | 0.50 | 0.50 |" in table
    with pytest.raises(SystemExit) as stop:
        main([str(tmp_path / "results"), "--controller", "nobody"])
    assert stop.value.code == 2
    error = capsys.readouterr().err
    assert "--controller 'nobody': not in" in error and error.count("\n") == 1
