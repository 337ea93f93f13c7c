"""A results folder fixes what each label is when first written (the controller's files and options, seed
by seed, and the content of each course it walked): a later call under that label with another is refused
in one line before any run, even where it would run none of the stored runs again."""

import json
from pathlib import Path

from agent_fakes import make_policy
from eval_fakes import stored_record

from krl.agent.config import AgentConfig
from krl.cli import main
from krl.util.hashing import file_sha256


def evaluate_argv(out, *options):
    """``krl evaluate`` with ``options``, one worker, quiet, JSON summary, results in ``out``."""
    return ["evaluate", *options, "--out", str(out), "--workers", "1", "--quiet", "--json"]


def renamed(course: Path, name: str) -> Path:
    """A copy of the course file ``course`` under another course name (its own file)."""
    path = course.with_name(f"{name}.toml")
    path.write_text(course.read_text().replace('name = "tiny"', f'name = "{name}"'))
    return path


def folder_state(out: Path) -> dict[str, bytes]:
    """Every file under ``out`` with its bytes: what a refused call must leave as it was."""
    return {str(path.relative_to(out)): path.read_bytes() for path in out.rglob("*") if path.is_file()}


def test_another_policy_under_a_stored_label_is_refused_before_any_run(tmp_path, tiny, capsys):
    # before the fix, the second call ran and `krl report` showed one agent-p of two policies
    policy, out = tmp_path / "p.npz", tmp_path / "out"
    make_policy(AgentConfig(), seed=1).save(policy)
    first = file_sha256(policy)
    assert main(evaluate_argv(out, "--controller", f"agent:{policy}", "--course", str(tiny))) == 0
    make_policy(AgentConfig(), scale=0.1, seed=2).save(policy)
    before = folder_state(out)
    capsys.readouterr()
    argv = evaluate_argv(out, "--controller", f"agent:{policy}", "--course", str(renamed(tiny, "other")))
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "'agent-p'" in err, err
    assert first in err and file_sha256(policy) in err
    assert folder_state(out) == before


def test_a_changed_seed_file_is_refused_even_when_another_seed_runs(tmp_path, tiny, capsys):
    group, out = tmp_path / "mine", tmp_path / "out"
    group.mkdir()
    for seed in (1, 2):
        make_policy(AgentConfig(), seed=seed).save(group / f"policy-seed{seed}.npz")
    controller = ["--controller", f"agent:{group}", "--course", str(tiny)]
    assert main(evaluate_argv(out, *controller, "--seeds", "1")) == 0
    stored = stored_record(out, "agent-mine", "tiny/start0-seed1")["controller"]["model_sha256"]
    make_policy(AgentConfig(), scale=0.1, seed=1).save(group / "policy-seed1.npz")
    capsys.readouterr()
    assert main(evaluate_argv(out, *controller, "--seeds", "2")) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "'agent-mine'" in err and "seed 1" in err, err
    assert stored in err and file_sha256(group / "policy-seed1.npz") in err
    (group / "policy-seed1.npz").unlink()  # a group that lost a seed keeps the other seeds' records
    capsys.readouterr()
    assert main(evaluate_argv(out, *controller)) == 0
    assert json.loads(capsys.readouterr().out)["ran"] == 1


def test_a_course_file_changed_between_calls_is_refused(tmp_path, tiny, capsys):
    group, out = tmp_path / "mine", tmp_path / "out"
    group.mkdir()
    for seed in (1, 2):
        make_policy(AgentConfig(), seed=seed).save(group / f"policy-seed{seed}.npz")
    controller = ["--controller", f"agent:{group}", "--course", str(tiny)]
    assert main(evaluate_argv(out, *controller, "--seeds", "1")) == 0
    stored = stored_record(out, "agent-mine", "tiny/start0-seed1")["course_fingerprint"]
    tiny.write_text(tiny.read_text().replace("[3.0, 0.0]", "[4.0, 0.0]"))  # same name, another course
    before = folder_state(out)
    capsys.readouterr()
    assert main(evaluate_argv(out, *controller, "--seeds", "2")) == 2  # runs of seed 2 alone
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "'agent-mine'" in err and "course 'tiny'" in err, err
    assert stored in err and folder_state(out) == before


def test_the_same_controller_and_courses_resume_and_grow(tmp_path, tiny, capsys):
    out = tmp_path / "out"
    assert main(evaluate_argv(out, "--controller", "kernel", "--course", str(tiny))) == 0
    capsys.readouterr()
    courses = ["--course", str(tiny), "--course", str(renamed(tiny, "b"))]
    argv = evaluate_argv(out, "--controller", "kernel", *courses)
    assert main(argv) == 0
    summary = json.loads(capsys.readouterr().out)
    assert (summary["ran"], summary["stored"]) == (1, 1)


def test_a_repeated_push_magnitude_is_one_run_in_the_summary(tmp_path, capsys):
    # before the fix, --magnitudes 300,300 stored one run per attempt but the summary said attempts 2
    out = tmp_path / "out"
    argv = ["--controller", "kernel", "--push-sweep", "--magnitudes", "300,300", "--attempts", "1"]
    assert main(evaluate_argv(out, *argv)) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["runs"] == summary["ran"] == 1
    assert summary["push_sweep"]["magnitudes"] == [300]
    ((row),) = summary["controllers"]["kernel-base"]["push"]
    assert row["attempts"] == 1


def test_a_repeated_seed_is_one_run_in_the_summary(tmp_path, tiny, capsys):
    group, out = tmp_path / "mine", tmp_path / "out"
    group.mkdir()
    make_policy(AgentConfig(), seed=1).save(group / "policy-seed1.npz")
    argv = evaluate_argv(out, "--controller", f"agent:{group}", "--course", str(tiny), "--seeds", "1,1")
    assert main(argv) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["runs"] == summary["ran"] == summary["controllers"]["agent-mine"]["tiny"]["runs"] == 1
