"""The push sweep's records read two more ways: which pushes some controller seed survives (headroom), and
success by the face of the trunk struck."""

from __future__ import annotations

import math

import pytest
from eval_fakes import complete_record

from krl.analysis.push_faces import face_of, face_rows, parse_band
from krl.analysis.push_headroom import headroom_rows, push_outcomes
from krl.cli import main
from krl.eval.records import write_part

SWEEP = {
    "attempts": 2,
    "seed": 0,
    "directions": "uniform",
    "window": [2.0, 5.0],
    "target": [3.0, 0.0],
    "d_min": 0.5,
}


def push_record(
    label, magnitude, attempt, seed, success, sweep=SWEEP, force=(0.0, 100.0, 0.0), point=(0, 0, 0.057)
):
    """A push-sweep record as krl evaluate writes it, reduced to what these analyses read (by default a push
    to the left, on the trunk's top)."""
    return {
        "format": 1,
        "controller": {"kind": "agent", "label": label},
        "sweep": dict(sweep),
        "magnitude": magnitude,
        "attempt": attempt,
        "seed": seed,
        "run": f"push/m{magnitude:g}-a{attempt}" + ("" if seed is None else f"-seed{seed}"),
        "metrics": {
            "success": success,
            "fell": not success,
            "push_heading": 0.0,
            "push": {"force": list(force), "point": list(point)},
        },
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


def test_a_point_on_the_trunk_lies_on_its_face():
    assert [
        face_of(p) for p in ((0.0, 0.0, 0.057), (0.1, 0.05, -0.057), (0.0, -0.097, 0.0), (0.1335, 0, 0))
    ] == [
        "top",
        "bottom",
        "sides",
        "ends",
    ]


def test_pushes_are_split_by_direction_and_face_per_force_band():
    """Sideways pushes on the top at 400 N: 3 of 4 survived; along (forward) on the bottom at 800 N: 0 of 1;
    a push at 300 N is in no band."""
    records = [push_record("agent", 400.0, a, 1, a != 0) for a in range(4)]
    records.append(push_record("agent", 800.0, 0, 1, False, force=(100.0, 0.0, 0.0), point=(0, 0, -0.057)))
    records.append(push_record("agent", 300.0, 0, 1, False))
    rows = {(r["direction"], r["face"]): r for r in face_rows({"agent": {"push": records}}, ["agent"])}
    assert rows[("sideways", "top")]["agent/350-600/success_rate"] == 0.75
    assert rows[("sideways", "top")]["agent/350-600/attempts"] == 4
    assert rows[("along", "bottom")]["agent/650-900/success_rate"] == 0.0
    assert rows[("sideways", "top")]["agent/650-900/success_rate"] is None
    assert sum(row[key] for row in rows.values() for key in row if key.endswith("/attempts")) == 5
    with pytest.raises(ValueError, match="--controller 'nobody': no push-sweep records"):
        face_rows({"agent": {"push": records}}, ["nobody"])


def test_a_band_is_low_colon_high_newtons():
    assert parse_band("350:600") == (350.0, 600.0)
    for text in ("600:350", "350", "a:b", "-1:5", "nan:5"):
        with pytest.raises(ValueError, match=f"--band {text!r}: expected LOW:HIGH"):
            parse_band(text)


def test_the_command_reads_a_results_folder_and_writes_both_tables(tmp_path, capsys):
    """``krl analyze push-sweep``: both tables, written or printed; a bad option value or folder is one line
    on stderr and exit status 2."""
    for label, records in found_of(OUTCOMES).items():
        write_part(tmp_path / "results" / label, label, [complete_record(r, label) for r in records["push"]])
    out = tmp_path / "push-sweep.md"
    command = ["analyze", "push-sweep", str(tmp_path / "results")]
    assert main([*command, "--controller", "agent", "--controller", "expert", "--out", str(out)]) == 0
    text = out.read_text()
    assert "survived by some of the 3 controller seeds | agent (2 seeds): mean | some seed |" in text
    assert "| 400 | 2 | 1.00 | 0.75 | 1.00 | 0.50 | 1.00 | 0.50 |" in text
    assert "| mean |  | 0.75 | 0.38 | 0.50 | 0.25 | 0.50 | 0.50 |" in text
    assert "| sideways | top | 0.75 (4) | 0.00 (4) | 0.50 (2) | 0.50 (2) |" in text
    capsys.readouterr()
    assert main([*command, "--seeds", "2"]) == 0  # agent's seed 2 and the expert, printed
    text = capsys.readouterr().out
    assert "(seeds 2)" in text and "agent (1 seed): mean" in text and "some of the 2 controller seeds" in text
    assert "| 400 | 2 | 1.00 | 1.00 | 0.50 |" in text  # some of the two; seed 2; the expert
    for argv, message in (
        ([*command, "--seeds", "2,x"], "--seeds expects comma-separated integers, got '2,x'"),
        ([*command, "--controller", "nobody"], "--controller 'nobody': not in"),
        ([*command, "--band", "9:1"], "--band '9:1': expected LOW:HIGH"),
        (["analyze", "push-sweep", str(tmp_path / "nowhere")], "no results directory"),
    ):
        assert main(argv) == 2
        error = capsys.readouterr().err
        assert error.startswith("krl: error: ") and message in error and error.count("\n") == 1
