"""``--push-directions balanced``: the push sweep's directions stratified over the four quarters around the
robot's heading at the push; the default (``uniform``) draws exactly the pushes it always drew."""

import json
import math
from collections import Counter

import numpy as np
import pytest
from eval_fakes import StandStill, TurningPointSim, stored_record

from krl.cli import main
from krl.eval import evaluate
from krl.eval.controllers import parse_controller
from krl.eval.episodes import PushSweep, score_push_attempt, score_walk
from krl.eval.evaluate import EvaluationError
from krl.eval.summaries import PUSH_DIRECTIONS, push_direction

# PushSweep(seed=7).push(500.0, a) for a = 0..3, printed by the code before the option existed:
# (start_time [s], force [N], point [m])
UNIFORM_SEED7_500N = [
    (
        3.875286399814001,
        (-388.5390476963328, 292.81740680083, 115.30557093941322),
        (-0.05335560192870281, -0.097, -0.05639975527952448),
    ),
    (
        4.310422853010422,
        (-380.7556129350214, -322.8335050574227, 28.349448509894646),
        (-0.1335, 0.0003353234715529896, 0.056182231291966804),
    ),
    (
        2.8339108465807428,
        (452.25987780871486, -162.33222418918868, 138.23621780936173),
        (-0.06680936391450101, -0.04280146717865203, 0.057),
    ),
    (
        4.925100661158504,
        (-373.2494162297, 330.8717201180128, 34.76748639656957),
        (-0.025273540450738916, 0.05906882255136717, 0.057),
    ),
]

UNIFORM_SETTINGS = {  # PushSweep().to_dict() before the option existed: what old records store
    "magnitudes": [float(m) for m in range(250, 901, 50)],
    "attempts": 10,
    "seed": 0,
    "target": [3.0, 0.0],
    "window": [2.0, 5.0],
    "time_limit": 40.0,
    "d_min": 0.5,
}


def test_the_default_sweep_draws_the_pushes_it_always_drew():
    sweep = PushSweep(seed=7)
    assert sweep.directions == "uniform"
    for attempt, (start, force, point) in enumerate(UNIFORM_SEED7_500N):
        push = sweep.push(500.0, attempt)
        assert push.start_time == start  # bit for bit
        assert push.force.tolist() == list(force) and push.point.tolist() == list(point)
    assert PushSweep().to_dict() == UNIFORM_SETTINGS  # so stored uniform records still resume


def test_a_balanced_sweep_has_equal_attempts_in_each_quarter():
    sweep = PushSweep(attempts=8, directions="balanced")
    strata = [sweep.stratum(attempt) for attempt in range(sweep.attempts)]
    assert strata == [*PUSH_DIRECTIONS, *PUSH_DIRECTIONS]  # attempt a: quarter a mod 4, whatever --attempts
    assert Counter(strata) == dict.fromkeys(PUSH_DIRECTIONS, 2)
    assert sweep.to_dict() == {**UNIFORM_SETTINGS, "attempts": 8, "directions": "balanced"}
    uniform = PushSweep(attempts=8)
    same, other = sweep.push(300.0, 5), uniform.push(300.0, 5)
    assert same.start_time == other.start_time and same.point.tolist() == other.point.tolist()


def test_balanced_directions_are_uniform_within_their_quarter_relative_to_the_heading():
    sweep = PushSweep(attempts=4, directions="balanced", seed=3)
    offsets = {direction: [] for direction in PUSH_DIRECTIONS}
    for attempt in range(400):
        force = sweep.push(600.0, attempt).force  # relative to the heading: x forward, y left
        assert np.linalg.norm(force) == pytest.approx(600.0)
        azimuth = math.atan2(force[1], force[0])
        centre = PUSH_DIRECTIONS.index(sweep.stratum(attempt)) * math.pi / 2
        offsets[sweep.stratum(attempt)].append(math.remainder(azimuth - centre, 2 * math.pi))
    for values in offsets.values():
        assert len(values) == 100 and max(np.abs(values)) <= math.pi / 4
        assert min(values) < -math.pi / 5 and max(values) > math.pi / 5  # spread over the whole quarter


@pytest.mark.parametrize("attempts", [1, 6, 10])
def test_balanced_directions_refuse_attempts_not_divisible_by_four(attempts):
    with pytest.raises(ValueError, match=f"divisible by 4.*got {attempts}"):
        PushSweep(attempts=attempts, directions="balanced")


def test_an_unknown_draw_is_refused():
    with pytest.raises(ValueError, match="unknown push directions 'sideways'; known: uniform, balanced"):
        PushSweep(directions="sideways")


def quick_sweep(**fields) -> PushSweep:
    """A sweep whose pushes come at 0.1-0.3 s and whose walk ends at 0.5 s."""
    return PushSweep(**{"magnitudes": (500.0,), "window": (0.1, 0.3), "time_limit": 0.5, **fields})


def test_each_balanced_push_lands_in_its_quarter_of_the_heading_at_the_push():
    sweep, target_relative = quick_sweep(attempts=8, directions="balanced"), []
    for attempt in range(sweep.attempts):
        sim = TurningPointSim(turn_per_step=0.05)  # 1-3 rad turned by the push: far from the target's line
        metrics = score_push_attempt(sweep, StandStill(), 500.0, attempt, sim=sim)
        heading = metrics["push_heading"]
        assert heading == pytest.approx(sim.pushed.start_step * 0.05)
        assert metrics["push"]["force"] == sim.pushed.force.tolist()  # recorded as applied, world frame
        assert metrics["push"]["stratum"] == sweep.stratum(attempt)
        record = {"sweep": sweep.to_dict(), "metrics": metrics}
        assert push_direction(record) == sweep.stratum(attempt)  # krl report's quarter is the stratum
        target_relative.append(push_direction({**record, "metrics": {**metrics, "push_heading": None}}))
    assert target_relative != [sweep.stratum(a) for a in range(8)]  # the heading, not the target, counts


def test_a_balanced_push_that_never_came_is_recorded_in_its_quarter_of_the_walk():
    sweep = quick_sweep(attempts=4, directions="balanced")
    for attempt in range(4):
        sim = TurningPointSim(turn_per_step=0.05, fall_at=3)  # falls before the push
        metrics = score_push_attempt(sweep, StandStill(), 500.0, attempt, sim=sim)
        assert metrics["push_heading"] is None and sim.pushed is None
        assert push_direction({"sweep": sweep.to_dict(), "metrics": metrics}) == sweep.stratum(attempt)


def test_a_uniform_push_is_not_turned():
    sweep = quick_sweep(attempts=1)
    sim = TurningPointSim(turn_per_step=0.05)
    metrics = score_push_attempt(sweep, StandStill(), 500.0, 0, sim=sim)
    assert sim.pushed.force.tolist() == sweep.push(500.0, 0).force.tolist() == metrics["push"]["force"]
    assert "stratum" not in metrics["push"]


def test_the_simulator_is_pushed_in_the_heading_at_the_push():
    from krl.sim.model import build_model
    from krl.sim.pushes import Push
    from krl.sim.robot import A1Sim

    left = Push(start_time=0.1, force=np.array([0.0, 300.0, 0.0]), point=np.zeros(3), duration=0.3)
    sim, controller = A1Sim(build_model("flat")), parse_controller("kernel").build()
    metrics = score_walk(sim, controller, np.array([[3.0, 0.0]]), (0.0, 0.0, 0.7), 0.2, 0.5, push=left,
                         push_in_heading_frame=True)  # fmt: skip
    heading = metrics["push_heading"]
    assert heading == pytest.approx(0.7, abs=0.05)
    assert sim.pending_push.force.tolist() == left.turned(heading).force.tolist()  # still acting at 0.2 s
    assert math.atan2(sim.pending_push.force[1], sim.pending_push.force[0]) == pytest.approx(
        heading + math.pi / 2
    )


def test_the_draw_is_in_every_record_and_a_resume_with_another_is_refused(tmp_path):
    balanced = PushSweep(
        magnitudes=(300.0,), attempts=4, window=(0.05, 0.1), time_limit=0.3, directions="balanced"
    )
    runs = evaluate.push_runs(parse_controller("kernel"), balanced)
    records = evaluate.execute(runs, tmp_path)
    assert [r["sweep"]["directions"] for r in records] == ["balanced"] * 4
    assert [push_direction(r) for r in records] == list(PUSH_DIRECTIONS)
    uniform = PushSweep(magnitudes=(300.0,), attempts=4, window=(0.05, 0.1), time_limit=0.3)
    with pytest.raises(EvaluationError, match="made by a different push sweep than this run"):
        evaluate.execute(evaluate.push_runs(parse_controller("kernel"), uniform), tmp_path)


def test_cli_records_the_draw_in_the_summary_and_refuses_a_resume_with_another(tmp_path, capsys, monkeypatch):
    def walk(self, controller, push, video=None, sim=None):  # a fake robot that falls after the push
        return original(self, StandStill(), push, video, TurningPointSim(fall_at=1001))

    original = PushSweep.walk
    monkeypatch.setattr(PushSweep, "walk", walk)
    # each run alone (one worker: in this process), so that the sweep walks the fake robot
    monkeypatch.setattr(evaluate, "run_job", lambda runs: [evaluate.run_one(run) for run in runs])
    out = tmp_path / "out"
    argv = ["evaluate", "--controller", "kernel", "--push-sweep", "--magnitudes", "300", "--attempts", "4"]
    argv += ["--out", str(out), "--workers", "1", "--quiet", "--json"]
    assert main([*argv, "--push-directions", "balanced"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["push_sweep"]["directions"] == "balanced"
    rows = summary["controllers"]["kernel-base"]["push_directions"]
    assert [(row["direction"], row["attempts"]) for row in rows] == [(d, 1) for d in PUSH_DIRECTIONS]
    sides = summary["controllers"]["kernel-base"]["push_left_right"]
    assert (sides["directions"], sides["left_attempts"], sides["right_attempts"]) == ("balanced", 1, 1)
    stored = stored_record(out, "kernel-base", "push/m300-a1")
    assert stored["sweep"]["directions"] == "balanced" and stored["metrics"]["push"]["stratum"] == "left"
    assert main(argv) == 2  # the default draw, uniform, into the same results
    err = capsys.readouterr().err
    assert "made by a different push sweep" in err and err.count("\n") == 1


def test_bad_push_directions_are_one_line_before_anything_is_written(tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["evaluate", "--controller", "expert", "--push-sweep", "--out", str(out), "--quiet"]
    with pytest.raises(SystemExit) as stop:  # argparse's usage error
        main([*argv, "--push-directions", "sideways"])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert "argument --push-directions: invalid choice: 'sideways'" in err and err.count("\n") == 1, err
    assert main([*argv, "--push-directions", "balanced"]) == 2  # with the default 10 attempts
    err = capsys.readouterr().err
    assert "divisible by 4 (one attempt per quarter in turn), got 10" in err and err.count("\n") == 1, err
    assert not out.exists()
