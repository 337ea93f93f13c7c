"""Scoring a run: a point robot walks through five waypoints, reaches three and falls."""

import numpy as np
import pytest
from eval_fakes import PointSim, StandStill

from krl.eval.episodes import RUN_METRICS, PushSweep, score_walk

WAYPOINTS = np.array([[1.0, 0.0], [2.0, 0.0], [3.0, 0.0], [4.0, 0.0], [5.0, 0.0]])


def test_three_of_five_then_a_fall_scores_exactly_that():
    # x = 0.25 k after step k: waypoint i (x = i + 1) is within 0.5 m at x = i + 0.75, i.e. steps 3, 7, 11;
    # the robot falls on step 13 (x = 3.25), 0.75 m short of the fourth waypoint.
    sim = PointSim(speed_per_step=0.25, fall_at=13)
    metrics = score_walk(sim, StandStill(), WAYPOINTS, (0.0, 0.0, 0.0), time_limit=60.0, d_min=0.5)
    assert list(metrics) == list(RUN_METRICS)
    assert metrics["targets"] == 5
    assert metrics["targets_reached"] == 3
    assert metrics["fell"] is True and metrics["success"] is False
    assert metrics["timed_out"] is False and metrics["error"] is None and metrics["ended"] == "fell"
    assert metrics["steps"] == 13
    assert metrics["distance_walked"] == pytest.approx(3.25)
    assert metrics["time_to_finish"] is None
    terms = metrics["reward_terms"]
    assert terms["target_reached"] == pytest.approx(3 * 8.75)
    assert terms["fall"] == pytest.approx(-19.8)
    assert terms["gravity"] == pytest.approx(13 * 0.0298)  # level all the way
    assert metrics["reward_total"] == pytest.approx(sum(terms.values()))
    assert metrics["reward_per_step"] == pytest.approx(metrics["reward_total"] / 13)


def test_every_waypoint_is_a_success_with_its_time():
    metrics = score_walk(PointSim(0.25), StandStill(), WAYPOINTS, (0.0, 0.0, 0.0), 60.0, 0.5)
    # the last waypoint (x = 5) is within 0.5 m at x = 4.75: step 19
    assert metrics["targets_reached"] == 5 and metrics["success"] is True and metrics["fell"] is False
    assert metrics["ended"] == "finished"
    assert metrics["steps"] == 19
    assert metrics["time_to_finish"] == pytest.approx(19 * 0.005)


def test_the_course_time_limit_ends_the_run():
    metrics = score_walk(PointSim(0.25), StandStill(), WAYPOINTS, (0.0, 0.0, 0.0), time_limit=0.04, d_min=0.5)
    # 0.04 s = 8 control steps: waypoints 1 (step 3) and 2 (step 7) reached, then time is up
    assert metrics["steps"] == 8 and metrics["targets_reached"] == 2
    assert metrics["timed_out"] is True and metrics["success"] is False and metrics["fell"] is False
    assert metrics["ended"] == "timed_out"


def test_a_step_that_passes_two_close_waypoints_counts_both():
    """Issue 46: reaching the first waypoint (step 3, x = 0.75) leaves the robot within D_min of the second
    (x = 1.2), so the task passes both on one step; the walk finishes at the third (step 11, x = 2.75) and
    is a success with every waypoint counted, not a failure one waypoint short."""
    close = np.array([[1.0, 0.0], [1.2, 0.0], [3.0, 0.0]])
    metrics = score_walk(PointSim(0.25), StandStill(), close, (0.0, 0.0, 0.0), 60.0, 0.5)
    assert metrics["targets_reached"] == 3 and metrics["success"] is True
    assert metrics["ended"] == "finished" and metrics["steps"] == 11


def test_a_diverging_simulation_is_recorded_not_raised():
    sim = PointSim(0.25, diverge_at=5)
    metrics = score_walk(sim, StandStill(), WAYPOINTS, (0.0, 0.0, 0.0), 60.0, 0.5)
    assert metrics["error"].startswith("SimulationUnstableError") and metrics["ended"] == "error"
    assert metrics["targets_reached"] == 1 and metrics["success"] is False


def test_push_sweep_attempts_share_their_draws_across_magnitudes():
    sweep = PushSweep()
    assert sweep.magnitudes == tuple(float(m) for m in range(250, 901, 50)) and sweep.attempts == 10
    low, high = sweep.push(250.0, 3), sweep.push(900.0, 3)
    assert low.start_time == high.start_time and np.allclose(low.point, high.point)
    assert np.allclose(low.force / low.magnitude, high.force / high.magnitude)
    assert high.magnitude == pytest.approx(900.0)
    assert sweep.window[0] <= low.start_time <= sweep.window[1]
    assert sweep.push(250.0, 4).start_time != low.start_time


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"attempts": 0}, "attempts"),
        ({"magnitudes": (-5.0,)}, "push magnitude must be"),
        ({"magnitudes": (300.0, 400.0, 300.0)}, "magnitudes must be distinct"),
        ({"window": (1.0, 50.0)}, "window"),
    ],
)
def test_push_sweep_rejects_bad_settings(kwargs, message):
    with pytest.raises(ValueError, match=message):
        PushSweep(**kwargs)
