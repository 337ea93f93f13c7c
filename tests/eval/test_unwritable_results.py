"""A result file krl cannot write (a full disk, a read-only folder) is one line naming that file, not the
temporary file it was being written through (issue 61: M2 and the full disk)."""

from __future__ import annotations

import errno
from pathlib import Path

import pytest

from krl.cli import main
from krl.util import output
from krl.util.output import write_atomic


def failing_writes(monkeypatch, under: Path, code: int) -> None:
    """Every temporary file :func:`write_atomic` opens under ``under`` fails with ``code`` (root may write
    into a chmod'ed folder, so the failure is simulated), as the system reports it: naming the temporary
    file."""
    mkstemp = output.tempfile.mkstemp

    def refused(dir, prefix, suffix):
        if Path(dir).is_relative_to(under):
            raise OSError(code, output.os.strerror(code), f"{dir}/{prefix}x1y2z3{suffix}")
        return mkstemp(dir=dir, prefix=prefix, suffix=suffix)

    monkeypatch.setattr(output.tempfile, "mkstemp", refused)


def test_a_full_disk_names_the_file_and_keeps_its_kind(tmp_path, monkeypatch):
    failing_writes(monkeypatch, tmp_path, errno.ENOSPC)
    with pytest.raises(OSError) as failed:
        write_atomic(tmp_path / "records" / "part.npz", b"data")
    assert str(failed.value) == f"cannot write {tmp_path / 'records' / 'part.npz'}: No space left on device"
    assert failed.value.errno == errno.ENOSPC
    failing_writes(monkeypatch, tmp_path, errno.EACCES)
    with pytest.raises(PermissionError):
        write_atomic(tmp_path / "table.csv", "a,b\n")


def test_a_folder_that_cannot_be_made_is_named(tmp_path):
    (tmp_path / "a-file").write_text("not a folder")
    with pytest.raises(NotADirectoryError) as failed:
        write_atomic(tmp_path / "a-file" / "results" / "table.csv", "a,b\n")
    folder = tmp_path / "a-file" / "results"
    assert str(failed.value) == f"cannot write {folder / 'table.csv'}: {folder}: Not a directory"


@pytest.fixture
def results(tmp_path, tiny, capsys) -> Path:
    """A results folder of one expert run on the tiny course."""
    out = tmp_path / "results"
    argv = ["evaluate", "--controller", "expert", "--course", str(tiny), "--out", str(out)]
    assert main([*argv, "--workers", "1", "--quiet"]) == 0
    capsys.readouterr()
    return out


def test_evaluate_and_report_into_read_only_folders_are_one_line_naming_the_file(
    results, tiny, tmp_path, capsys, monkeypatch
):
    failing_writes(monkeypatch, results, errno.EACCES)
    argv = ["evaluate", "--controller", "expert", "--course", str(tiny), "--out", str(results)]
    assert main([*argv, "--workers", "1", "--quiet", "--json"]) == 2  # a new command: remembered
    assert capsys.readouterr().err == (
        f"krl: error: cannot write {results / 'expert-stance0.2' / 'commands.txt'}: Permission denied\n"
    )
    report = tmp_path / "report"
    report.mkdir()
    failing_writes(monkeypatch, report, errno.EROFS)
    assert main(["report", "--results", str(results), "--out", str(report)]) == 2
    assert capsys.readouterr().err == (
        f"krl: error: cannot write {report / 'course-tiny.csv'}: Read-only file system\n"
    )
