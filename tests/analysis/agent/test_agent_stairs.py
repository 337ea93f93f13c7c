"""The stairs diagnosis: its measures on hand-made traces, and one traced run equal to krl evaluate's."""

from __future__ import annotations

import numpy as np
import pytest

from krl.analysis.agent.stairs import command_following, gait_on_stairs, run_summary, stairs_geometry
from krl.eval.courses import load_course
from krl.util.timing import CONTROL_DT

GEOMETRY = {
    "first_riser": 1.0,
    "landing_start": 2.2,
    "landing_end": 3.7,
    "stairs_end": 4.9,
    "half_width": 1.5,
}


def straight_trace(speed: float, yaw_rate: float, seconds: float, command: tuple[float, float, float]):
    """A trunk moving at ``speed`` [m/s] along its heading while turning at ``yaw_rate`` [rad/s]."""
    t = np.arange(round(seconds / CONTROL_DT)) * CONTROL_DT
    yaw = yaw_rate * t
    velocity = speed * np.stack([np.cos(yaw), np.sin(yaw)], axis=1)
    xy = np.cumsum(velocity, axis=0) * CONTROL_DT
    base = np.column_stack([xy, np.full(len(t), 0.3)])
    return {
        "base_pos": base,
        "rpy": np.column_stack([np.zeros((len(t), 2)), yaw]),
        "command": np.tile(command, (len(t), 1)),
        "foot_pos": base[:, None, :]
        + np.array([[0.18, -0.13, -0.3], [0.18, 0.13, -0.3], [-0.18, -0.13, -0.3], [-0.18, 0.13, -0.3]]),
    }


def test_command_following_of_a_steady_turn():
    trace = straight_trace(speed=0.3, yaw_rate=0.2, seconds=16.0, command=(0.4, 0.0, 0.25))
    following = command_following(trace)
    assert following["forward_speed_error"] == pytest.approx(-0.1, abs=2e-3)
    assert following["yaw_rate_gain"] == pytest.approx(0.8, abs=5e-3)


def test_a_run_that_leaves_the_landing_by_its_side():
    trace = straight_trace(speed=0.5, yaw_rate=0.0, seconds=4.0, command=(0.5, 0.0, 0.0))
    trace["base_pos"][:, :2] = np.column_stack(
        [np.full(len(trace["base_pos"]), 3.0), np.linspace(0, 1.8, 800)]
    )
    trace["foot_pos"] = trace["base_pos"][:, None, :] + np.array([0.0, 0.13, -0.3])
    row = run_summary(trace, {"targets_reached": 2, "success": False, "fell": True}, GEOMETRY)
    assert row["fall_xy"] == [3.0, 1.8] and row["fell_past_the_side"] is True
    assert row["landing_max_abs_y_base"] == pytest.approx(1.8)
    assert row["landing_max_abs_y_feet"] == pytest.approx(1.93)


def test_the_gait_inputs_are_averaged_over_the_stairs_only():
    trace = straight_trace(speed=0.5, yaw_rate=0.0, seconds=12.0, command=(0.5, 0.0, 0.0))
    steps = len(trace["base_pos"])  # x runs 0 -> 6 m: over the stairs (1 < x < 4.9) from 2 s to 9.8 s
    trace["time"] = np.arange(steps) * CONTROL_DT
    trace["ground"] = np.zeros((steps, 4))
    trace["gait_inputs"] = np.tile([0.0, 0.0, 0.0, 0.08, 0.25, 1.0], (steps, 1))
    over = (trace["base_pos"][:, 0] > 1.0) & (trace["base_pos"][:, 0] < 4.9)
    trace["gait_inputs"][over, 3] = 0.12  # a higher step over the stairs only
    trace["gait_inputs"][: steps // 2, 5] = 2.0  # the clock fast for the first 6 s
    gait = gait_on_stairs(trace, GEOMETRY)
    assert gait["step_height_on_stairs"] == pytest.approx(0.12)
    assert gait["ride_height_on_stairs"] == pytest.approx(0.25)
    assert gait["clock_rate_on_stairs"] == pytest.approx((4.0 * 2 + 3.8 * 1) / 7.8, abs=2e-3)
    assert gait["step_height"].shape == gait["ground"].shape == (steps,)
    trace["base_pos"][:, 0] = 0.0  # never over the stairs
    assert np.isnan(gait_on_stairs(trace, GEOMETRY)["clock_rate_on_stairs"])


def test_the_geometry_is_read_from_the_course():
    geometry = stairs_geometry(load_course("stairs"))
    assert geometry == {**GEOMETRY, "half_width": 3.2, "landing_height": pytest.approx(0.2)}


def test_a_traced_run_is_the_run_krl_evaluate_scores(tmp_path):
    from krl.agent.controller import AgentController
    from krl.agent.policy import load_policy, shipped_policy_dir
    from krl.analysis.agent.trace import TRACE_FIELDS, trace_course_run
    from krl.eval.episodes import score_walk
    from krl.sim.robot import A1Sim

    course_file = tmp_path / "short.toml"
    course_file.write_text(
        'format = 1\nname = "short"\ntime_limit = 1.5\nd_min = 0.5\nwaypoints = [[2.0, 0.0]]\n'
        'starts = [[0.0, 0.0, 0.0]]\n\n[terrain]\nname = "stairs"\n'
    )
    course = load_course(course_file)
    policy = shipped_policy_dir() / "agent-rp" / "seed150.npz"
    trace, metrics = trace_course_run(policy, course, 0)
    expected = score_walk(
        A1Sim(course.build()),
        AgentController(load_policy(policy)),
        np.array(course.waypoints),
        course.starts[0],
        course.time_limit,
        course.d_min,
    )
    drop = {"wall_seconds"}
    assert {k: v for k, v in metrics.items() if k not in drop} == {
        k: v for k, v in expected.items() if k not in drop
    }
    assert set(trace) == set(TRACE_FIELDS) and len(trace["time"]) == metrics["steps"]
    assert trace["residual"].shape == (metrics["steps"], 4, 3)


def test_krl_agent_stairs_writes_the_figure_and_its_table(tmp_path, capsys):
    import json

    from krl.cli import main

    course_file = tmp_path / "short-stairs.toml"
    course_file.write_text(
        'format = 1\nname = "short-stairs"\ntime_limit = 1.0\nd_min = 0.5\nwaypoints = [[2.0, 0.0]]\n'
        'starts = [[0.0, 0.0, 0.0], [1.05, 0.3, 0.0]]\n\n[terrain]\nname = "stairs"\n'
    )
    argv = ["agent", "stairs", "--policy", "shipped=rp", "--course", str(course_file), "--out", str(tmp_path)]
    assert main([*argv, "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert [run["policy"] for run in printed["runs"]] == ["shipped", "shipped"]
    for kind in ("png", "json", "csv"):
        assert (tmp_path / f"stairs-diagnosis.{kind}").is_file()
    assert (
        printed["gait_png"] == str(tmp_path / "stairs-gait.png") and (tmp_path / "stairs-gait.png").is_file()
    )
    # agent-rp drives nothing: kernel-base's nominal step and ride heights, rate 1 on the stairs (the second
    # start's trunk is past the first riser), none from the first start, 1 m before the riser
    first, second = printed["runs"]
    assert first["step_height_on_stairs"] is None
    assert (second["ride_height_on_stairs"], second["clock_rate_on_stairs"]) == (0.25, 1.0)
    assert main(["agent", "stairs", "--policy", "rp", "--course", "flat", "--out", str(tmp_path)]) == 2
    assert "not on stairs" in capsys.readouterr().err
