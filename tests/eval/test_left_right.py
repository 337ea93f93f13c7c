"""``krl report``'s left-right differences: left push success minus right, with Newcombe's 95 % interval."""

import math

import numpy as np
import pytest

from krl.eval import evaluate, summaries, sweep_report
from krl.eval.summaries import SUCCESS_CONFIDENCE_Z, difference_interval


def test_the_difference_interval_by_hand():
    # 10 of 10 against 0 of 10: Wilson gives 10/(10 + z²) to 1 and 0 to z²/(10 + z²), so Newcombe's hybrid
    # score interval is 1 - sqrt((1 - 10/(10 + z²))² + (z²/(10 + z²))²) = 1 - √2 z²/(10 + z²) to 1 + 0
    z2 = SUCCESS_CONFIDENCE_Z**2
    low, high = difference_interval(10, 10, 0, 10)
    assert low == pytest.approx(1 - math.sqrt(2) * z2 / (10 + z2)) and low == pytest.approx(0.6075, abs=1e-4)
    assert high == 1.0
    # Newcombe (1998), Statistics in Medicine 17:873-890, Table II, method 10: 56/70 - 48/80 and 5/56 - 0/29
    assert difference_interval(56, 70, 48, 80) == pytest.approx((0.0524, 0.3339), abs=5e-5)
    assert difference_interval(5, 56, 0, 29) == pytest.approx((-0.0381, 0.1926), abs=5e-5)
    swapped = difference_interval(48, 80, 56, 70)  # the other way round: the same interval, negated
    assert swapped == pytest.approx((-0.3339, -0.0524), abs=5e-5)
    with pytest.raises(ValueError, match="successes <= attempts"):
        difference_interval(3, 2, 1, 2)


def record(azimuth_deg, success, magnitude=400.0, directions=None):
    """A push attempt's record: a force at ``azimuth_deg`` from the heading (0: the walk, +x)."""
    azimuth = np.radians(azimuth_deg)
    force = [magnitude * np.cos(azimuth), magnitude * np.sin(azimuth), 30.0]
    sweep = {"target": [3.0, 0.0], **({"directions": directions} if directions else {})}
    push = {"force": force, "impulse": magnitude * 0.06, "delta_v": magnitude * 0.06 / 12.46}
    metrics = {"success": success, "fell": not success, "error": None, "push_heading": 0.0, "push": push}
    return {"sweep": sweep, "magnitude": magnitude, "metrics": metrics}


def test_left_minus_right_per_force_band_and_controller():
    left = [record(90, a < 3) for a in range(4)] + [record(80, False, magnitude=800.0)] * 2
    right = [record(-90, a < 1) for a in range(4)]
    found = {
        "agent-rp": {evaluate.PUSH_DIR: [*left, *right, record(0, True)]},
        "kernel-base": {evaluate.PUSH_DIR: [record(90, True, directions="balanced")]},  # no right push
    }
    rows = {(r["controller"], r["forces"]): r for r in sweep_report.push_left_right_rows(found)}
    assert set(rows) == {("agent-rp", "all"), ("agent-rp", "350-600")}  # a side without attempts: no row
    every, band = rows["agent-rp", "all"], rows["agent-rp", "350-600"]
    assert (every["left_attempts"], every["left_success_rate"]) == (6, 0.5)  # the 800 N pushes count here
    assert (band["left_attempts"], band["left_success_rate"]) == (4, 0.75)  # and not here
    assert (band["right_attempts"], band["right_success_rate"]) == (4, 0.25)
    assert band["difference"] == 0.5 and band["directions"] == "uniform"
    assert (band["difference_low"], band["difference_high"]) == difference_interval(3, 4, 1, 4)
    table = sweep_report.push_left_right_markdown(list(rows.values()))
    low, high = difference_interval(3, 4, 1, 4)
    assert "| agent-rp (uniform) | +0.25 (3/6 - 1/4), " in table
    assert f"| +0.50 (3/4 - 1/4), {low:+.2f} to {high:+.2f} |" in table
    assert "Newcombe's hybrid score interval" in table


def test_the_report_writes_the_left_right_table_after_the_direction_tables(tmp_path):
    records = [record(90, True, directions="balanced"), record(-90, False, directions="balanced")]
    parts, written, _, _ = sweep_report.write_sweep_sections({"x": {evaluate.PUSH_DIR: records}}, tmp_path)
    text = "\n".join(parts)
    assert text.index("### Push success by direction") < text.index("### Left minus right")
    assert "| x (balanced) | +1.00 (1/1 - 0/1), " in text
    assert str(tmp_path / "push-left-right.csv") in written
    header = (tmp_path / "push-left-right.csv").read_text().splitlines()[0]
    assert header.startswith("controller,forces,directions,left_attempts,left_successes,left_success_rate")


def test_the_summary_of_a_sweep_gives_left_minus_right():
    row = summaries.summarise_push_left_right([record(90, True), record(-90, True), record(-90, False)])
    assert (row["left_attempts"], row["right_attempts"], row["difference"]) == (1, 2, 0.5)
    assert summaries.summarise_push_left_right([record(90, True)]) is None
