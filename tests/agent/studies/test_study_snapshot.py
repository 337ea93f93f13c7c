"""``krl agent study NAME --snapshot DIR`` on a tiny real study: the database and run folders without
TensorBoard files, whole files only, stale files of an older snapshot gone, and a study copied back from
it resumes with nothing left to train."""

from __future__ import annotations

import json
import shutil

from agent_fakes import TINY_STUDY

from krl.agent.studies.runner import LIST
from krl.cli import main


def _study(tmp_path, out, *extra: str) -> list[str]:
    tiny = tmp_path / "tiny.json"
    tiny.write_text(json.dumps(TINY_STUDY))
    argv = ["agent", "study", "alternative", "--out", str(out), "--seeds", "7", "--budget", "256"]
    return [*argv, "--config", str(tiny), "--workers", "1", "--jobs", "1", "--quiet", "--json", *extra]


def test_a_snapshot_holds_what_resumes_the_study_and_nothing_else(tmp_path, capsys):
    import optuna

    out, snap = tmp_path / "study", tmp_path / "snapshot"
    assert main(_study(tmp_path, out)) == 0
    capsys.readouterr()
    stale = snap / "trials" / "list" / "residual-seed7" / "checkpoints" / "00000000001" / "model.zip"
    stale.parent.mkdir(parents=True)
    stale.write_bytes(b"an older snapshot's checkpoint")
    (snap / ".study.db.x.tmp").write_bytes(b"")  # a temporary file of a stopped snapshot: not a run's
    assert main(_study(tmp_path, out, "--snapshot", str(snap))) == 0
    written = json.loads(capsys.readouterr().out)
    assert written["database"] == str(snap / "study.db")
    assert written["runs"] == ["list/commands-seed7", "list/residual-seed7"]
    for entry in ("commands-seed7", "residual-seed7"):
        run, copy = out / "trials" / "list" / entry, snap / "trials" / "list" / entry
        assert any(path.name.startswith("events.out") for path in run.iterdir())  # TensorBoard's
        expected = sorted(
            p.relative_to(run) for p in run.rglob("*") if p.is_file() and not p.name.startswith("events.out")
        )
        assert sorted(p.relative_to(copy) for p in copy.rglob("*") if p.is_file()) == expected
        assert all((copy / p).read_bytes() == (run / p).read_bytes() for p in expected)
    assert not stale.parent.exists() and not list(snap.glob("**/*.tmp"))
    url = f"sqlite:///{snap / 'study.db'}"
    states = [t.state.name for t in optuna.load_study(study_name="alternative", storage=url).trials]
    assert states == ["COMPLETE", "COMPLETE"]

    restored = tmp_path / "restored"
    shutil.copytree(snap, restored)
    assert main(_study(tmp_path, restored)) == 0  # resumes: both runs finished, nothing trains
    assert json.loads(capsys.readouterr().out)[LIST] == {
        "finished": 2,
        "pruned": 0,
        "failed": 0,
        "missing": 0,
    }
    assert sorted(p.name for p in (restored / "trials" / "list").iterdir()) == [
        "commands-seed7",
        "residual-seed7",
    ]


def test_nothing_to_snapshot_is_one_line(tmp_path, capsys):
    argv = [
        "agent",
        "study",
        "alternative",
        "--out",
        str(tmp_path / "none"),
        "--snapshot",
        str(tmp_path / "s"),
    ]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "cannot snapshot study alternative: nothing to snapshot" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "s").exists()
