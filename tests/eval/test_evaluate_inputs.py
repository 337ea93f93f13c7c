"""krl evaluate's inputs: checked before anything is written; a controller is known by its files' content."""

import hashlib
import json
import re
import shutil
from pathlib import Path

import pytest
from agent_fakes import make_policy
from eval_fakes import as_json_layout, stored_record

from krl.agent.config import AgentConfig
from krl.agent.policy import shipped_policy_dir
from krl.cli import main
from krl.eval.controllers import ControllerSpecError, distinct_controllers, parse_controller
from krl.kernel.registry import shipped_model_path
from krl.util.hashing import file_sha256

SHIPPED_GROUP = shipped_policy_dir() / "agent-rp"
SHIPPED_RP = SHIPPED_GROUP / "seed150.npz"


def evaluate_argv(out, *options):
    """``krl evaluate`` with ``options``, one worker, quiet, JSON summary, results in ``out``."""
    return ["evaluate", *options, "--out", str(out), "--workers", "1", "--quiet", "--json"]


def per_seed_folder(folder: Path, seeds) -> Path:
    """A run folder of per-seed policies (as ``krl agent train`` over several seeds leaves them)."""
    folder.mkdir(parents=True)
    for seed in seeds:
        make_policy(AgentConfig(), seed=seed).save(folder / f"policy-seed{seed}.npz")
    return folder


def copy_of(source: Path, target: Path) -> Path:
    """A byte-identical copy of ``source`` at ``target``."""
    target.parent.mkdir(parents=True, exist_ok=True)
    shutil.copy(source, target)
    return target


@pytest.mark.parametrize(
    "options, message",
    [
        (["--course", "TINY", "--seeds", "150"], "no policy for seed 150 (has seeds 1, 2)"),
        (["--push-sweep", "--attempts", "1", "--seeds", "2,3"], "no policy for seed 3 (has seeds 1, 2)"),
    ],
)
def test_a_run_without_its_policy_is_refused_before_anything_is_written(
    tmp_path, tiny, capsys, options, message
):
    folder = per_seed_folder(tmp_path / "runs" / "mine", [1, 2])
    out = tmp_path / "out"
    options = [str(tiny) if option == "TINY" else option for option in options]
    assert main(evaluate_argv(out, "--controller", f"agent:{folder}", *options)) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not out.exists()


def test_controllers_of_no_file_still_make_their_tasks(tiny):
    from krl.eval import evaluate
    from krl.eval.courses import load_course

    for text in ("expert", "kernel", "agent:rp@150"):
        runs = evaluate.course_runs(parse_controller(text), [load_course(tiny)], [150, 215])
        assert [run.key for run in runs] == ["tiny/start0"]


def test_a_seed_group_runs_every_seed_it_holds_unless_told(tmp_path, tiny):
    from krl.eval import evaluate
    from krl.eval.courses import load_course
    from krl.eval.episodes import PushSweep

    spec = parse_controller(f"agent:{per_seed_folder(tmp_path / 'agent-mine', [556, 150, 345, 215])}")
    course = load_course(tiny)
    keys = [run.key for run in evaluate.course_runs(spec, [course])]
    assert keys == [f"tiny/start0-seed{seed}" for seed in (150, 215, 345, 556)]
    assert [run.seed for run in evaluate.course_runs(spec, [course], [345])] == [345]
    sweep = PushSweep(magnitudes=(300.0,), attempts=2)
    pushes = evaluate.push_runs(spec, sweep, [150, 215])
    assert [(run.key, run.seed) for run in pushes] == [
        ("push/m300-a0-seed150", 150),
        ("push/m300-a1-seed150", 150),
        ("push/m300-a0-seed215", 215),
        ("push/m300-a1-seed215", 215),
    ]
    assert pushes[0].identity()["seed"] == 150
    assert "seed" not in evaluate.push_runs(parse_controller("kernel"), sweep)[0].identity()


@pytest.mark.parametrize(
    "spellings",
    [
        ["agent", "agent:rp", f"agent:{SHIPPED_GROUP}"],
        ["agent:rp@150", f"agent:{SHIPPED_RP}", "agent:COPY/agent-rp.npz"],
        [f"agent:{SHIPPED_RP}", "agent:COPY/agent-rp.npz", "agent:OTHER/agent-rp.npz"],
        ["kernel", f"kernel:{shipped_model_path('base')}", "kernel:COPY/kernel-base.npz"],
    ],
)
def test_one_file_given_several_ways_is_one_controller_under_its_first_label(tmp_path, spellings):
    """By name, by path, or as a byte-identical copy: one controller, labelled as first given."""
    copy_of(SHIPPED_RP, tmp_path / "COPY" / "agent-rp.npz")
    copy_of(SHIPPED_RP, tmp_path / "OTHER" / "agent-rp.npz")
    copy_of(shipped_model_path("base"), tmp_path / "COPY" / "kernel-base.npz")
    folders = {name: str(tmp_path / name) for name in ("COPY", "OTHER")}
    texts = [text.replace("COPY", folders["COPY"]).replace("OTHER", folders["OTHER"]) for text in spellings]
    specs = [parse_controller(text) for text in texts]
    assert distinct_controllers(specs) == [specs[0]]


def test_two_policies_of_one_label_are_still_refused(tmp_path):
    paths = []
    for run, seed in (("a", 1), ("b", 2)):
        paths.append(make_policy(AgentConfig(), scale=0.1, seed=seed).save(tmp_path / run / "agent-mine.npz"))
    specs = [parse_controller(f"agent:{path}") for path in paths]
    with pytest.raises(ControllerSpecError, match="two different controllers are labelled 'agent-mine'"):
        distinct_controllers(specs)


def test_the_shipped_policy_and_its_path_are_evaluated_once(tmp_path, tiny, capsys):
    out = tmp_path / "out"
    controllers = ["--controller", "agent", "--controller", f"agent:{SHIPPED_GROUP}"]
    assert main(evaluate_argv(out, *controllers, "--course", str(tiny), "--seeds", "150")) == 0
    summary = json.loads(capsys.readouterr().out)
    assert (summary["runs"], summary["ran"]) == (1, 1) and list(summary["controllers"]) == ["agent-rp"]
    assert [row["seed"] for row in summary["controllers"]["agent-rp"]["tiny"]["by_seed"]] == [150]
    assert sorted(path.name for path in out.iterdir()) == ["agent-rp"]


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            "expert:swing=0.3",
            "controller 'expert:swing=0.3': expert options are stance=VALUE, step=VALUE, ride=VALUE",
        ),
        ("expert:stance", "expert options are stance=VALUE"),
        ("expert:stance=fast", "stance must be a number, got 'fast'"),
        ("expert:step=inf", "step must be a number, got 'inf'"),
        ("gait:ride=nan", "ride must be a number, got 'nan'"),
    ],
)
def test_a_controllers_numeric_options_are_known_and_finite(text, message):
    with pytest.raises(ControllerSpecError, match=re.escape(message)):
        parse_controller(text)


def test_a_group_that_gains_a_seed_keeps_the_records_of_the_others(tmp_path, tiny, capsys):
    group = per_seed_folder(tmp_path / "agent-mine", [150])
    out = tmp_path / "out"
    argv = evaluate_argv(out, "--controller", f"agent:{group}", "--course", str(tiny))
    assert main(argv) == 0
    (label,) = (path.name for path in out.iterdir())
    first = stored_record(out, label, "tiny/start0-seed150")
    assert first["controller"]["model_sha256"] == file_sha256(group / "policy-seed150.npz")
    make_policy(AgentConfig(), seed=215).save(group / "policy-seed215.npz")
    capsys.readouterr()
    assert main(argv) == 0
    summary = json.loads(capsys.readouterr().out)
    assert (summary["ran"], summary["stored"]) == (1, 1)
    assert stored_record(out, label, "tiny/start0-seed150") == first


def test_a_policy_file_in_two_groups_runs_once_and_each_group_keeps_its_record(tmp_path, tiny, capsys):
    """A variant's two seeds that are also two of a seed group's four (agent-gait, the chosen variant)."""
    variant = per_seed_folder(tmp_path / "variant", [150, 215])
    group = tmp_path / "group"
    for seed in (150, 215):
        copy_of(variant / f"policy-seed{seed}.npz", group / f"seed{seed}.npz")
    make_policy(AgentConfig(), seed=345).save(group / "seed345.npz")
    out = tmp_path / "out"
    controllers = ["--controller", f"agent:{variant}", "--controller", f"agent:{group}"]
    assert main(evaluate_argv(out, *controllers, "--course", str(tiny))) == 0
    summary = json.loads(capsys.readouterr().out)
    assert (summary["runs"], summary["ran"], summary["stored"], summary["shared"]) == (5, 3, 0, 2)
    labels = sorted(summary["controllers"])
    assert labels == sorted(parse_controller(f"agent:{folder}").label for folder in (variant, group))
    for seed in (150, 215):
        a, b = (stored_record(out, label, f"tiny/start0-seed{seed}") for label in labels)
        assert a["controller"]["label"] != b["controller"]["label"]
        assert {**a, "controller": None} == {**b, "controller": None}
    # alone, the group computes the same records as the copies it was given
    assert (
        main(evaluate_argv(tmp_path / "alone", "--controller", f"agent:{group}", "--course", str(tiny))) == 0
    )
    group_label = parse_controller(f"agent:{group}").label
    for seed in (150, 215):
        copied, alone = (
            stored_record(folder, group_label, f"tiny/start0-seed{seed}")
            for folder in (out, tmp_path / "alone")
        )
        copied["metrics"].pop("wall_seconds"), alone["metrics"].pop("wall_seconds")
        assert copied == alone
    # a group added later copies the stored records of the files it shares instead of running them again
    capsys.readouterr()
    later = tmp_path / "later"
    assert main(evaluate_argv(later, "--controller", f"agent:{variant}", "--course", str(tiny))) == 0
    capsys.readouterr()
    assert main(evaluate_argv(later, *controllers, "--course", str(tiny))) == 0
    summary = json.loads(capsys.readouterr().out)
    assert (summary["ran"], summary["stored"], summary["shared"]) == (1, 2, 2)


def test_records_that_named_the_whole_group_are_kept_while_its_files_are_unchanged(tmp_path, tiny, capsys):
    group = per_seed_folder(tmp_path / "agent-mine", [150, 215])
    out = tmp_path / "out"
    argv = evaluate_argv(out, "--controller", f"agent:{group}", "--course", str(tiny))
    assert main(argv) == 0
    files = [file_sha256(group / f"policy-seed{seed}.npz") for seed in (150, 215)]
    group_hash = hashlib.sha256(f"150:{files[0]}\n215:{files[1]}".encode()).hexdigest()
    as_json_layout(out)
    for record in out.glob("*/tiny/*.json"):  # as krl wrote a group's records before they named one file
        data = json.loads(record.read_text())
        data["controller"].update(model_sha256=group_hash, seeds=[150, 215])
        record.write_text(json.dumps(data))
    capsys.readouterr()
    assert main(argv) == 0
    assert json.loads(capsys.readouterr().out)["stored"] == 2
    make_policy(AgentConfig(), scale=0.1, seed=215).save(group / "policy-seed215.npz")
    assert main(argv) == 2
    assert "was made by a different controller than this run" in capsys.readouterr().err
