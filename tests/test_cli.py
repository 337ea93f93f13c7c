"""The krl command: render (headless), bench, terrains, and one-line errors."""

import json
import os

import numpy as np
import pytest

from krl.cli import main

needs_gl = pytest.mark.skipif(
    os.environ.get("MUJOCO_GL", "osmesa") == "osmesa"
    and not any(
        os.path.exists(p)
        for p in ("/usr/lib/x86_64-linux-gnu/libOSMesa.so.8", "/usr/lib/aarch64-linux-gnu/libOSMesa.so.8")
    ),
    reason="offscreen rendering needs libosmesa6 (installed by .ci/run)",
)


@needs_gl
@pytest.mark.parametrize("terrain", ["flat", "stairs"])
def test_render_writes_a_png(tmp_path, terrain, capsys):
    from PIL import Image

    out = tmp_path / f"{terrain}.png"
    assert main(["render", "--terrain", terrain, "--out", str(out), "--width", "320", "--height", "240"]) == 0
    image = Image.open(out)
    assert image.size == (320, 240)
    pixels = np.asarray(image.convert("L"))
    assert int(pixels.max()) - int(pixels.min()) > 50  # not a blank frame
    assert "wrote" in capsys.readouterr().out


@needs_gl
def test_render_a_course_shows_its_waypoints(tmp_path, capsys):
    from PIL import Image

    out = tmp_path / "tabletop.png"
    argv = ["render", "--course", "tabletop", "--out", str(out), "--width", "320", "--height", "240"]
    assert main(argv) == 0
    pixels = np.asarray(Image.open(out).convert("RGB")).astype(int)
    red = (pixels[..., 0] > 150) & (pixels[..., 1] < 60) & (pixels[..., 2] < 60)
    assert red.sum() > 50  # the red waypoint posts are in the picture
    assert "terrain tabletop" in capsys.readouterr().out


def test_bench_sim_json(capsys):
    assert main(["bench", "sim", "--json", "--steps", "50", "--repeats", "1"]) == 0
    result = json.loads(capsys.readouterr().out)
    for key in ("raw_steps_per_s", "env_steps_per_s", "ratio"):
        assert result[key] > 0
    assert set(result["terrains"]) == {"flat", "heightfield"}


def test_bench_terrains_compares_each_terrain_with_flat_ground(capsys):
    argv = ["bench", "terrains", "--terrain", "pyramids", "--steps", "400", "--repeats", "1", "--json"]
    assert main(argv) == 0
    result = json.loads(capsys.readouterr().out)
    assert list(result["terrains"]) == ["flat", "pyramids"]
    flat, pyramids = result["terrains"].values()
    assert flat["step_vs_flat"] == 1.0 and flat["contacts"] == 4  # four feet down on flat ground
    assert pyramids["step_vs_flat"] == pyramids["step_us"] / flat["step_us"]
    assert all(row[key] > 0 for row in (flat, pyramids) for key in ("add_terrain_ms", "compile_ms"))


@pytest.mark.parametrize("bad, named", [(["--terrain", "moon"], "moon"), (["--steps", "0"], "step")])
def test_bench_terrains_refuses_bad_input_in_one_line(bad, named, capsys):
    assert main(["bench", "terrains", *bad, "--json"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("krl: error:") and named in err and err.count("\n") == 1


def test_terrains_lists_every_terrain(capsys):
    from krl.sim.terrains import TERRAIN_NAMES

    assert main(["terrains"]) == 0
    out = capsys.readouterr().out
    assert all(name in out for name in TERRAIN_NAMES)


def test_unknown_terrain_is_one_line_error(tmp_path, capsys):
    out = tmp_path / "x.png"
    assert main(["render", "--terrain", "moon", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("krl: error:") and "moon" in err and err.count("\n") == 1
    assert not out.exists()


def test_bad_param_syntax(capsys):
    assert main(["render", "--terrain", "flat", "--param", "oops", "--out", "x.png"]) == 2
    assert "KEY=VALUE" in capsys.readouterr().err


def test_view_without_display_explains(monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert main(["view", "--terrain", "flat"]) == 2
    assert "krl render" in capsys.readouterr().err


def test_expert_run_json(capsys):
    assert main(["expert", "run", "--command", "0.3,0,0", "--duration", "2.5", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    for key in ("targets_reached", "fell", "sim_seconds", "wall_seconds", "mpc_ms_median", "mean_velocity"):
        assert key in result
    assert not result["fell"] and result["sim_seconds"] == pytest.approx(2.5)
    assert len(result["mean_velocity"]) == 3


def test_expert_run_to_given_waypoints(capsys):
    assert main(["expert", "run", "--target", "0.8,0", "--target", "0.8,0.8", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["targets_reached"] == 2 and not result["fell"]


@needs_gl
def test_expert_run_writes_a_video(tmp_path, capsys):
    import imageio.v2 as imageio

    video = tmp_path / "walk.mp4"
    assert main(["expert", "run", "--command", "0.2,0,0", "--duration", "2.1", "--video", str(video)]) == 0
    assert imageio.get_reader(video).count_frames() == pytest.approx(63, abs=1)  # 2.1 s at 30 fps


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["expert", "run", "--stance-duration", "-0.2"], "stance_duration"),
        (["expert", "run", "--step-height", "0.5"], "step_height"),
        (["expert", "run", "--command", "0.3,0"], "--command expects 3"),
        (["expert", "run", "--targets", "0"], "--targets must be >= 1, got 0"),
        (["expert", "run", "--targets", "-3"], "--targets must be >= 1, got -3"),
        (["expert", "run", "--target-time-limit", "-5"], "target_time_limit must be a positive number"),
        (["expert", "run", "--target-time-limit", "0"], "target_time_limit must be a positive number"),
    ],
)
def test_expert_run_bad_options(argv, message, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
