"""A seed group's results (one policy per training seed): pooled rows as the thesis's, and the rows by seed
behind them, on records whose every number is worked out by hand."""

import json

import pytest
from eval_fakes import complete_record

from krl.eval import evaluate, report, summaries, sweep_report


def course_record(seed, start, reached, fell):
    success = reached == 5 and not fell
    metrics = {
        "targets": 5,
        "targets_reached": reached,
        "success": success,
        "fell": fell,
        "error": None,
        "reward_per_step": 0.09 if success else 0.05,
        "distance_walked": 10.0,
        "time_to_finish": 40.0 if success else None,
    }
    return {
        "course": "stairs",
        "start": start,
        "seed": seed,
        "run": f"stairs/start{start}-seed{seed}",
        "metrics": metrics,
    }


def push_record(seed, attempt, success, magnitude=300.0):
    push = {"impulse": 18.0, "delta_v": 1.44, "force": [magnitude, 0.0, 0.0]}
    metrics = {"success": success, "fell": not success, "error": None, "push": push}
    return {
        "magnitude": magnitude,
        "attempt": attempt,
        "seed": seed,
        "sweep": {"target": [3.0, 0.0]},
        "metrics": metrics,
    }


COURSE = [
    course_record(150, 0, 5, False),
    course_record(150, 1, 5, False),
    course_record(215, 0, 5, False),
    course_record(215, 1, 1, True),
]
PUSHES = [push_record(150, a, a < 8) for a in range(10)] + [push_record(215, a, a < 4) for a in range(10)]


def test_a_groups_course_row_pools_every_run_and_its_seed_rows_show_the_spread():
    pooled = summaries.summarise_course(COURSE)
    assert pooled["runs"] == 4 and pooled["targets_reached_mean"] == 4.0
    assert pooled["targets_reached_std"] == pytest.approx(2.0)  # sample std of 5, 5, 5, 1
    assert (pooled["success_rate"], pooled["fall_rate"]) == (0.75, 0.25)
    rows = summaries.summarise_course_by_seed(COURSE)
    assert [
        (r["seed"], r["runs"], r["success_rate"], r["fall_rate"], r["targets_reached_mean"]) for r in rows
    ] == [
        (150, 2, 1.0, 0.0, 5.0),
        (215, 2, 0.5, 0.5, 3.0),
    ]
    assert summaries.summarise_course_by_seed([{**r, "seed": None} for r in COURSE]) == []
    table = report._seed_markdown(report.seed_rows({"agent-rp": {"stairs": COURSE}}, "stairs"))
    assert "| controller | seed 150 | seed 215 |" in table
    assert "| agent-rp | 2/2, 0 fell, 5.00 | 1/2, 1 fell, 3.00 |" in table


def test_a_groups_push_rows_are_pooled_with_the_seeds_spread_then_one_per_seed():
    (pooled,) = summaries.summarise_push(PUSHES)
    assert pooled["attempts"] == 20 and pooled["success_rate"] == pytest.approx(0.6)  # mean of 0.8 and 0.4
    assert pooled["seeds"] == 2 and pooled["success_rate_seed_std"] == pytest.approx(0.2828427)
    by_seed = summaries.summarise_push_by_seed(PUSHES)
    assert [(r["seed"], r["attempts"], r["success_rate"]) for r in by_seed] == [
        (150, 10, 0.8),
        (215, 10, 0.4),
    ]
    assert "seeds" not in by_seed[0]
    table = sweep_report.push_markdown(sweep_report.push_rows({"agent-rp": {evaluate.PUSH_DIR: PUSHES}}))
    cells = {
        row[1]: row[2:]
        for row in (
            [c.strip() for c in line.strip("|").split("|")] for line in table.splitlines() if line[:2] == "| "
        )
    }
    assert cells["agent-rp (pooled over 2 seeds) (20 attempts)"][1] == "0.60"  # 300 N
    assert cells["agent-rp seed 150"][1] == "0.8" and cells["agent-rp seed 215"][1] == "0.4"


def test_the_report_writes_the_seed_rows_beside_the_tables(tmp_path):
    results = tmp_path / "eval"
    for record in COURSE:
        path = results / "agent-rp" / f"{record['run']}.json"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(complete_record(record, "agent-rp")))
    written = report.write_report(results, tmp_path / "out", None, "krl report")
    assert str(tmp_path / "out" / "course-stairs-seeds.csv") in written["written"]
    markdown = (tmp_path / "out" / "evaluation.md").read_text()
    assert "By training seed" in markdown and "| agent-rp (Agent-rp) | 4 |" in markdown


def test_each_push_line_has_its_own_colour_and_a_thesis_row_its_counterparts():
    ours = ["agent-rp", "expert-stance0.2", *(f"agent-variant{index}" for index in range(10))]
    rows = [{"source": "krl", "controller": label} for label in ours]
    rows += [
        {"source": "thesis", "controller": name} for name in ("Agent-rp", "MPC (τ_stance=0.2)", "Kernel")
    ]
    colours = sweep_report._push_colours(rows)
    assert len({colours["krl", label] for label in ours}) == len(ours)  # past the default cycle's 10
    assert colours["thesis", "Agent-rp"] == colours["krl", "agent-rp"]
    assert colours["thesis", "MPC (τ_stance=0.2)"] == colours["krl", "expert-stance0.2"]
    assert colours["thesis", "Kernel"] not in {colours["krl", label] for label in ours}  # no kernel-base here
