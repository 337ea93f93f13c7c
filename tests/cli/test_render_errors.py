"""Without a GL library, a rendering command's error is its one line, not GLFW's warnings before it."""

from __future__ import annotations

import os
import subprocess
import sys


def test_render_without_any_gl_library_is_one_line(tmp_path):
    environment = {
        k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM", "DISPLAY")
    }
    code = (
        "import ctypes.util; ctypes.util.find_library = lambda name: None\n"  # as without libosmesa6
        "import sys; from krl.cli import main\n"
        "sys.exit(main(['render', '--terrain', 'flat', '--out', 'x.png']))\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], env=environment, cwd=tmp_path, capture_output=True, text=True
    )
    assert result.returncode == 2
    assert result.stderr == (
        "krl: error: offscreen rendering needs the OSMesa library (libOSMesa not found): "
        "apt-get install libosmesa6 (with sudo when not root)\n"
    )


def test_a_rendering_backend_mujoco_cannot_load_is_one_line_for_every_command(tmp_path):
    """MuJoCo loads its MUJOCO_GL backend on import; one that cannot load (here an unknown value; on a
    machine without libEGL, ``egl``) fails even a command that never renders: in one line, not a traceback."""
    environment = {**os.environ, "MUJOCO_GL": "vulkan-please"}
    code = "import sys; from krl.cli import main\nsys.exit(main(['agent', 'info']))\n"
    result = subprocess.run(
        [sys.executable, "-c", code], env=environment, cwd=tmp_path, capture_output=True, text=True
    )
    assert result.returncode == 2
    assert result.stderr == (
        "krl: error: MuJoCo could not load its rendering backend MUJOCO_GL=vulkan-please (RuntimeError: "
        "invalid value for environment variable MUJOCO_GL: vulkan-please); set MUJOCO_GL=osmesa (apt-get "
        "install libosmesa6 (with sudo when not root)), or MUJOCO_GL=disable where nothing is rendered\n"
    )
    assert list(tmp_path.iterdir()) == []
