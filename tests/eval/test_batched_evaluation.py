"""Batched evaluation: a run walked in a batch is the run walked alone, record for record."""

from __future__ import annotations

import pytest

from krl.eval import batch
from krl.eval.batch import run_batch
from krl.eval.controllers import parse_controller
from krl.eval.courses import load_course
from krl.eval.episodes import PushSweep
from krl.eval.evaluate import course_runs, push_runs, run_one

HEIGHTFIELD_COURSE = """
format = 1
name = "rough-short"
time_limit = 2.5
d_min = 0.5
waypoints = [[0.6, 0.0], [0.7, 0.3]]
starts = [[0.0, 0.0, 0.0], [0.0, 0.3, -0.3], [0.0, -0.3, 0.3]]

[terrain]
name = "heightfield"
seed = 3
"""
"""Three starts on rough ground, two close waypoints, 2.5 s: some runs finish, others run out of time."""

SWEEP = PushSweep(magnitudes=(250.0, 900.0), attempts=2, window=(0.3, 0.8), time_limit=2.0)
"""Pushes soon after the start, the strongest enough to topple every controller."""


def without_wall_time(record: dict) -> dict:
    return {**record, "metrics": {k: v for k, v in record["metrics"].items() if k != "wall_seconds"}}


@pytest.mark.parametrize("text", ["kernel", "kernel:ext", "agent:gait-ground", "expert"])
def test_runs_walked_in_a_batch_make_the_records_they_make_alone(tmp_path, monkeypatch, text):
    path = tmp_path / "rough-short.toml"
    path.write_text(HEIGHTFIELD_COURSE)
    spec = parse_controller(text)
    seeds = spec.seeds[:1] if spec.seeded else None
    # the course last: its runs end the batch, and some finish (a robot whose task is over waits)
    runs = push_runs(spec, SWEEP, seeds) + course_runs(spec, [load_course(str(path))], seeds)
    monkeypatch.setattr(batch, "BATCH_SLOTS", 3)  # fewer robots than runs: slots start second runs
    batched = run_batch(runs)
    alone = [run_one(run) for run in runs]
    assert [without_wall_time(r) for r in batched] == [without_wall_time(r) for r in alone]
    endings = {record["metrics"]["ended"] for record in alone}
    assert "fell" in endings and len(endings) >= 2


def test_a_batch_refuses_runs_of_two_controllers(tmp_path):
    path = tmp_path / "rough-short.toml"
    path.write_text(HEIGHTFIELD_COURSE)
    course = load_course(str(path))
    runs = course_runs(parse_controller("kernel"), [course]) + course_runs(
        parse_controller("expert"), [course]
    )
    with pytest.raises(ValueError, match="one controller and seed"):
        run_batch(runs)


def test_jobs_batch_consecutive_runs_of_one_controller_and_seed(tmp_path):
    from krl.eval.evaluate import BATCH_RUNS, EvalRun, batch_jobs

    agent, expert = parse_controller("agent:gait-ground"), parse_controller("expert")
    runs = [EvalRun(f"c/start{k}", agent, seed=150) for k in range(2 * BATCH_RUNS + 3)]
    runs += [
        EvalRun("c/film", agent, seed=150, video=str(tmp_path / "a.mp4")),
        EvalRun("c/start0", agent, seed=215),
    ]
    runs += [EvalRun(f"c/start{k}", expert) for k in range(3)]
    jobs = batch_jobs(runs, workers=2)
    half = BATCH_RUNS // 2 + 1  # 2 x BATCH_RUNS + 3 runs in four jobs, two for each worker
    assert [len(job) for job in jobs] == [half, half, half, 2 * BATCH_RUNS + 3 - 3 * half, 1, 1, 1, 1, 1]
    assert [index for job in jobs for index in job] == list(range(len(runs)))
    assert [len(job) for job in batch_jobs(runs[:8], workers=2)] == [4, 4]  # a job for each worker


SEESAW_COURSE = """
format = 1
name = "seesaw-short"
time_limit = 2.0
d_min = 0.5
waypoints = [[0.0, 0.0]]
starts = [[-1.6, 0.0, 0.0], [-1.5, 0.2, 0.1]]

[terrain]
name = "seesaw"
"""
"""The seesaw, a moving prop under the scan, briefly."""


def test_a_policy_that_scans_the_ground_makes_the_same_records_batched_and_alone(tmp_path, monkeypatch):
    from dataclasses import replace

    from agent_fakes import make_policy

    from krl.agent.config import AgentConfig, ScanConfig

    config = AgentConfig()
    observation = replace(
        config.observation, features=(*config.observation.features, "height_scan"), scan=ScanConfig(noise=0.1)
    )
    path = make_policy(replace(config, observation=observation), scale=0.05, seed=2).save(
        tmp_path / "scan.npz"
    )
    course = tmp_path / "seesaw-short.toml"
    course.write_text(SEESAW_COURSE)
    rough = tmp_path / "rough-short.toml"
    rough.write_text(HEIGHTFIELD_COURSE)
    spec = parse_controller(f"agent:{path}")
    runs = course_runs(spec, [load_course(str(course)), load_course(str(rough))], spec.seeds)
    monkeypatch.setattr(batch, "BATCH_SLOTS", 2)
    batched = run_batch(runs)
    alone = [run_one(run) for run in runs]
    assert [without_wall_time(r) for r in batched] == [without_wall_time(r) for r in alone]
