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
"""

from __future__ import annotations

import numpy as np

from krl.control.commands import CommandParams
from krl.control.types import JointCommand
from krl.robots.a1.constants import STANDING_JOINT_ANGLES
from krl.sim.pushes import scripted_push
from krl.task.waypoints import WaypointTask
from krl.timing import CONTROL_DT

KEY_SPACE, KEY_BACKSPACE = 32, 259
KEY_RIGHT, KEY_LEFT, KEY_DOWN, KEY_UP = 262, 263, 264, 265
KEY_C, KEY_P, KEY_R = 67, 80, 82

PUSH_FORCE: float = 250.0
"""Force of a push from the keyboard [N]."""
COMMAND_STEP: tuple[float, float] = (0.1, 0.1)
"""Change of the manual forward velocity [m/s] and yaw rate [rad/s] per key press."""


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

    def __init__(self, sim, controller, waypoints=(), start=None, d_min: float = 0.5, seed: int = 0) -> None:
        self.sim = sim
        self.controller = controller
        self.waypoints = np.asarray(waypoints, dtype=float).reshape(-1, 2)
        self.start = start
        self.params = CommandParams(d_min=d_min)
        self.rng = np.random.default_rng(seed)
        self.paused = False
        self.manual: np.ndarray | None = None if len(self.waypoints) else np.zeros(3)
        """The keyboard's command (v_x, v_y, ω_z), or None while the waypoints steer."""
        self.messages: list[str] = []
        """What happened, newest last (falls, reaching the last waypoint, pushes, resets)."""
        self.reset()

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


def run_viewer(session: LiveSession) -> None:
    """Open MuJoCo's viewer on the session and step it in real time until the window closes."""
    import time

    import mujoco.viewer

    with mujoco.viewer.launch_passive(
        session.sim.model, session.sim.data, key_callback=session.key
    ) as viewer:
        while viewer.is_running():
            started = time.perf_counter()
            session.step()
            viewer.sync()
            time.sleep(max(0.0, CONTROL_DT - (time.perf_counter() - started)))
