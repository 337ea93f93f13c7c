"""``krl view``: a controller walking live in MuJoCo's viewer, steered from the keyboard.

:class:`LiveSession` is the loop without the window: one :meth:`LiveSession.step` is one 200 Hz control
step of the controller, driven by the course's waypoint task or by a command the keyboard sets, and
:meth:`LiveSession.key` applies a key press (GLFW key codes, as ``mujoco.viewer`` reports them):

| key | action |
| --- | --- |
| space | pause / resume |
| backspace or R | reset to the course's first start (or the terrain's spawn point) |
| P | push the trunk: 250 N for 0.3 s, a random horizontal direction, slightly upwards |
| up / down | manual command: forward velocity ± 0.1 m/s |
| left / right | manual command: yaw rate ± 0.1 rad/s |
| C | back to the course's waypoints (leave the manual command) |
| H | show / hide the height scan's points (an agent that observes the terrain) |

The camera follows the trunk (MuJoCo's mouse controls still turn and zoom it; Escape frees it); the viewer's
own panels start hidden (Tab and Shift+Tab show them). What happens (falls, pushes, resets) is printed.
"""

from __future__ import annotations

import numpy as np

from krl.control.commands import CommandParams
from krl.control.types import JointCommand, attach_scene
from krl.robots.a1.constants import STANDING_JOINT_ANGLES
from krl.sim.pushes import scripted_push
from krl.sim.render import CameraView, aim_camera
from krl.task.waypoints import WaypointTask
from krl.util.timing import CONTROL_DT

KEY_SPACE, KEY_BACKSPACE = 32, 259
KEY_RIGHT, KEY_LEFT, KEY_DOWN, KEY_UP = 262, 263, 264, 265
KEY_C, KEY_H, KEY_P, KEY_R = 67, 72, 80, 82
SCAN_POINT_RADIUS: float = 0.012
"""Radius of the spheres that mark the height scan's points [m]."""
SCAN_POINT_RGBA: tuple[float, float, float, float] = (1.0, 0.55, 0.1, 0.9)

PUSH_FORCE: float = 250.0
"""Force of a push from the keyboard [N]."""
COMMAND_STEP: tuple[float, float] = (0.1, 0.1)
"""Change of the manual forward velocity [m/s] and yaw rate [rad/s] per key press."""
VIEW_CAMERA = CameraView(distance=2.2, azimuth=135.0, elevation=-20.0)
"""The viewer's camera: it tracks the trunk from this distance [m] and these angles [deg]."""


class StandingController:
    """The controller of ``krl view`` without ``--controller``: it holds the standing pose."""

    def reset(self, state) -> None:
        pass

    def act(self, state, command) -> JointCommand:
        return JointCommand(STANDING_JOINT_ANGLES)


class LiveSession:
    """A controller in a simulator, stepped in real time by the viewer's loop.

    Args:
        sim: the simulator (:class:`krl.sim.robot.A1Sim`).
        controller: any :class:`krl.control.types.Controller`.
        waypoints: the course's waypoints, world (x, y) [m], shape (N, 2); empty: manual command only.
        start: (x, y, yaw) [m, m, rad] to reset to; None: the terrain's spawn point.
        d_min: the waypoint threshold [m].
        seed: seed of the keyboard pushes' directions and points.
    """

    def __init__(
        self, sim, controller, waypoints=(), start=None, d_min: float = CommandParams.d_min, seed: int = 0
    ) -> None:
        self.sim = sim
        self.controller = controller
        attach_scene(controller, sim.backend)
        self.waypoints = np.asarray(waypoints, dtype=float).reshape(-1, 2)
        self.start = start
        self.params = CommandParams(d_min=d_min)
        self.rng = np.random.default_rng(seed)
        self.paused = False
        self.manual: np.ndarray | None = None if len(self.waypoints) else np.zeros(3)
        """The keyboard's command (v_x, v_y, ω_z), or None while the waypoints steer."""
        self.messages: list[str] = []
        """What happened, newest last (falls, reaching the last waypoint, pushes, resets)."""
        self.show_scan = True
        """Whether the viewer marks the height scan's points (key H)."""
        self.reset()

    def scan_points(self) -> np.ndarray:
        """World positions [m] of the points the controller's height scan reads, on the terrain's surface
        as it stands now; none for a controller without one (or hidden). Shape: (P, 3)."""
        from krl.sim.scan import heading_points_to_world

        senses = getattr(self.controller, "senses", None)
        if not self.show_scan or senses is None or not senses.sensing.needed:
            return np.zeros((0, 3))
        points = senses.sensing.points
        heights = self.sim.backend.terrain_heights(points)[0]
        state = self.sim.state
        xy = heading_points_to_world(points, state.base_pos, float(state.rpy[2]))
        return np.column_stack([xy, heights])

    def reset(self) -> None:
        if self.start is None:
            state = self.sim.reset()
        else:
            x, y, yaw = self.start
            state = self.sim.reset(xy=(x, y), yaw=yaw)
        self.controller.reset(state)
        self.task = WaypointTask(self.waypoints, self.params, target_time_limit=None)
        self.task.reset(state.base_pos[:2])

    def key(self, code: int) -> None:
        """Apply one key press (module docstring)."""
        if code == KEY_SPACE:
            self.paused = not self.paused
        elif code in (KEY_BACKSPACE, KEY_R):
            self.reset()
            self.messages.append("reset")
        elif code == KEY_P:
            push = scripted_push(PUSH_FORCE, self.rng, (self.sim.time, self.sim.time))
            self.sim.push(push)
            self.messages.append(f"push of {PUSH_FORCE:g} N")
        elif code in (KEY_UP, KEY_DOWN, KEY_LEFT, KEY_RIGHT):
            if self.manual is None:
                self.manual = np.zeros(3)
            step_v, step_w = COMMAND_STEP
            change = {
                KEY_UP: (0, step_v),
                KEY_DOWN: (0, -step_v),
                KEY_LEFT: (2, step_w),
                KEY_RIGHT: (2, -step_w),
            }
            axis, delta = change[code]
            self.manual[axis] += delta
            self.manual = np.clip(self.manual, self.params.low, self.params.high)
        elif code == KEY_C and len(self.waypoints):
            self.manual = None
        elif code == KEY_H:
            self.show_scan = not self.show_scan

    def command(self) -> np.ndarray:
        """The velocity command of the next step (the keyboard's, or the waypoint task's; zero when done)."""
        state = self.sim.state
        if self.manual is not None:
            return self.manual.copy()
        command = self.task.command(state.base_pos[:2], float(state.rpy[2]))
        return np.zeros(3) if command is None else command

    def step(self) -> None:
        """One control step (nothing while paused or after a fall)."""
        if self.paused or self.sim.state.fallen:
            return
        state = self.sim.step(*self.controller.act(self.sim.state, self.command()))
        if self.manual is None:
            self.task.after_step(state.base_pos[:2])
        if state.fallen:
            self.messages.append(f"fell at t = {state.time:.1f} s (backspace resets)")


def _mark_points(scene, points: np.ndarray) -> None:
    """Draw ``points`` (shape (P, 3), world [m]) as small spheres in the viewer's user scene (replacing what
    it drew before), as many as the scene holds."""
    import mujoco

    count = min(len(points), scene.maxgeom)
    for index in range(count):
        mujoco.mjv_initGeom(
            scene.geoms[index],
            mujoco.mjtGeom.mjGEOM_SPHERE,
            np.array([SCAN_POINT_RADIUS, 0.0, 0.0]),
            points[index],
            np.eye(3).ravel(),
            np.array(SCAN_POINT_RGBA, dtype=np.float32),
        )
    scene.ngeom = count


HEADLESS_HINT = (
    "on a headless machine use `krl render --terrain NAME --out FILE.png`, or `krl demo` / `--video` for a "
    "walking robot"
)


def window_problem() -> str | None:
    """Why MuJoCo's viewer cannot open a window here (one line), or None when it can: no display is set, or
    GLFW cannot open the one that is (a stale ``DISPLAY`` over SSH, a stopped X server)."""
    import glfw

    from krl.sim.render import has_display

    if not has_display():
        return f"`krl view` needs a display (DISPLAY/WAYLAND_DISPLAY is unset); {HEADLESS_HINT}"
    reporting, glfw.ERROR_REPORTING = glfw.ERROR_REPORTING, "ignore"  # read by get_error instead
    try:
        if not glfw.init():
            _, description = glfw.get_error()
            reason = description.decode(errors="replace") if description else "glfwInit failed"
            return f"`krl view` cannot open a window: {reason}; {HEADLESS_HINT}"
        glfw.terminate()
    finally:
        glfw.ERROR_REPORTING = reporting
    return None


def run_viewer(session: LiveSession, duration: float | None = None) -> None:
    """Open MuJoCo's viewer on the session and step it in real time until the window closes, the
    simulation reaches ``duration`` seconds (None: no end), or Ctrl-C (then KeyboardInterrupt, once the
    window is gone); print the session's messages as they come.

    The viewer draws on a daemon thread, which is waited for after the window is asked to close: an
    interpreter that exits while that thread still tears down its OpenGL context dies by a segmentation
    fault. Ctrl-C only sets a flag, so it never interrupts a frame half-synchronised.
    """
    import signal
    import threading
    import time

    import mujoco.viewer

    interrupted = threading.Event()
    before = set(threading.enumerate())
    previous = signal.signal(signal.SIGINT, lambda signum, frame: interrupted.set())
    try:
        with mujoco.viewer.launch_passive(
            session.sim.model,
            session.sim.data,
            key_callback=session.key,
            show_left_ui=False,
            show_right_ui=False,
        ) as viewer:
            drawing = set(threading.enumerate()) - before
            with viewer.lock():
                aim_camera(viewer.cam, session.sim.model, VIEW_CAMERA)
            shown = 0
            while viewer.is_running() and not interrupted.is_set():
                if duration is not None and session.sim.time >= duration:
                    break
                started = time.perf_counter()
                session.step()
                with viewer.lock():
                    _mark_points(viewer.user_scn, session.scan_points())
                viewer.sync()
                for message in session.messages[shown:]:
                    print(f"krl view: {message}", flush=True)
                shown = len(session.messages)
                time.sleep(max(0.0, CONTROL_DT - (time.perf_counter() - started)))
        for thread in drawing:
            thread.join(timeout=10.0)
    finally:
        signal.signal(signal.SIGINT, previous)
    if interrupted.is_set():
        raise KeyboardInterrupt
