"""The friction sweep: course files set the ground's μ, the sweep's runs, summaries, CLI and report."""

import json

import pytest
from agent_fakes import make_policy
from eval_fakes import stored_record

from krl.agent.config import AgentConfig
from krl.cli import main
from krl.eval import evaluate, summaries, sweep_report
from krl.eval.controllers import parse_controller
from krl.eval.courses import CourseError, load_course
from krl.eval.episodes import FRICTION_SWEEP_FRICTIONS, FrictionSweep

TINY = """
format = 1
name = "tiny"
time_limit = 0.1
d_min = 0.5
waypoints = [[3.0, 0.0]]
starts = [[0.0, 0.0, 0.0], [0.0, 0.2, 0.3]]

[terrain]
name = "flat"
"""


@pytest.fixture
def tiny(tmp_path):
    path = tmp_path / "tiny.toml"
    path.write_text(TINY)
    return path


def test_a_course_files_friction_reaches_the_model(tmp_path, tiny):
    plain = load_course(tiny)
    path = tmp_path / "icy.toml"
    path.write_text(TINY + "params = { friction = 0.3 }\n")
    icy = load_course(path)
    assert icy.terrain_params == {"friction": 0.3} and icy.fingerprint != plain.fingerprint
    built = icy.build()
    assert built.model.geom("floor").friction[0] == 0.3 and built.terrain.params == {"friction": 0.3}
    assert plain.build().model.geom("floor").friction[0] == 1.0
    assert FrictionSweep.on(plain, 0.3).fingerprint == icy.fingerprint
    path.write_text(TINY + "params = { friction = 0 }\n")
    with pytest.raises(CourseError) as error:
        load_course(path)
    assert "parameter 'friction' = 0.0 must be > 0" in str(error.value) and str(path) in str(error.value)


@pytest.mark.parametrize(
    "fields, message",
    [
        ({"frictions": ()}, "at least one friction coefficient"),
        ({"frictions": (1.0, 0.0)}, "friction 0 is out of range: 0 < μ <= 5"),
        ({"frictions": (0.5, float("nan"))}, "friction nan is out of range"),
        ({"frictions": (0.5, 0.5)}, "frictions must be distinct"),
        ({"courses": ()}, "at least one course"),
    ],
)
def test_a_bad_sweep_is_refused(fields, message):
    with pytest.raises(ValueError, match=message):
        FrictionSweep(**fields)


def test_the_default_sweep_walks_the_flat_and_height_field_courses():
    sweep = FrictionSweep()
    assert sweep.frictions == FRICTION_SWEEP_FRICTIONS and 1.0 in sweep.frictions and 0.5 in sweep.frictions
    assert [course.terrain for course in sweep.load_courses()] == ["flat", "heightfield"]


def test_the_sweeps_runs_of_a_seed_group(tmp_path, tiny):
    folder = tmp_path / "runs" / "mine"
    folder.mkdir(parents=True)
    for seed in (1, 2):
        make_policy(AgentConfig(), seed=seed).save(folder / f"policy-seed{seed}.npz")
    spec = parse_controller(f"agent:{folder}")
    sweep = FrictionSweep(frictions=(1.0, 0.5), courses=(str(tiny),))
    runs = evaluate.friction_runs(spec, sweep, sweep.load_courses(), video_dir=tmp_path / "v")
    assert [run.key for run in runs] == [
        f"friction/tiny-mu{mu:g}-start{start}-seed{seed}"
        for mu in (1, 0.5)
        for start in (0, 1)
        for seed in (1, 2)
    ]
    assert [run.video is not None for run in runs] == [True, False, False, False] * 2
    identity = runs[4].identity()
    assert identity["friction"] == 0.5 and identity["seed"] == 1 and identity["course"] == "tiny"
    assert identity["course_fingerprint"] == FrictionSweep.on(load_course(tiny), 0.5).fingerprint
    assert runs[0].course.terrain_params == {"friction": 1.0}
    assert [run.seed for run in evaluate.friction_runs(spec, sweep, sweep.load_courses(), [2])] == [2] * 4
    assert "friction" not in evaluate.course_runs(spec, [load_course(tiny)])[0].identity()


def record(course, friction, seed, success, fell=False, error=None, targets=5):
    return {
        "course": course,
        "friction": friction,
        "seed": seed,
        "metrics": {"success": success, "fell": fell, "error": error, "targets_reached": targets},
    }


def test_friction_summary_by_hand():
    records = [
        record("flat", 0.5, 1, True),
        record("flat", 0.5, 1, False, fell=True, targets=2),
        record("flat", 0.5, 2, True),
        record("flat", 0.5, 2, True),
        record("flat", 1.0, 1, True),
        record("heightfield", 0.5, 1, False, error="MPCError: gave up", targets=0),
    ]
    rows = summaries.summarise_friction(records)
    assert [(row["course"], row["friction"]) for row in rows] == [
        ("flat", 1.0),
        ("flat", 0.5),
        ("heightfield", 0.5),
    ]
    flat = rows[1]
    assert flat["runs"] == 4 and flat["success_rate"] == 0.75 and flat["fall_rate"] == 0.25
    assert flat["targets_reached_mean"] == 4.25 and flat["success_low"] < 0.75 < flat["success_high"]
    assert flat["seeds"] == 2 and flat["success_rate_seed_std"] == pytest.approx(0.3535534, rel=1e-6)
    assert "seeds" not in rows[0] and rows[2]["fall_rate"] == 1.0  # an error counts as a fall
    by_seed = summaries.summarise_friction_by_seed(records)
    assert [(r["seed"], r["course"], r["friction"], r["success_rate"]) for r in by_seed] == [
        (1, "flat", 1.0, 1.0),
        (1, "flat", 0.5, 0.5),
        (1, "heightfield", 0.5, 0.0),
        (2, "flat", 0.5, 1.0),
    ]
    rows = sweep_report.friction_rows({"agent-mine": {evaluate.FRICTION_DIR: records}})
    table = sweep_report.friction_markdown(rows)
    assert (
        "| controller | μ = 1 | μ = 0.5 |" in table
        and "| agent-mine | 1.00 / 0.00 (1) | 0.75 / 0.25 (4) |" in table
    )
    assert "| agent-mine seed 2 | – | 1.00 / 0.00 (2) |" in table and "Course `heightfield`" in table


@pytest.mark.parametrize(
    "options, message",
    [
        (["--frictions", "0"], "--frictions: 0 is out of range: 0 < μ <= 5 (got '0')"),
        (["--frictions", "0.5,x"], "--frictions expects a comma list"),
        (["--frictions", "0.5,0.5"], "frictions must be distinct"),
        (["--friction-course", "moon"], "unknown course 'moon'"),
    ],
)
def test_bad_friction_options_are_one_line_before_anything_is_written(tmp_path, capsys, options, message):
    out = tmp_path / "out"
    argv = ["evaluate", "--controller", "expert", "--friction-sweep", *options, "--out", str(out), "--quiet"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not out.exists()


def test_cli_friction_sweep_then_report(tmp_path, tiny, capsys):
    out, docs = tmp_path / "out", tmp_path / "docs"
    argv = [
        "evaluate",
        "--controller",
        "expert",
        "--course",
        str(tiny),
        "--friction-sweep",
        "--frictions",
        "1,0.4",
    ]
    argv += ["--friction-course", str(tiny), "--out", str(out), "--workers", "1", "--quiet", "--json"]
    assert main(argv) == 0
    summary = json.loads(capsys.readouterr().out)
    entry = summary["controllers"]["expert-stance0.2"]
    assert summary["runs"] == 2 + 4 and entry["tiny"]["runs"] == 2  # the course's own runs, apart
    assert [(row["course"], row["friction"], row["runs"]) for row in entry["friction"]] == [
        ("tiny", 1.0, 2),
        ("tiny", 0.4, 2),
    ]
    stored = stored_record(out, "expert-stance0.2", "friction/tiny-mu0.4-start1")
    assert stored["friction"] == 0.4 and stored["start"] == 1
    assert main(argv) == 0 and json.loads(capsys.readouterr().out)["stored"] == 6  # resumed
    assert main(["report", "--results", str(out), "--out", str(docs), "--json"]) == 0
    written = json.loads(capsys.readouterr().out)["written"]
    assert str(docs / "friction.csv") in written and not (docs / "course-friction.csv").exists()
    assert str(docs / "friction.png") in written and (docs / "friction.png").stat().st_size > 0
    markdown = (docs / "evaluation.md").read_text()
    assert "Success against ground friction" in markdown and "(friction.png)" in markdown


def test_friction_options_restate_no_default():
    from krl.cli import build_parser
    from krl.cli.eval import friction_sweep_from_args

    parse = build_parser().parse_args
    args = parse(["evaluate", "--controller", "expert", "--friction-sweep"])
    assert args.frictions is None and args.friction_course is None
    assert friction_sweep_from_args(args) == FrictionSweep()
    args = parse(
        ["evaluate", "--controller", "expert", "--frictions", "0.7,0.2", "--friction-course", "flat"]
    )
    assert friction_sweep_from_args(args) == FrictionSweep(frictions=(0.7, 0.2), courses=("flat",))
