"""Without a GL library, a rendering command's error is its one line, not GLFW's warnings before it."""

from __future__ import annotations

import os
import subprocess
import sys


def _krl(argv: list[str], environment: dict[str, str], cwd, prelude: str = "") -> subprocess.CompletedProcess:
    """``krl ARGV`` in a fresh interpreter (MuJoCo's backend is chosen at its first import), after
    ``prelude``; its exit status and output."""
    code = f"{prelude}import sys; from krl.cli import main\nsys.exit(main({argv!r}))\n"
    return subprocess.run(
        [sys.executable, "-c", code], env=environment, cwd=cwd, capture_output=True, text=True
    )


def test_render_without_any_gl_library_is_one_line(tmp_path):
    environment = {
        k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM", "DISPLAY")
    }
    without_osmesa = "import ctypes.util; ctypes.util.find_library = lambda name: None\n"
    result = _krl(["render", "--terrain", "flat", "--out", "x.png"], environment, tmp_path, without_osmesa)
    assert result.returncode == 2
    assert result.stderr == (
        "krl: error: offscreen rendering needs the OSMesa library (libOSMesa not found): "
        "apt-get install libosmesa6 (with sudo when not root)\n"
    )


def test_a_rendering_backend_mujoco_cannot_load_is_one_line_for_every_command(tmp_path):
    """MuJoCo loads its MUJOCO_GL backend on import; one that cannot load (here an unknown value; on a
    machine without libEGL, ``egl``) fails even a command that never renders: in one line, not a traceback."""
    environment = {**os.environ, "MUJOCO_GL": "vulkan-please"}
    result = _krl(["agent", "info"], environment, tmp_path)
    assert result.returncode == 2
    assert result.stderr == (
        "krl: error: MuJoCo could not load its rendering backend MUJOCO_GL=vulkan-please (RuntimeError: "
        "invalid value for environment variable MUJOCO_GL: vulkan-please); set MUJOCO_GL=osmesa (apt-get "
        "install libosmesa6 (with sudo when not root)), or MUJOCO_GL=disable where nothing is rendered\n"
    )
    assert list(tmp_path.iterdir()) == []
