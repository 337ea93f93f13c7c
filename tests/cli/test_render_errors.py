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
