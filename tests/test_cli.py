"""The krl command: render (headless), bench, terrains, and one-line errors."""

import json
import os

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
    pixels = list(image.convert("L").getdata())
    assert max(pixels) - min(pixels) > 50  # not a blank frame
    assert "wrote" in capsys.readouterr().out


def test_bench_sim_json(capsys):
    assert main(["bench", "sim", "--json", "--steps", "50", "--repeats", "1"]) == 0
    result = json.loads(capsys.readouterr().out)
    for key in ("raw_steps_per_s", "env_steps_per_s", "ratio"):
        assert result[key] > 0
    assert set(result["terrains"]) == {"flat", "heightfield"}


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
