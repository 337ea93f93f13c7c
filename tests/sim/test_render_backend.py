"""The offscreen backend choice: OSMesa only when there is no display, no user choice, and the library."""

from __future__ import annotations

import os
import subprocess
import sys

from krl.sim.render import offscreen_backend


def found(name: str) -> str:
    return f"lib{name}.so.8"


def missing(name: str) -> None:
    return None


def test_osmesa_is_chosen_on_a_headless_machine_that_has_it():
    assert offscreen_backend({}, found) == {"MUJOCO_GL": "osmesa", "PYOPENGL_PLATFORM": "osmesa"}


def test_nothing_is_chosen_without_the_library_a_display_or_against_the_users_choice():
    assert offscreen_backend({}, missing) == {}
    assert offscreen_backend({"DISPLAY": ":0"}, found) == {}
    assert offscreen_backend({"MUJOCO_GL": "egl"}, found) == {}


def test_import_krl_and_krl_help_work_without_any_gl_library():
    environment = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    environment.pop("DISPLAY", None)
    code = (
        "import ctypes.util; ctypes.util.find_library = lambda name: None\n"
        "import sys; from krl.cli import main\n"
        "sys.exit(main(['terrains']))\n"
    )
    result = subprocess.run([sys.executable, "-c", code], env=environment, capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert "heightfield" in result.stdout


def test_without_the_library_rendering_says_what_to_install():
    environment = {
        k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM", "DISPLAY")
    }
    code = (
        "import ctypes.util; ctypes.util.find_library = lambda name: None\n"
        "import sys; from krl.cli import main\n"
        "sys.exit(main(['render', '--terrain', 'flat', '--out', 'x.png']))\n"
    )
    result = subprocess.run([sys.executable, "-c", code], env=environment, capture_output=True, text=True)
    assert result.returncode == 2
    assert result.stderr.strip().splitlines()[-1] == (
        "krl: error: offscreen rendering needs the OSMesa library (libOSMesa not found): "
        "apt-get install libosmesa6 (with sudo when not root)"
    )


def test_a_failed_gl_start_is_remembered_and_never_retried(monkeypatch):
    """A second failed start of MuJoCo's GL backend aborts the interpreter, so it is not tried twice."""
    import mujoco
    import pytest

    from krl.sim import render

    starts = []

    def failing_renderer(*args, **kwargs):
        starts.append(args)
        raise AttributeError("'NoneType' object has no attribute 'glGetError'")

    monkeypatch.setattr(render, "_backend_failure", None)
    monkeypatch.setattr(mujoco, "Renderer", failing_renderer)
    model = mujoco.MjModel.from_xml_string("<mujoco><worldbody><body name='trunk'/></worldbody></mujoco>")
    for _ in range(3):
        with pytest.raises(render.RenderError, match="libosmesa6"):
            render.FrameRenderer(model, 16, 16)
    assert len(starts) == 1
    assert render.rendering_problem() is not None and len(starts) == 1


def test_asking_again_after_a_failed_gl_start_does_not_abort_the_interpreter():
    """Found by a fresh clone without libosmesa6: a second failed start of MuJoCo's GLFW backend aborted
    the process (libc++abi "recursive initialization", exit 134). GLFW without a display fails to start."""
    environment = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    environment["MUJOCO_GL"] = "glfw"
    code = (
        "from krl.sim.render import rendering_problem\n"
        "print(sum(rendering_problem() is not None for _ in range(3)))\n"
    )
    result = subprocess.run([sys.executable, "-c", code], env=environment, capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "3"
