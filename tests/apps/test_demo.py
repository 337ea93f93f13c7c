"""``krl demo`` end to end, smoke-sized (the flat course cut short, no video)."""

from __future__ import annotations

import json

import pytest
from eval_fakes import short_flat

from krl.cli import main


def test_demo_writes_its_plot_and_table(tmp_path, capsys):
    out = tmp_path / "demo"
    course = short_flat(tmp_path)
    code = main(
        ["demo", "--out", str(out), "--course", str(course), "--workers", "1", "--no-video", "--quiet"]
    )
    assert code == 0
    printed = capsys.readouterr().out
    assert f"path: {out / 'path.png'}" in printed and "metrics:" in printed
    assert (out / "path.png").stat().st_size > 10_000
    table = (out / "metrics.md").read_text()
    assert "kernel-base" in table and "expert-stance0.2" in table


def test_demo_says_there_will_be_no_video_before_the_walks(tmp_path, monkeypatch, capsys):
    import krl.sim.render

    problem = "offscreen rendering needs the OSMesa library (libOSMesa not found): apt-get install libosmesa6"
    monkeypatch.setattr(krl.sim.render, "rendering_problem", lambda: problem)
    said = []  # what stderr held when the walks would start (they are skipped: no walk runs)

    def no_walks(*args, **kwargs):
        said.append(capsys.readouterr().err)
        return []

    monkeypatch.setattr("krl.util.parallel.run_jobs", no_walks)
    course = tmp_path / "mine.toml"
    course.write_text(
        'format = 1\nname = "mine"\ndescription = "one waypoint"\ntime_limit = 4.0\nd_min = 0.5\n'
        'waypoints = [[0.6, 0.0]]\nstarts = [[0.0, 0.0, 0.0]]\n[terrain]\nname = "flat"\nseed = 0\n'
    )
    argv = ["demo", "--out", str(tmp_path / "demo"), "--course", str(course), "--workers", "1", "--quiet"]
    assert main(argv) == 0
    assert said == [f"krl demo: no video: {problem}\n"]  # on stderr, one line, before any walk ran


def test_demo_walks_the_controllers_given_in_order(tmp_path, monkeypatch, capsys):
    course = tmp_path / "short.toml"
    course.write_text(
        'format = 1\nname = "short"\ndescription = "one waypoint"\ntime_limit = 3.0\nd_min = 0.5\n'
        'waypoints = [[0.6, 0.0]]\nstarts = [[0.0, 0.0, 0.0]]\n[terrain]\nname = "flat"\nseed = 0\n'
    )
    out = tmp_path / "demo"
    argv = ["demo", "--out", str(out), "--course", str(course), "--controller", "agent:gait"]
    assert main([*argv, "--controller", "kernel:ext", "--workers", "1", "--no-video", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert [row["controller"] for row in summary["runs"]] == ["agent-gait-seed150", "kernel-ext"]


def test_demo_refuses_an_unknown_controller_in_one_line(tmp_path, capsys):
    argv = ["demo", "--out", str(tmp_path / "demo"), "--controller", "agent:nowhere", "--no-video"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "agent:nowhere" in err
    assert not (tmp_path / "demo").exists()


def test_demo_says_what_it_films_and_writes_the_video(tmp_path, capsys):
    from krl.sim.render import rendering_problem

    if rendering_problem() is not None:
        pytest.skip(rendering_problem())
    course = tmp_path / "short.toml"
    course.write_text(
        'format = 1\nname = "short"\ndescription = "one waypoint"\ntime_limit = 1.0\nd_min = 0.5\n'
        'waypoints = [[0.6, 0.0]]\nstarts = [[0.0, 0.0, 0.0]]\n[terrain]\nname = "flat"\nseed = 0\n'
    )
    out = tmp_path / "demo"
    argv = ["demo", "--out", str(out), "--course", str(course), "--controller", "kernel", "--workers", "1"]
    assert main([*argv, "--quiet"]) == 0
    said = capsys.readouterr().err
    assert "krl demo: filming kernel-base: 31 frames (1 s of walking)" in said
    assert (out / "kernel-base-short.mp4").stat().st_size > 0
