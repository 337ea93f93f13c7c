"""krl evaluate's executor and krl report: resumable, worker-count independent, one-line errors."""

import json

import numpy as np
import pytest
from eval_fakes import stored_record

from krl.cli import main
from krl.eval import evaluate, summaries
from krl.eval.controllers import ControllerSpecError, parse_controller
from krl.eval.courses import load_course
from krl.eval.episodes import PushSweep

TINY = """
format = 1
name = "tiny"
time_limit = 0.25
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


def test_runs_are_stored_and_not_redone(tmp_path, tiny):
    spec = parse_controller("kernel")
    runs = evaluate.course_runs(spec, [load_course(tiny)], seeds=[150, 215])
    assert [t.key for t in runs] == ["tiny/start0", "tiny/start1"]  # the kernel does not depend on a seed
    seen = []
    records = evaluate.execute(runs, tmp_path / "out", on_done=lambda run, record, how: seen.append(how))
    assert seen == ["ran", "ran"]
    assert [p.name for p in (tmp_path / "out" / "kernel-base").iterdir()] == ["part-00000.parquet"]
    assert records[0]["metrics"]["steps"] == 50 and records[0]["metrics"]["timed_out"] is True
    seen.clear()
    again = evaluate.execute(runs, tmp_path / "out", on_done=lambda run, record, how: seen.append(how))
    assert seen == ["stored", "stored"] and again == records


def test_two_controllers_keep_their_own_records(tmp_path, tiny):
    course = load_course(tiny)
    runs = [
        *evaluate.course_runs(parse_controller("kernel"), [course], [0]),
        *evaluate.course_runs(parse_controller("kernel:ext"), [course], [0]),
    ]
    for _ in range(2):  # run, then read back from storage
        records = evaluate.execute(runs, tmp_path)
        labels = [r["controller"]["label"] for r in records]
        assert labels == ["kernel-base", "kernel-base", "kernel-ext", "kernel-ext"]
        assert records[0]["metrics"] != records[2]["metrics"]


def test_results_do_not_depend_on_the_worker_count(tmp_path, tiny):
    runs = evaluate.course_runs(parse_controller("kernel"), [load_course(tiny)], seeds=[0])
    one = evaluate.execute(runs, tmp_path / "one", workers=1)
    two = evaluate.execute(runs, tmp_path / "two", workers=2)
    for a, b in zip(one, two, strict=True):
        a["metrics"].pop("wall_seconds"), b["metrics"].pop("wall_seconds")
        assert a == b


def test_a_changed_course_or_a_corrupt_file_is_refused(tmp_path, tiny):
    spec = parse_controller("kernel")
    out = tmp_path / "out"
    evaluate.execute(evaluate.course_runs(spec, [load_course(tiny)], [0]), out)
    tiny.write_text(TINY.replace("[3.0, 0.0]", "[4.0, 0.0]"))
    changed = evaluate.course_runs(spec, [load_course(tiny)], [0])
    with pytest.raises(evaluate.EvaluationError, match="made by a different course than this run"):
        evaluate.execute(changed, out)
    part = out / "kernel-base" / "part-00000.parquet"
    part.write_bytes(part.read_bytes()[:-100])
    with pytest.raises(evaluate.EvaluationError, match=r"part-00000\.parquet: damaged record part"):
        evaluate.execute(changed, out)


def test_push_sweep_records_the_push(tmp_path):
    sweep = PushSweep(magnitudes=(300.0, 600.0), attempts=1, window=(0.05, 0.1), time_limit=0.3)
    runs = evaluate.push_runs(parse_controller("kernel"), sweep)
    assert [t.key for t in runs] == ["push/m300-a0", "push/m600-a0"]
    records = evaluate.execute(runs, tmp_path)
    push = records[1]["metrics"]["push"]
    assert push["magnitude"] == pytest.approx(600.0)
    assert push["impulse"] == pytest.approx(600.0 * 60 * 0.001)  # 60 control steps, 1 ms each
    rows = summaries.summarise_push(records)
    assert [r["magnitude"] for r in rows] == [300.0, 600.0] and rows[0]["attempts"] == 1


def test_a_pushed_walk_records_the_heading_at_the_push():
    from krl.eval.episodes import score_walk
    from krl.sim.model import build_model
    from krl.sim.pushes import Push
    from krl.sim.robot import A1Sim

    def heading(start_time, yaw):
        force = np.array([0.0, 300.0, 0.0])
        push = Push(start_time=start_time, force=force, point=np.zeros(3), duration=0.05)
        controller = parse_controller("kernel").build()
        metrics = score_walk(A1Sim(build_model("flat")), controller, np.array([[3.0, 0.0]]), (0.0, 0.0, yaw),
                             0.2, 0.5, push=push)  # fmt: skip
        return metrics["push_heading"]

    assert heading(0.1, 0.7) == pytest.approx(0.7, abs=0.05)  # the base's yaw, not the target's direction
    assert heading(0.1, -0.4) == pytest.approx(-0.4, abs=0.05)
    assert heading(0.5, 0.7) is None  # the run ended before the push


def test_course_summary_by_hand():
    def record(reached, fell, reward, error=None):
        success = reached == 5 and not fell and error is None
        return {
            "metrics": {
                "targets": 5,
                "targets_reached": reached,
                "success": success,
                "fell": fell,
                "error": error,
                "reward_per_step": reward,
                "distance_walked": 1.0,
                "time_to_finish": 30.0 if success else None,
            }
        }

    summary = summaries.summarise_course(
        [
            record(5, False, 0.1),
            record(3, True, 0.05),
            record(0, False, 0.02, "MPCError: x"),
            record(5, False, 0.09),
        ]
    )
    assert summary["runs"] == 4
    assert summary["targets_reached_mean"] == pytest.approx(13 / 4)
    assert summary["targets_reached_std"] == pytest.approx(2.3629078, rel=1e-6)  # sample std of 5, 3, 0, 5
    assert summary["success_rate"] == 0.5 and summary["fall_rate"] == 0.5 and summary["error_runs"] == 1
    assert summary["time_to_finish_mean"] == 30.0


def test_unknown_controller_and_missing_model():
    with pytest.raises(ControllerSpecError, match="unknown controller 'ppo'"):
        parse_controller("ppo")
    with pytest.raises(ControllerSpecError, match="no kernel file"):
        parse_controller("kernel:/nowhere/kernel.npz")


def test_cli_evaluate_then_report(tmp_path, tiny, capsys):
    out, docs = tmp_path / "results", tmp_path / "docs"
    argv = [
        "evaluate",
        "--controller",
        "kernel",
        "--course",
        str(tiny),
        "--out",
        str(out),
        "--workers",
        "1",
        "--quiet",
        "--json",
    ]
    assert main(argv) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["ran"] == 2 and summary["controllers"]["kernel-base"]["tiny"]["runs"] == 2
    assert main(argv) == 0
    assert json.loads(capsys.readouterr().out)["ran"] == 0
    assert main(["report", "--results", str(out), "--out", str(docs), "--json"]) == 0
    written = json.loads(capsys.readouterr().out)["written"]
    assert str(docs / "evaluation.md") in written and (docs / "courses.png").exists()
    text = (docs / "evaluation.md").read_text()
    assert "krl evaluate --controller kernel" in text and "| krl | kernel-base" in text


@pytest.mark.parametrize(
    "argv, message",
    [
        (["evaluate", "--controller", "ppo", "--course", "flat"], "unknown controller 'ppo'"),
        (["evaluate", "--controller", "kernel:missing.npz", "--course", "flat"], "no kernel file"),
        (["evaluate", "--controller", "expert", "--course", "moon"], "unknown course 'moon'"),
        (["evaluate", "--controller", "expert", "--push-sweep", "--magnitudes", "9:1:5"], "--magnitudes"),
        (["report", "--results", "/nonexistent/results"], "no results directory"),
    ],
)
def test_cli_errors_are_one_line(argv, message, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_video_of_the_first_run(tmp_path, tiny):
    from krl.sim.render import FrameRenderer, RenderError

    try:
        FrameRenderer(load_course(tiny).build().model, 32, 32).close()
    except RenderError as error:
        pytest.skip(f"offscreen rendering unavailable: {error}")
    runs = evaluate.course_runs(
        parse_controller("kernel"), [load_course(tiny)], [0], video_dir=tmp_path / "v"
    )
    assert [t.video is not None for t in runs] == [True, False]
    evaluate.execute(runs, tmp_path / "out")
    video = tmp_path / "v" / "kernel-base" / "tiny-start0.mp4"
    assert video.stat().st_size > 1000


def evaluate_argv(out, *options):
    return ["evaluate", *options, "--out", str(out), "--workers", "1", "--quiet", "--json"]


def test_a_users_kernel_file_named_like_a_shipped_one_keeps_its_own_results(tmp_path, tiny, capsys):
    """The issue's case: kernel and kernel:X/kernel-base.npz (a copy of kernel-ext) on one course."""
    import shutil

    from krl.kernel.registry import shipped_model_path

    copy = tmp_path / "X" / "kernel-base.npz"
    copy.parent.mkdir()
    shutil.copy(shipped_model_path("ext"), copy)
    user = parse_controller(f"kernel:{copy}")
    assert user.label == f"kernel-base-{user.content_hash[:6]}" != parse_controller("kernel").label
    out = tmp_path / "EVZ"
    controllers = ["--controller", "kernel", "--controller", f"kernel:{copy}"]
    argv = evaluate_argv(out, *controllers, "--course", str(tiny))
    assert main(argv) == 0
    summary = json.loads(capsys.readouterr().out)
    assert (summary["runs"], summary["ran"]) == (4, 4)
    assert sorted(summary["controllers"]) == sorted(["kernel-base", user.label])
    stored = sorted(str(p.relative_to(out)) for p in out.rglob("*.parquet"))
    assert stored == sorted(f"{label}/part-00000.parquet" for label in summary["controllers"])
    base, ext = (stored_record(out, label, "tiny/start0") for label in summary["controllers"])
    assert base["metrics"] != ext["metrics"]
    assert main(argv) == 0  # and a re-run finds both, each made by its own controller
    assert json.loads(capsys.readouterr().out)["stored"] == 4


def test_a_kernel_npz_takes_its_folders_name(tmp_path):
    import shutil

    from krl.kernel.registry import shipped_model_path

    paths = {}
    for folder, model in (("mine", "base"), ("kernel-ext", "base"), ("kernel-base", "base")):
        paths[folder] = tmp_path / folder / "kernel.npz"
        paths[folder].parent.mkdir()
        shutil.copy(shipped_model_path(model), paths[folder])
    assert parse_controller(f"kernel:{paths['mine']}").label == "kernel-mine"
    ext = parse_controller(f"kernel:{paths['kernel-ext']}")
    assert ext.label == f"kernel-ext-{ext.content_hash[:6]}"  # "ext" is a shipped kernel's name
    # a byte-identical copy of the shipped kernel it is named after is that kernel
    assert parse_controller(f"kernel:{paths['kernel-base']}").label == "kernel-base"


def test_a_seed_group_named_as_a_shipped_agent_takes_its_label_only_as_a_byte_identical_copy(tmp_path):
    import shutil

    from krl.agent.policy import policy_artifacts

    whole, part = tmp_path / "whole" / "agent-gait-ground", tmp_path / "part" / "agent-gait-ground"
    for group, seeds in ((whole, 4), (part, 2)):  # all four seeds' files, and two of them
        group.mkdir(parents=True)
        for seed, path in policy_artifacts("gait-ground")[1][:seeds]:
            shutil.copy(path, group / f"seed{seed}.npz")
    assert parse_controller(f"agent:{whole}").label == "agent-gait-ground"
    two = parse_controller(f"agent:{part}")
    assert two.label == f"agent-gait-ground-{two.content_hash[:6]}"


def test_two_different_files_of_one_label_are_refused_before_anything_is_written(tmp_path, tiny, capsys):
    import shutil

    from krl.kernel.registry import shipped_model_path

    paths = []
    for run, model in (("a", "base"), ("b", "ext")):
        paths.append(tmp_path / run / "x" / "kernel.npz")
        paths[-1].parent.mkdir(parents=True)
        shutil.copy(shipped_model_path(model), paths[-1])
    out = tmp_path / "out"
    controllers = ["--controller", f"kernel:{paths[0]}", "--controller", f"kernel:{paths[1]}"]
    assert main(evaluate_argv(out, *controllers, "--course", str(tiny))) == 2
    err = capsys.readouterr().err
    assert "two different controllers are labelled 'kernel-x'" in err and str(paths[1]) in err
    assert err.count("\n") == 1 and not out.exists()


def test_two_courses_of_one_name_are_refused_before_anything_is_written(tmp_path, tiny, capsys):
    mine = tmp_path / "mine.toml"
    mine.write_text(TINY.replace('name = "tiny"', 'name = "flat"'))
    out = tmp_path / "out"
    assert main(evaluate_argv(out, "--controller", "kernel", "--course", "flat", "--course", str(mine))) == 2
    err = capsys.readouterr().err
    assert "two different courses are named 'flat'" in err and str(mine) in err and err.count("\n") == 1
    assert not out.exists()


def test_the_same_course_or_controller_twice_runs_once(tmp_path, tiny, capsys):
    controllers = ["--controller", "kernel", "--controller", "kernel:base"]
    argv = evaluate_argv(tmp_path, *controllers, "--course", str(tiny), "--course", str(tiny))
    assert main(argv) == 0
    summary = json.loads(capsys.readouterr().out)
    assert (summary["runs"], summary["ran"]) == (2, 2) and list(summary["controllers"]) == ["kernel-base"]


def test_two_different_runs_never_share_a_result_file(tmp_path, tiny):
    from dataclasses import replace

    course = load_course(tiny)
    other = replace(course, waypoints=((4.0, 0.0),))  # same name, other content
    runs = evaluate.course_runs(parse_controller("kernel"), [course, other], [0])
    with pytest.raises(
        evaluate.EvaluationError, match=r"run kernel-base tiny/start0 would be two different runs"
    ):
        evaluate.execute(runs, tmp_path / "out")
    assert not (tmp_path / "out").exists()
    kernel = parse_controller("kernel")
    impostor = replace(parse_controller("kernel:ext"), label=kernel.label)
    runs = [*evaluate.course_runs(kernel, [course], [0]), *evaluate.course_runs(impostor, [course], [0])]
    with pytest.raises(evaluate.EvaluationError, match=r"two different runs .*controller"):
        evaluate.execute(runs, tmp_path / "out")


def test_a_refused_evaluation_writes_nothing(tmp_path, tiny, capsys):
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as stop:  # a usage error (krl.cli.common.process_count)
        main([*evaluate_argv(out, "--controller", "kernel", "--course", str(tiny)), "--workers", "0"])
    err = capsys.readouterr().err
    assert stop.value.code == 2 and "at least 1, got 0" in err and err.count("\n") == 1 and not out.exists()
    assert main(evaluate_argv(out, "--controller", "kernel", "--course", str(tiny))) == 0
    capsys.readouterr()
    tiny.write_text(TINY.replace("[3.0, 0.0]", "[4.0, 0.0]"))  # same name, other course
    argv = evaluate_argv(out, "--controller", "kernel", "--course", str(tiny), "--seeds", "1")
    assert main(argv) == 2
    assert "made by a different course" in capsys.readouterr().err
    assert len((out / "kernel-base" / "commands.txt").read_text().splitlines()) == 1


def test_success_interval_is_wilsons():
    from scipy.stats import binomtest

    for attempts in (1, 3, 10, 50):
        for successes in range(attempts + 1):
            expected = binomtest(successes, attempts).proportion_ci(method="wilson")
            low, high = summaries.success_interval(successes, attempts)
            assert (low, high) == pytest.approx((expected.low, expected.high), abs=1e-12)
    assert summaries.success_interval(10, 10)[1] == 1.0 and summaries.success_interval(0, 10)[0] == 0.0
    with pytest.raises(ValueError, match="successes <= attempts"):
        summaries.success_interval(11, 10)


def test_push_table_shows_the_attempts_and_intervals():
    from krl.eval import sweep_report

    def record(magnitude, success, azimuth=0.0):
        force = [magnitude * np.cos(azimuth), magnitude * np.sin(azimuth), 0.0]
        push = {"impulse": magnitude * 0.06, "delta_v": magnitude * 0.06 / 12.46, "force": force}
        metrics = {"success": success, "fell": not success, "error": None, "push": push}
        return {"magnitude": magnitude, "sweep": {"target": [3.0, 0.0]}, "metrics": metrics}

    records = [record(300.0, a < 48) for a in range(50)] + [record(600.0, a < 20) for a in range(50)]
    rows = summaries.summarise_push(records)
    assert [r["success_rate"] for r in rows] == [0.96, 0.4]
    assert rows[0]["success_low"] < 0.96 < rows[0]["success_high"] < 1.0
    pushes = sweep_report.push_rows({"agent-rp": {evaluate.PUSH_DIR: records}})
    thesis = [r for r in pushes if r["source"] == "thesis"]
    assert all(
        r["attempts"] == 10 and r["success_low"] <= r["success_rate"] <= r["success_high"] for r in thesis
    )
    table = sweep_report.push_markdown(pushes)
    rows = [
        [c.strip() for c in line.strip("|").split("|")] for line in table.splitlines() if line[:2] == "| "
    ]
    cells = {row[1]: row[2:] for row in rows}  # controller: one cell per magnitude, 250 ... 900 N
    assert cells["agent-rp (50 attempts)"][:8] == ["–", "0.96", "–", "–", "–", "–", "–", "0.40"]
    assert cells["Agent-rp"][:8] == ["1.0", "1.0", "1.0", "1.0", "0.9", "0.8", "0.9", "0.8"]  # the thesis's
    assert "95 % Wilson interval" in table


def test_push_directions_are_quarters_around_the_walk():
    from krl.eval import sweep_report

    def record(azimuth_deg, success, target=(3.0, 0.0), magnitude=400.0):
        azimuth = np.radians(azimuth_deg)
        metrics = {
            "success": success,
            "push": {"force": [magnitude * np.cos(azimuth), magnitude * np.sin(azimuth), 50.0]},
        }
        return {"sweep": {"target": list(target)}, "magnitude": magnitude, "metrics": metrics}

    assert [summaries.push_direction(record(a, True)) for a in (10, 80, -170, -100, 44, 46)] == [
        "forward", "left", "backward", "right", "forward", "left",
    ]  # fmt: skip
    assert summaries.push_direction(record(100, True, target=(0.0, 3.0))) == "forward"  # walking along +y
    turned = record(100, True)
    turned["metrics"]["push_heading"] = np.pi / 2  # walking along +y when the push came, target along +x
    assert summaries.push_direction(turned) == "forward"
    turned["metrics"]["push_heading"] = None  # the run ended before the push: the target's direction
    assert summaries.push_direction(turned) == "left"
    records = [record(0, True), record(0, False), record(90, False), record(-90, True)]
    rows = {r["direction"]: r for r in summaries.summarise_push_directions(records)}
    assert set(rows) == {"forward", "left", "right"}  # no backward push: no row
    assert rows["forward"]["attempts"] == 2 and rows["forward"]["success_rate"] == 0.5
    assert rows["left"]["success_high"] < 1.0 and rows["right"]["success_low"] > 0.0
    by_band = sweep_report.push_direction_rows(
        {"x": {evaluate.PUSH_DIR: [*records, record(90, True, magnitude=700)]}}
    )
    left = {row["forces"]: row for row in by_band if row["direction"] == "left"}
    assert (left["all"]["attempts"], left["all"]["success_rate"]) == (2, 0.5)
    assert (left["350-600"]["attempts"], left["350-600"]["success_rate"]) == (1, 0.0)  # not the 700 N push
    table = sweep_report.push_direction_markdown(by_band)
    assert "| x | 0.50 (2), " in table and "| – |" in table and "Forces 350-600 N:" in table
