"""The stair sweep: its flights, its rows (riser, direction, success, fall, inside the training range),
the report's section and the CLI's refusals."""

from __future__ import annotations

import numpy as np
import pytest

from krl.cli import main
from krl.eval.stair_sweep import STAIR_TARGET_DOWN, STAIR_TARGET_UP, StairSweep, flight
from krl.eval.summaries import summarise_stairs
from krl.eval.sweep_report import stairs_markdown


def test_each_flight_climbs_to_its_landing_and_descends_past_its_foot():
    for riser in (0.04, 0.14):
        up, down = flight(riser, "up"), flight(riser, "down")
        terrain = up.build().terrain
        landing = 5 * riser
        assert terrain.height(*STAIR_TARGET_UP) == pytest.approx(landing)
        assert terrain.height(*STAIR_TARGET_DOWN) == 0.0
        assert all(terrain.height(x, y) == 0.0 for x, y, _ in up.starts)
        assert all(terrain.height(x, y) == pytest.approx(landing) for x, y, _ in down.starts)
        xs = np.linspace(0.0, 2.5, 251)
        assert np.isclose(np.diff(terrain.height(xs, 0.0)), riser).sum() == 5  # five risers up
    assert [(r, d) for r, d, _ in StairSweep((0.06, 0.1)).courses()] == [
        (0.06, "up"),
        (0.06, "down"),
        (0.1, "up"),
        (0.1, "down"),
    ]


def _record(riser, direction, success, fell, trained=None, seed=None):
    metrics = {"success": success, "fell": fell, "targets_reached": int(success), "error": None}
    stair = {"riser": riser, "direction": direction, "trained_risers": trained}
    return {"stair": stair, "seed": seed, "metrics": metrics}


def test_rows_pool_runs_and_say_whether_a_riser_was_trained_on():
    records = [
        _record(0.14, "up", False, True, [0.03, 0.12]),
        _record(0.04, "down", True, False, [0.03, 0.12]),
        _record(0.04, "up", True, False, [0.03, 0.12]),
        _record(0.04, "up", False, False, [0.03, 0.12]),
    ]
    rows = summarise_stairs(records)
    assert [(r["riser"], r["direction"], r["runs"]) for r in rows] == [
        (0.04, "up", 2),
        (0.04, "down", 1),
        (0.14, "up", 1),
    ]
    assert rows[0]["success_rate"] == 0.5 and rows[2]["fall_rate"] == 1.0
    assert [r["in_training"] for r in rows] == [True, True, False]
    text = stairs_markdown([{"controller": "agent-x", **row} for row in rows])
    assert "| agent-x | 0.50 / 0.00 (2) | 0.00 / 1.00 (1)† | 3-12 cm |" in text
    untrained = summarise_stairs([_record(0.04, "up", True, False)])
    assert untrained[0]["in_training"] is None and untrained[0]["trained_risers"] is None


@pytest.mark.parametrize(
    ("risers", "message"), [("4,x", "--risers expects"), ("4,40", "out of range"), ("6,6", "distinct")]
)
def test_bad_risers_are_refused_in_one_line(tmp_path, capsys, risers, message):
    out = tmp_path / "out"
    code = main(
        ["evaluate", "--controller", "kernel", "--stair-sweep", "--risers", risers, "--out", str(out)]
    )
    error = capsys.readouterr().err
    assert code != 0 and message in error and len(error.strip().splitlines()) == 1
    assert not out.exists()
