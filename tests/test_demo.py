"""``krl demo`` end to end, smoke-sized (one controller on the flat course, no video)."""

from __future__ import annotations

from krl.cli import main


def test_demo_writes_its_plot_and_table(tmp_path, capsys):
    out = tmp_path / "demo"
    code = main(["demo", "--out", str(out), "--course", "flat", "--workers", "1", "--no-video", "--quiet"])
    assert code == 0
    printed = capsys.readouterr().out
    assert f"path: {out / 'path.png'}" in printed and "metrics:" in printed
    assert (out / "path.png").stat().st_size > 10_000
    table = (out / "metrics.md").read_text()
    assert "kernel-base" in table and "expert-stance0.2" in table
