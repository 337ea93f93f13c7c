"""``krl agent push``: one push, the same for every controller, and the response measured from its trace."""

import json

import numpy as np
import pytest

from krl.analysis import push as probe_module
from krl.analysis.push import PushProbe, push_summary, push_trace, touchdowns
from krl.cli import main
from krl.eval.controllers import parse_controller
from krl.eval.episodes import score_walk
from krl.sim import pushes
from krl.sim.model import build_model
from krl.sim.robot import A1Sim

DT = 0.005


def test_touchdowns_count_a_foot_after_a_real_swing_not_a_flicker():
    time = np.arange(12) * 0.01
    contact = np.zeros((12, 4), dtype=bool)
    contact[:, 0] = [1, 1, 0, 0, 0, 0, 0, 1, 1, 0, 1, 1]  # a 5-step swing, then a 1-step flicker
    contact[:, 1] = True
    downs = touchdowns(time, contact)
    assert downs[0].tolist() == [0.07] and [d.size for d in downs[1:]] == [0, 0, 0]


def synthetic_trace():
    """Walking along +x at 0.4 m/s; pushed left: 1.5 m/s across the walk for 2.5 <= t < 2.8 s; trunk at
    0.25 m, 0.20 m at 2.9 s; rolled by -0.3 rad at 2.7 s (and by 0.5 rad at 1 s, before the push); feet FR
    and RL come down at 2.2 s and again at 2.62 s."""
    time = np.arange(0, 5, DT)
    velocity = np.zeros((time.size, 3))
    velocity[:, 0] = 0.4
    velocity[(time >= 2.5 - 1e-9) & (time < 2.8 - 1e-9), 1] = 1.5
    base_pos = np.cumsum(velocity, axis=0) * DT
    base_pos[:, 2] = 0.25
    base_pos[np.argmin(np.abs(time - 2.9)), 2] = 0.20
    contact = np.ones((time.size, 4), dtype=bool)
    for foot in (0, 3):
        contact[(time >= 2.1) & (time < 2.2 - 1e-9), foot] = False
        contact[(time >= 2.5) & (time < 2.62 - 1e-9), foot] = False
    gait = np.full((time.size, 3), np.nan)
    rpy = np.zeros((time.size, 3))
    rpy[np.argmin(np.abs(time - 2.7)), 0] = -0.3
    rpy[np.argmin(np.abs(time - 1.0)), 0] = 0.5
    return {
        "time": time,
        "base_pos": base_pos,
        "velocity": velocity,
        "rpy": rpy,
        "foot_contact": contact,
        "gait": gait,
        "residual": np.full((time.size, 4, 3), np.nan),
        "residual_action": np.full((time.size, 12), np.nan),
    }


def test_the_response_to_a_push_by_hand():
    probe = PushProbe(magnitude=400, direction="left", start_time=2.5)
    summary = push_summary(probe, synthetic_trace(), {"fell": False, "success": True})
    assert summary["peak_speed"] == pytest.approx(1.5)  # the 0.2 s average is full inside the 0.3 s push
    assert summary["drift"] == pytest.approx(1.5 * 0.3)
    # the 40-step average falls below 0.1 m/s when 2 of its steps are pushed ones: 2.985 s, 0.185 s after
    assert summary["recovery_time"] == pytest.approx(0.185)
    assert summary["min_height"] == 0.2 and summary["first_touchdown"] == pytest.approx(0.12)
    assert summary["peak_roll"] == 0.3  # either way, after the push began
    assert summary["touchdowns"] == 2 and summary["stride_after"] is None
    assert summary["stride_before"] is None  # one touchdown per foot before: no interval
    assert summary["min_ride_height"] is None and summary["max_clock_rate"] is None
    assert summary["peak_residual"] is None and summary["residual_at_bound"] is None
    # an agent: its residual 0.03 m but for 0.05 m at 2.6 s, one action component of 12 at the bound
    # (-1) for the first half of the window
    agent = synthetic_trace()
    agent["residual"][:] = 0.03
    agent["residual"][np.argmin(np.abs(agent["time"] - 2.6)), 1, 2] = -0.05
    agent["residual_action"][:] = 0.5
    agent["residual_action"][agent["time"] < 3.5 - 1e-9, 4] = -1.0
    summary = push_summary(probe, agent, {"fell": False, "success": True})
    assert summary["peak_residual"] == 0.05 and summary["residual_at_bound"] == pytest.approx(
        1 / 24, abs=1e-4
    )
    # along the walk nothing changed: the walk's own 0.4 m/s is not the push's
    forward = PushProbe(magnitude=400, direction="forward", start_time=2.5)
    summary = push_summary(forward, synthetic_trace(), {"fell": False, "success": True})
    assert summary["peak_speed"] == pytest.approx(0.0, abs=1e-12) and summary["recovery_time"] == 0.0
    assert summary["drift"] == pytest.approx(0.0, abs=1e-12)


def test_a_probe_refuses_what_it_cannot_do():
    with pytest.raises(ValueError, match="unknown push direction 'up'"):
        PushProbe(direction="up")
    with pytest.raises(ValueError, match="push start time must lie in"):
        PushProbe(start_time=-1.0)
    with pytest.raises(ValueError, match="push magnitude must be a finite number"):
        PushProbe(magnitude=float("nan"))
    with pytest.raises(ValueError, match="unknown push point 'side'; known: centre, top, bottom"):
        PushProbe(point="side")


def test_a_probe_strikes_the_trunk_where_asked():
    """The middle of the top face is the trunk box's half height above its origin; the force is the same."""
    centre, top = PushProbe(magnitude=500), PushProbe(magnitude=500, point="top")
    assert centre.push().point.tolist() == [0.0, 0.0, 0.0]
    assert (
        top.push().point.tolist() == [0.0, 0.0, 0.057] and PushProbe(point="bottom").push().point[2] == -0.057
    )
    assert top.push().force.tolist() == centre.push().force.tolist()


def test_a_traced_push_is_the_push_sweeps_run():
    probe = PushProbe(magnitude=300, direction="right", start_time=2.55)
    trace, metrics = push_trace(probe, parse_controller("kernel").build())
    sweep = probe.sweep
    plain = score_walk(
        A1Sim(build_model("flat")),
        parse_controller("kernel").build(),
        np.array([sweep.target]),
        (0.0, 0.0, 0.0),
        sweep.time_limit,
        sweep.d_min,
        push=probe.push(),
    )
    keep = ("fell", "success", "targets_reached", "reward_per_step", "distance_walked")
    assert {k: metrics[k] for k in keep} == {k: plain[k] for k in keep}
    assert trace["time"].shape == (trace["base_pos"].shape[0],) and trace["gait"].shape[1] == 3
    pushed = (trace["time"] >= 2.55) & (trace["time"] < 2.85)
    assert trace["velocity"][pushed, 1].min() < -0.3  # carried to the right (−y) by the push


def test_krl_agent_push_writes_the_figure_table_and_traces(tmp_path, capsys):
    out = tmp_path / "push"
    argv = ["agent", "push", "--controller", "kernel", "--magnitude", "250", "--direction", "backward"]
    assert main([*argv, "--out", str(out), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert [row["controller"] for row in result["controllers"]] == ["kernel-base"]
    assert result["probe"]["push"]["force"] == [-250.0, 0.0, 0.0]
    for name in ("png", "json", "csv", "npz"):
        assert (out / f"push-trace.{name}").stat().st_size > 0
    traces = np.load(out / "push-trace.npz")
    assert set(traces.files) == {f"kernel-base/{field}" for field in probe_module.TRACE_FIELDS}
    bad = tmp_path / "bad"
    assert main(["agent", "push", "--at", "99", "--out", str(bad)]) == 2
    assert "push start time must lie in" in capsys.readouterr().err and not bad.exists()


def test_a_push_that_blows_the_simulation_up_is_an_unstable_run_as_krl_evaluate_records_it(
    tmp_path, capsys, monkeypatch
):
    """Issue 47: 1e30 N blew the simulation up and the trace said the kernel did not fall. As in ``krl
    evaluate``, the run carries the SimulationUnstableError and counts as a fall; stderr says so. (Such a
    push is refused since issue 61; the bound is lifted here to blow the simulation up.)"""
    monkeypatch.setattr(pushes, "MAX_PUSH_FORCE", np.inf)
    out = tmp_path / "push"
    argv = ["agent", "push", "--controller", "kernel", "--magnitude", "1e30", "--out", str(out), "--json"]
    assert main(argv) == 0
    captured = capsys.readouterr()
    (row,) = json.loads(captured.out)["controllers"]
    assert row["error"].startswith("SimulationUnstableError: ") and row["fell"] and not row["success"]
    assert json.loads((out / "push-trace.json").read_text())["controllers"][0]["error"] == row["error"]
    assert "error" in (out / "push-trace.csv").read_text().splitlines()[0].split(",")
    assert f"krl: warning: kernel-base: {row['error']} (counted as a fall, as krl evaluate counts it)" in (
        captured.err.splitlines()
    )


@pytest.mark.parametrize("magnitude", ["nan", "inf", "-1e30", "-5", "1e30", "5000.5"])
def test_a_push_not_from_0_to_5000_n_is_refused_in_one_line(tmp_path, capsys, magnitude):
    out = tmp_path / "push"
    assert main(["agent", "push", "--magnitude", magnitude, "--controller", "kernel", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert (
        err.startswith("krl: error: push magnitude must be a finite number from 0 to 5000 N, got ")
        and err.count("\n") == 1
    )
    assert not out.exists()


def test_a_summary_of_a_run_that_ended_with_an_error_is_a_fall_with_that_error():
    metrics = {"fell": False, "success": False, "error": "MPCError: the QP failed"}
    summary = push_summary(PushProbe(start_time=2.5), synthetic_trace(), metrics)
    assert summary["fell"] and summary["error"] == "MPCError: the QP failed"
    assert (
        push_summary(PushProbe(start_time=2.5), synthetic_trace(), {"fell": False, "success": True})["error"]
        is None
    )


def test_an_agents_trace_holds_its_residual_within_the_bound():
    """agent-robust's residual: the raw action in [-1, 1], the filtered one in metres within the bound,
    and the summary reads both."""
    controller = parse_controller("agent:robust@150").build()
    probe = PushProbe(magnitude=300, direction="left", start_time=2.55)
    trace, metrics = push_trace(probe, controller)
    bound = np.asarray(controller.policy.config.residual.residual_bound)
    raw, residual = trace["residual_action"], trace["residual"]
    assert raw.shape == (trace["time"].size, 12) and np.all(np.abs(raw) <= 1.0)
    assert residual.shape == (trace["time"].size, 4, 3) and np.all(np.abs(residual) <= bound + 1e-12)
    assert np.abs(residual).max() > 0.0
    summary = push_summary(probe, trace, metrics)
    assert 0.0 < summary["peak_residual"] <= bound.max() and 0.0 <= summary["residual_at_bound"] <= 1.0
