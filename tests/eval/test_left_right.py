"""``krl report``'s left-right differences: left push success minus right, with Newcombe's 95 % interval
and the interval that resamples the distinct pushes."""

import math

import numpy as np
import pytest

from krl.eval import evaluate, summaries, sweep_report
from krl.eval.summaries import SUCCESS_CONFIDENCE_Z, cluster_difference_interval, difference_interval


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


def record(azimuth_deg, success, magnitude=400.0, directions=None, attempt=0):
    """Attempt ``attempt``'s record: a force at ``azimuth_deg`` from the heading (0: the walk, +x)."""
    azimuth = np.radians(azimuth_deg)
    force = [magnitude * np.cos(azimuth), magnitude * np.sin(azimuth), 30.0]
    sweep = {"target": [3.0, 0.0], **({"directions": directions} if directions else {})}
    push = {"force": force, "impulse": magnitude * 0.06, "delta_v": magnitude * 0.06 / 12.46}
    metrics = {"success": success, "fell": not success, "error": None, "push_heading": 0.0, "push": push}
    return {"sweep": sweep, "magnitude": magnitude, "attempt": attempt, "metrics": metrics}


def test_left_minus_right_per_force_band_and_controller():
    left = [record(90, a < 3, attempt=a) for a in range(4)] + [record(80, False, magnitude=800.0)] * 2
    right = [record(-90, a < 1, attempt=a) for a in range(4)]
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
    assert (every["left_pushes"], band["left_pushes"], band["right_pushes"]) == (4, 4, 4)  # 800 N: attempt 0
    pushes = cluster_difference_interval([(1, 1)] * 3 + [(0, 1)], [(1, 1)] + [(0, 1)] * 3)
    assert (band["difference_low_pushes"], band["difference_high_pushes"]) == pushes
    table = sweep_report.push_left_right_markdown(list(rows.values()))
    low, high = difference_interval(3, 4, 1, 4)
    assert "| agent-rp (uniform) | +0.25 (3/6 - 1/4), " in table
    by_push = f"pushes 4/4: {pushes[0]:+.2f} to {pushes[1]:+.2f}"
    assert f"| +0.50 (3/4 - 1/4), {low:+.2f} to {high:+.2f}; {by_push} |" in table
    assert "Newcombe's hybrid score interval" in table
    assert "a 95 % bootstrap interval that resamples these pushes" in table and "the one to read" in table


def test_the_report_writes_the_left_right_table_after_the_direction_tables(tmp_path):
    records = [record(90, True, directions="balanced"), record(-90, False, directions="balanced")]
    parts, written, _, _, _ = sweep_report.write_sweep_sections({"x": {evaluate.PUSH_DIR: records}}, tmp_path)
    text = "\n".join(parts)
    assert text.index("### Push success by direction") < text.index("### Left minus right")
    assert "| x (balanced) | +1.00 (1/1 - 0/1), " in text
    assert str(tmp_path / "push-left-right.csv") in written
    header = (tmp_path / "push-left-right.csv").read_text().splitlines()[0]
    assert header.startswith("controller,forces,directions,left_attempts,left_successes,left_success_rate")
    pushes = "left_pushes,right_pushes,difference_low_pushes,difference_high_pushes"
    assert header.endswith(f",difference_high,{pushes}")  # after the columns it had


def test_the_summary_of_a_sweep_gives_left_minus_right():
    row = summaries.summarise_push_left_right([record(90, True), record(-90, True), record(-90, False)])
    assert (row["left_attempts"], row["right_attempts"], row["difference"]) == (1, 2, 0.5)
    assert summaries.summarise_push_left_right([record(90, True)]) is None


def replayed(pushes, replays):
    """Records of ``pushes`` distinct pushes a side, each met ``replays`` times (forces and seeds): left push
    ``a`` succeeds every time for even ``a``, a quarter of the times for odd; right push ``a`` the other way
    round."""
    records = []
    for a in range(pushes):
        records += [record(90, r % 4 == 0 or a % 2 == 0, attempt=a) for r in range(replays)]
        records += [record(-90, r % 4 == 0 or a % 2 == 1, attempt=a) for r in range(replays)]
    return records


def test_the_pushes_interval_counts_distinct_pushes_not_their_replays():
    few = summaries.summarise_push_left_right(replayed(4, 48))  # 192 attempts a side, 4 distinct pushes
    assert (few["left_attempts"], few["left_pushes"], few["right_pushes"]) == (192, 4, 4)
    assert few["difference"] == 0
    newcombe = few["difference_high"] - few["difference_low"]
    pushes = few["difference_high_pushes"] - few["difference_low_pushes"]
    assert newcombe < 0.2 and pushes > 3 * newcombe  # 4 pushes a side are too few to tell the sides apart
    many = summaries.summarise_push_left_right(replayed(64, 3))  # as many attempts, 64 pushes a side
    assert (many["left_attempts"], many["left_pushes"], many["difference"]) == (192, 64, 0)
    assert many["difference_high_pushes"] - many["difference_low_pushes"] < pushes / 3


def test_the_pushes_interval_is_deterministic_and_weighs_each_push_by_its_runs():
    left, right = [(3, 5), (0, 4), (5, 5), (1, 6)], [(2, 2), (0, 3), (4, 7)]
    first = cluster_difference_interval(left, right)
    assert cluster_difference_interval(left, right) == first and -1 < first[0] < first[1] < 1
    assert cluster_difference_interval([(4, 4), (2, 2)], [(0, 3), (0, 1)]) == (1.0, 1.0)  # no spread
    # one failing run against 9 pushes each of 100 successes: a resample's left rate is all its successes
    # over all its runs, at least 700/703 but where it drew the failure 4 times or more (1.3 % of them)
    low, high = cluster_difference_interval([(0, 1)] + [(100, 100)] * 9, [(0, 5), (0, 5)])
    assert 0.99 < low and high == 1.0  # the mean of the pushes' rates would go down to 0.7
    with pytest.raises(ValueError, match="successes <= runs"):
        cluster_difference_interval([(3, 2), (1, 2)], [(1, 2), (1, 2)])


def test_a_side_with_one_distinct_push_gives_the_whole_range():
    # attempt 0 went left for one seed and right for another (a uniform draw, turned by the heading): a
    # left push and a right push; the left side has no other, so the pushes tell nothing of the difference
    records = [record(90, True, attempt=0)] * 10 + [record(-90, a % 2 == 0, attempt=a) for a in range(5)]
    row = summaries.summarise_push_left_right(records)
    assert (row["left_pushes"], row["right_pushes"]) == (1, 5)
    assert (row["difference_low_pushes"], row["difference_high_pushes"]) == (-1.0, 1.0)
    assert row["difference_low"] > 0  # while Newcombe's, taking 10 left runs as independent, is above 0
    assert cluster_difference_interval([(1, 2), (0, 2)], [(1, 2)]) == (-1.0, 1.0)
