"""Without a GL library, a rendering command's error is its one line, not GLFW's warnings before it."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest


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


UNLOADABLE: dict[str, dict[str, str]] = {
    "an unknown backend": {"MUJOCO_GL": "vulkan-please"},
    "osmesa without libOSMesa": {"MUJOCO_GL": "osmesa", "PYOPENGL_PLATFORM": "osmesa"},
}
"""``MUJOCO_GL`` backends MuJoCo cannot load on import (libOSMesa hidden by :data:`WITHOUT_OSMESA`)."""

WITHOUT_OSMESA = (
    "import ctypes, ctypes.util\n"
    "ctypes.util.find_library = lambda name: None\n"
    "class _WithoutOSMesa(ctypes.CDLL):\n"
    "    def __init__(self, name, *args, **kwargs):\n"
    "        if name is not None and 'osmesa' in str(name).lower():\n"
    "            raise OSError(f'{name}: cannot open shared object file: No such file or directory')\n"
    "        super().__init__(name, *args, **kwargs)\n"
    "ctypes.CDLL = _WithoutOSMesa\n"
    "ctypes.cdll = ctypes.LibraryLoader(_WithoutOSMesa)\n"
)
"""A prelude in which no GL library is found, whether or not the machine has libOSMesa (PyOpenGL looks it
up with ``find_library``, then opens it by name through ``ctypes.cdll``)."""


@pytest.mark.parametrize("backend", UNLOADABLE)
def test_only_rendering_needs_a_backend_mujoco_cannot_load(tmp_path, backend):
    """Issue 47: with ``MUJOCO_GL=osmesa`` and no libOSMesa, even ``krl --help`` and ``krl --version``
    failed (MuJoCo imports its backend with itself). Every command but the rendering ones works; those
    name the backend in one line."""
    environment = {**os.environ, **UNLOADABLE[backend]}
    environment.pop("DISPLAY", None)
    for argv, shows in ((["--version"], "krl "), (["--help"], "COMMAND"), (["terrains"], "heightfield")):
        result = _krl(argv, environment, tmp_path, WITHOUT_OSMESA)
        assert result.returncode == 0 and shows in result.stdout, (argv, result.stderr)
        assert result.stderr == ""
    result = _krl(["render", "--terrain", "flat", "--out", "x.png"], environment, tmp_path, WITHOUT_OSMESA)
    assert result.returncode == 2 and result.stderr.count("\n") == 1
    assert result.stderr.startswith(
        f"krl: error: MuJoCo could not load its rendering backend MUJOCO_GL={environment['MUJOCO_GL']} ("
    )
    assert not (tmp_path / "x.png").exists()
