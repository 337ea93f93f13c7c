"""krl evaluate's record store: Parquet parts per controller, the older JSON layout still read, and every
damaged, foreign or half-written part refused or redone in one line, never mixed into results."""

import functools
import json

import pytest
from eval_fakes import as_json_layout, complete_record

from krl.cli import main
from krl.eval import evaluate, records
from krl.eval.controllers import parse_controller
from krl.eval.courses import load_course
from krl.eval.episodes import PushSweep
from krl.util.machine import machine

SWEEP = PushSweep(magnitudes=(300.0, 600.0), attempts=2, window=(0.05, 0.1), time_limit=0.15)


def runs_of(tiny, controller="kernel"):
    spec = parse_controller(controller)
    return [*evaluate.course_runs(spec, [load_course(tiny)]), *evaluate.push_runs(spec, SWEEP)]


def test_records_go_to_one_part_per_controller_and_read_back_equal(tmp_path, tiny):
    out = tmp_path / "out"
    ran = evaluate.execute(runs_of(tiny), out)
    assert sorted(p.name for p in (out / "kernel-base").iterdir()) == ["part-00000.parquet"]
    runs = records.read_runs(out / "kernel-base")
    assert list(runs) == ["push/m300-a0", "push/m300-a1", "push/m600-a0", "push/m600-a1", "tiny/start0"]
    assert sorted(ran, key=lambda r: records.run_order(r["run"])) == [s.record for s in runs.values()]
    assert all(s.record["machine"] == machine() for s in runs.values())  # where its arithmetic was done
    import pyarrow.parquet as pq  # the query columns repeat the records' fields

    table = pq.read_table(out / "kernel-base" / "part-00000.parquet").to_pylist()
    assert list(table[0]) == list(records.COLUMNS)
    for row, stored in zip(table, runs.values(), strict=True):
        assert json.loads(row["record"]) == stored.record and row["fell"] == stored.record["metrics"]["fell"]


def test_batches_become_parts_and_are_merged_into_one_at_the_end(tmp_path, tiny, monkeypatch):
    out = tmp_path / "out"
    parts = []
    real = records._next_part
    monkeypatch.setattr(records, "_next_part", lambda *args: parts.append(real(*args)) or parts[-1])
    monkeypatch.setattr(evaluate, "RecordWriter", functools.partial(records.RecordWriter, flush_records=2))
    evaluate.execute(runs_of(tiny), out)
    assert len(parts) == 4  # 2 + 2 + 1 records, then the merged part
    assert [p.name for p in (out / "kernel-base").glob("*.parquet")] == ["part-00000.parquet"]
    assert len(records.read_runs(out / "kernel-base")) == 5


def test_an_interrupted_evaluation_keeps_every_record_it_reported(tmp_path, tiny):
    out = tmp_path / "out"
    seen = []

    def stop_after_two(run, record, how):
        seen.append(run.key)
        if len(seen) == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        evaluate.execute(runs_of(tiny), out, on_done=stop_after_two)
    assert list(records.read_runs(out / "kernel-base")) == sorted(seen, key=records.run_order)
    how = []
    evaluate.execute(runs_of(tiny), out, on_done=lambda run, record, done: how.append(done))
    assert how.count("stored") == 2 and how.count("ran") == 3


def test_a_half_written_part_is_removed_with_one_line_and_its_runs_redone(tmp_path, tiny, capsys):
    out = tmp_path / "out"
    evaluate.execute(runs_of(tiny)[:1], out)
    leftover = out / "kernel-base" / ".part-00001.parquet.x1y2z3.tmp"
    leftover.write_bytes(b"PAR1 half")
    how = []
    evaluate.execute(runs_of(tiny), out, on_done=lambda run, record, done: how.append(done))
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"removed {leftover}" in err and not leftover.exists()
    assert how.count("stored") == 1 and how.count("ran") == 4


def test_a_damaged_part_is_refused_in_one_line(tmp_path, tiny, capsys):
    out = tmp_path / "out"
    argv = ["evaluate", "--controller", "kernel", "--course", str(tiny), "--out", str(out), "--quiet"]
    assert main(argv) == 0
    part = out / "kernel-base" / "part-00000.parquet"
    good = part.read_bytes()
    for damaged in (good[: len(good) // 2], good[:-1], b""):
        part.write_bytes(damaged)
        capsys.readouterr()
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"{part}: damaged record part" in err and "delete it" in err
        assert main(["report", "--results", str(out), "--out", str(tmp_path / "report")]) == 2
        assert f"{part}: damaged record part" in capsys.readouterr().err


def test_a_flipped_byte_is_refused_or_changes_nothing(tmp_path, tiny):
    out = tmp_path / "out"
    evaluate.execute(runs_of(tiny), out)
    part = out / "kernel-base" / "part-00000.parquet"
    good, runs = part.read_bytes(), records.read_part(part, "kernel-base")
    refused = 0
    offsets = range(0, len(good), 13)
    for offset in offsets:
        part.write_bytes(good[:offset] + bytes([good[offset] ^ 0x5A]) + good[offset + 1 :])
        try:
            assert records.read_part(part, "kernel-base") == runs, offset  # a byte nothing decoded depends on
        except records.EvaluationError as error:
            assert "damaged record part" in str(error) and "\n" not in str(error)
            refused += 1
    assert refused > len(offsets) // 4  # the rest: statistics, padding, the magic number


def test_a_part_whose_records_do_not_match_their_hash_is_refused(tmp_path, tiny):
    import pyarrow as pa
    import pyarrow.parquet as pq

    out = tmp_path / "out"
    evaluate.execute(runs_of(tiny), out)
    part = out / "kernel-base" / "part-00000.parquet"
    table = pq.read_table(part)
    texts = table.column("record").to_pylist()
    texts[0] = texts[0].replace('"success": false', '"success": true')
    forged = table.set_column(table.schema.get_field_index("record"), "record", pa.array(texts))
    pq.write_table(forged, part)
    with pytest.raises(records.EvaluationError, match="do not match their SHA-256"):
        records.read_runs(out / "kernel-base")


def test_a_part_of_another_controller_or_course_is_refused(tmp_path, tiny):
    out = tmp_path / "out"
    evaluate.execute(runs_of(tiny), out)
    evaluate.execute(runs_of(tiny, "kernel:ext"), out)
    part = out / "kernel-ext" / "part-00000.parquet"
    part.write_bytes((out / "kernel-base" / "part-00000.parquet").read_bytes())
    with pytest.raises(
        records.EvaluationError, match="holds records of controller 'kernel-base', not 'kernel-ext'"
    ):
        evaluate.execute(runs_of(tiny, "kernel:ext"), out)
    tiny.write_text(tiny.read_text().replace("[3.0, 0.0]", "[4.0, 0.0]"))
    message = r"kernel-base/part-00000\.parquet \(run tiny/start0\) was made by a different course"
    with pytest.raises(records.EvaluationError, match=message):
        evaluate.execute(runs_of(tiny), out)


def test_a_run_stored_twice_is_one_run_when_equal_and_refused_when_not(tmp_path, tiny):
    out = tmp_path / "out"
    evaluate.execute(runs_of(tiny), out)
    folder = out / "kernel-base"
    runs = records.read_runs(folder)
    copy = records.write_part(folder, "kernel-base", [runs["tiny/start0"].record])  # a merge cut short
    assert {run: stored.record for run, stored in records.read_runs(folder).items()} == {
        run: stored.record for run, stored in runs.items()
    }
    again = {
        **runs["tiny/start0"].record,
        "metrics": {**runs["tiny/start0"].record["metrics"], "wall_seconds": 9},
    }
    copy.write_bytes(records.part_bytes("kernel-base", [again]))  # the run redone: the newer record is kept
    assert records.read_runs(folder)["tiny/start0"] == records.StoredRun(again, copy)
    elsewhere = {**again, "machine": {**again["machine"], "cpu": "another"}}  # redone on another machine
    copy.write_bytes(records.part_bytes("kernel-base", [elsewhere]))
    assert records.read_runs(folder)["tiny/start0"] == records.StoredRun(elsewhere, copy)
    changed = {**runs["tiny/start0"].record, "metrics": {**runs["tiny/start0"].record["metrics"], "steps": 1}}
    copy.write_bytes(records.part_bytes("kernel-base", [changed]))
    with pytest.raises(records.EvaluationError, match="run kernel-base tiny/start0 is stored twice"):
        records.read_runs(folder)


def test_a_converted_folder_reads_as_the_unconverted_one(tmp_path, tiny, capsys):
    out = tmp_path / "out"
    argv = ["evaluate", "--controller", "kernel", "--controller", "expert", "--course", str(tiny)]
    argv += ["--push-sweep", "--magnitudes", "300", "--attempts", "2", "--out", str(out), "--json", "--quiet"]
    assert main(argv) == 0
    summary = json.loads(capsys.readouterr().out)
    as_json_layout(out)  # as krl wrote it before Parquet
    assert len(list(out.rglob("*.json"))) == 6 and not list(out.rglob("*.parquet"))
    assert main(["report", "--results", str(out), "--out", str(tmp_path / "before"), "--json"]) == 0
    assert main(argv) == 0
    capsys.readouterr()
    assert main(["convert-results", str(out), "--json"]) == 0
    converted = json.loads(capsys.readouterr().out)
    assert (converted["runs"], converted["json_removed"]) == (6, 6)
    assert sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file()) == [
        "expert-stance0.2/commands.txt",
        "expert-stance0.2/part-00000.parquet",
        "kernel-base/commands.txt",
        "kernel-base/part-00000.parquet",
    ]
    assert main(argv) == 0
    again = json.loads(capsys.readouterr().out)
    assert again["stored"] == 6 and {**again, "stored": 0, "ran": 6} == summary
    assert main(["report", "--results", str(out), "--out", str(tmp_path / "after"), "--json"]) == 0
    for name in ("course-tiny.csv", "push.csv"):
        assert (tmp_path / "after" / name).read_bytes() == (tmp_path / "before" / name).read_bytes()
    capsys.readouterr()
    assert main(["convert-results", str(out), "--json"]) == 0  # nothing left to convert
    assert json.loads(capsys.readouterr().out)["json_removed"] == 0


def test_convert_names_a_missing_folder_or_controller_in_one_line(tmp_path, capsys):
    assert main(["convert-results", str(tmp_path / "nowhere")]) == 2
    assert "no results folder" in capsys.readouterr().err
    assert main(["convert-results", str(tmp_path), "--controller", "kernel-base"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no results for controller 'kernel-base'" in err


def _write_parts(folder, first, count):
    """Write ``count`` parts of one record each, then merge (in a process of its own)."""
    for index in range(first, first + count):
        record = complete_record({"run": f"tiny/start{index}"}, "kernel-base")
        records.write_part(folder, "kernel-base", [record])
    records.consolidate(folder)


def test_two_writers_of_one_controller_keep_every_record(tmp_path):
    import multiprocessing

    folder = tmp_path / "kernel-base"
    context = multiprocessing.get_context("fork")
    writers = [context.Process(target=_write_parts, args=(folder, first, 40)) for first in (0, 1000)]
    for writer in writers:
        writer.start()
    for writer in writers:
        writer.join(timeout=60)
        assert writer.exitcode == 0
    runs = records.read_runs(folder)
    assert len(runs) == 80
    records.consolidate(folder)
    assert [p.name for p in records.part_files(folder)] == ["part-00000.parquet"]
    assert records.read_runs(folder) == runs


def test_a_run_redone_for_its_missing_video_replaces_its_record(tmp_path, tiny):
    from krl.sim.render import FrameRenderer, RenderError

    try:
        FrameRenderer(load_course(tiny).build().model, 32, 32).close()
    except RenderError as error:
        pytest.skip(f"offscreen rendering unavailable: {error}")
    spec = parse_controller("kernel")
    runs = evaluate.course_runs(spec, [load_course(tiny)], video_dir=tmp_path / "v")
    out = tmp_path / "out"
    first = evaluate.execute(runs, out)
    (video,) = (tmp_path / "v").rglob("*.mp4")
    video.unlink()
    as_json_layout(out)  # the older layout too: its file goes once a part holds the newer record
    how = []
    second = evaluate.execute(runs, out, on_done=lambda run, record, done: how.append(done))
    assert how == ["ran"] and video.exists()
    assert [p.name for p in (out / "kernel-base").rglob("*.*")] == ["part-00000.parquet"]
    assert records.read_runs(out / "kernel-base")["tiny/start0"].record == second[0]
    assert (
        evaluate.execute(runs, out) == second
        and first[0]["metrics"]["steps"] == second[0]["metrics"]["steps"]
    )
