"""``krl view``'s window: its camera follows the trunk, and Ctrl-C closes it cleanly (under Xvfb)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import textwrap

import pytest

from krl.apps.viewer import VIEW_CAMERA
from krl.sim.model import build_model
from krl.sim.render import aim_camera
from krl.sim.robot import A1Sim


def test_the_camera_tracks_the_trunk():
    import mujoco  # after krl, which chooses the rendering backend before mujoco's first import

    model = A1Sim(build_model("flat")).model
    camera = mujoco.MjvCamera()
    aim_camera(camera, model, VIEW_CAMERA)
    assert camera.type == mujoco.mjtCamera.mjCAMERA_TRACKING
    assert camera.trackbodyid == model.body("trunk").id
    assert (camera.distance, camera.azimuth, camera.elevation) == (
        VIEW_CAMERA.distance,
        VIEW_CAMERA.azimuth,
        VIEW_CAMERA.elevation,
    )


@pytest.mark.skipif(shutil.which("xvfb-run") is None, reason="needs xvfb-run (apt-get install xvfb)")
def test_ctrl_c_closes_the_window_and_exits_130(tmp_path):
    # Before the fix, two of three Ctrl-Cs ended in a segmentation fault (exit 139): the interpreter
    # exited while the viewer's daemon thread still tore down its OpenGL context.
    script = textwrap.dedent(
        """
        import os, signal, sys, threading
        from krl.cli import main
        threading.Timer(4.0, os.kill, (os.getpid(), signal.SIGINT)).start()
        sys.exit(main(["view", "--controller", "kernel", "--course", "flat"]))
        """
    )
    env = {**os.environ, "MUJOCO_GL": "glfw"}
    done = subprocess.run(
        ["xvfb-run", "-a", "-s", "-screen 0 640x480x24", sys.executable, "-c", script],
        env=env,
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 130, done.stderr
    assert done.stderr.endswith("krl: interrupted\n")


def test_a_display_that_cannot_be_opened_is_one_line(monkeypatch, capsys):
    from krl.cli import main

    monkeypatch.setenv("DISPLAY", ":77")  # no X server there (a stale DISPLAY over SSH)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert main(["view", "--controller", "kernel", "--course", "stairs"]) == 2
    error = capsys.readouterr().err
    assert error.startswith("krl: error: `krl view` cannot open a window: X11: Failed to open display :77;")
    assert error.count("\n") == 1
