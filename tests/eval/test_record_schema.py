"""A stored record is read whole or refused: every field its readers need, of its type, checked on read
(one line naming the file and the field, from krl report, krl evaluate's resumption and the push sweep's
analysis alike); krl convert-results writes only parts those readers accept."""

import json
from pathlib import Path

import pytest
from eval_fakes import as_json_layout

from krl.analysis.push_sweep import push_sweep_markdown
from krl.cli import main
from krl.eval import records

EVALUATIONS = Path(__file__).parents[2] / "evaluations"
"""The evaluations this repository keeps, made by krl versions since the first."""


def evaluate_argv(out, tiny):
    """A krl evaluate of kernel-base on the tiny course and one push, resumable in ``out``."""
    return [
        "evaluate", "--controller", "kernel", "--course", str(tiny), "--push-sweep", "--magnitudes", "300",
        "--attempts", "1", "--out", str(out), "--workers", "1", "--quiet", "--json",
    ]  # fmt: skip


def forge(part: Path, run: str, change) -> None:
    """Rewrite ``part`` with ``change(record)`` applied to run ``run``'s record, its columns and SHA-256
    made anew: a part whose every check but the record's fields passes."""
    found = records.read_part(part, part.parent.name)
    for record in found:
        if record["run"] == run:
            change(record)
    part.write_bytes(records.part_bytes(part.parent.name, found))


def refusals(out, tiny, capsys) -> list[str]:
    """The errors of krl report, krl evaluate's resumption and the push sweep's analysis on ``out``."""
    errors = []
    for argv in (
        ["report", "--results", str(out), "--out", str(out.parent / "report")],
        evaluate_argv(out, tiny),
    ):
        capsys.readouterr()
        assert main(argv) == 2
        errors.append(capsys.readouterr().err)
    with pytest.raises(ValueError) as refused:  # what its command prints in one line
        push_sweep_markdown(out)
    return [*errors, f"krl: error: {refused.value}\n"]


def test_a_part_with_a_null_success_is_refused_in_one_line(tmp_path, tiny, capsys):
    # before the fix, krl report and the resumption failed with a traceback (a TypeError)
    out = tmp_path / "out"
    assert main(evaluate_argv(out, tiny)) == 0
    part = out / "kernel-base" / "part-00000.parquet"
    forge(part, "tiny/start0", lambda record: record["metrics"].update(success=None))
    for err in refusals(out, tiny, capsys):
        assert err.count("\n") == 1 and f"{part} (run tiny/start0)" in err, err
        assert "field metrics.success is null, not a boolean" in err


def test_an_old_json_row_with_only_its_success_is_refused_in_one_line(tmp_path, tiny, capsys):
    out = tmp_path / "out"
    assert main(evaluate_argv(out, tiny)) == 0
    as_json_layout(out)
    row = out / "kernel-base" / "push" / "m300-a0.json"
    row.write_text(json.dumps({"metrics": {"success": True}}))
    for err in refusals(out, tiny, capsys):
        assert err.count("\n") == 1 and f"{row}: field controller is missing" in err, err


def test_a_damaged_part_is_refused_by_the_push_sweeps_analysis_as_by_krl_report(tmp_path, tiny, capsys):
    # before the fix, python -m krl.analysis.push_sweep printed a traceback (a RuntimeError)
    out = tmp_path / "out"
    assert main(evaluate_argv(out, tiny)) == 0
    part = out / "kernel-base" / "part-00000.parquet"
    part.write_bytes(part.read_bytes()[:-1])
    for err in refusals(out, tiny, capsys):
        assert err.count("\n") == 1 and f"{part}: damaged record part" in err, err


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda record: record.pop("controller"), "field controller is missing"),
        (lambda record: record["metrics"].update(fell="no"), 'field metrics.fell is "no", not a boolean'),
        (lambda record: record.update(controller={**record["controller"], "label": "x"}), "controller 'x'"),
        (lambda record: record.update(run="tiny/start9"), "record of run 'tiny/start9'"),
    ],
)
def test_convert_refuses_a_record_its_readers_would_refuse_and_writes_nothing(
    tmp_path, tiny, capsys, change, message
):
    # before the fix, krl convert-results wrote a part that every later krl evaluate and krl report refused
    out = tmp_path / "out"
    assert main(evaluate_argv(out, tiny)) == 0
    as_json_layout(out)
    row = out / "kernel-base" / "tiny" / "start0.json"
    record = json.loads(row.read_text())
    change(record)
    row.write_text(json.dumps(record))
    before = {path: path.read_bytes() for path in out.rglob("*") if path.is_file()}
    capsys.readouterr()
    assert main(["convert-results", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{row}: " in err and message in err, err
    assert {path: path.read_bytes() for path in out.rglob("*") if path.is_file()} == before


def test_every_stored_version_converts_to_a_part_that_reads_back(tmp_path, tiny, capsys):
    # the older layout of today's records, of the first records (no run key, no machine), and one holding NaN
    out = tmp_path / "out"
    argv = evaluate_argv(out, tiny)
    assert main([*argv, "--friction-sweep", "--frictions", "0.5", "--friction-course", str(tiny)]) == 0
    as_json_layout(out)
    rows = sorted((out / "kernel-base").rglob("*.json"))
    first = json.loads(rows[0].read_text())
    del first["run"], first["machine"], first["metrics"]["ended"]
    rows[0].write_text(json.dumps(first))
    nan = json.loads(rows[1].read_text())
    nan["metrics"]["reward_per_step"] = float("nan")  # a query column of the part
    rows[1].write_text(json.dumps(nan))
    stored = records.read_runs(out / "kernel-base")
    assert main(["convert-results", str(out)]) == 0
    converted = records.read_runs(out / "kernel-base")
    assert [p.name for p in records.part_files(out / "kernel-base")] == ["part-00000.parquet"]
    assert not list(out.rglob("*.json"))
    assert json.dumps([s.record for s in converted.values()]) == json.dumps(
        [s.record for s in stored.values()]
    )
    capsys.readouterr()
    assert main(argv) == 0  # and krl evaluate resumes from it
    assert json.loads(capsys.readouterr().out)["stored"] == 2


def test_every_evaluation_this_repository_keeps_reads_and_round_trips(tmp_path):
    folders = sorted({part.parent.parent for part in EVALUATIONS.glob("*/*/part-*.parquet")})
    assert len(folders) >= 6  # evaluations made by krl versions of several dates
    for folder in folders:
        part = min(folder.glob("*/part-*.parquet"), key=lambda path: path.stat().st_size)
        label = part.parent.name
        found = records.read_part(part, label)
        assert (
            records.read_part(records.write_part(tmp_path / folder.name / label, label, found), label)
            == found
        )
