"""Walking a controller to waypoints (or at a fixed command) in the simulator.

Shared by ``krl expert run``, data collection, the kernel and the evaluation courses: each control step
the waypoint task (:class:`krl.task.waypoints.WaypointTask`: the command generator of Algorithm 2 and the
D_min and time-limit rules) turns the current waypoint into a velocity command, the controller turns it
into a joint command, and the simulator steps.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from krl.control.commands import CommandGenerator, CommandParams
from krl.control.frames import realised_velocity
from krl.control.types import Controller, JointCommand
from krl.sim.robot import A1Sim, RobotState
from krl.task.waypoints import TARGET_TIME_LIMIT, TaskStatus, WaypointStep, WaypointTask
from krl.util.timing import CONTROL_DT

__all__ = ["HOLD_RAMP", "HOLD_SETTLE", "RunResult", "Runner", "StepRecord"]

HOLD_RAMP: float = 1.0
"""Default time over which a fixed command rises from zero [s]."""

HOLD_SETTLE: float = 1.0
"""Time after the ramp before velocities count as steady [s]."""


@dataclass
class StepRecord:
    """One control step, as seen by a recorder."""

    before: RobotState
    """State the controller saw."""
    command: np.ndarray
    """Velocity command (vx, vy, wz) [m/s, m/s, rad/s]. Shape: (3,)."""
    joint_command: JointCommand
    """What the controller sent."""
    after: RobotState
    """State after the step."""
    target_index: int
    """Index of the waypoint being walked to (-1 in fixed-command runs)."""


@dataclass
class RunResult:
    """Outcome of one run."""

    targets_reached: int = 0
    fell: bool = False
    timed_out: bool = False
    """A waypoint was not reached within its time limit."""
    sim_seconds: float = 0.0
    """Simulated time this call ran [s]."""
    wall_seconds: float = 0.0
    commanded: list[np.ndarray] = field(default_factory=list, repr=False)
    realised: list[np.ndarray] = field(default_factory=list, repr=False)

    def mean_velocity(self) -> list[float]:
        """Mean realised (vx, vy) in the base frame [m/s] and yaw rate [rad/s] over the run."""
        if not self.realised:
            return [0.0, 0.0, 0.0]
        return [float(v) for v in np.mean(self.realised, axis=0)]


class Runner:
    """Runs one controller in one simulator.

    Args:
        sim: the simulator (reset by :meth:`walk_to` / :meth:`hold_command` unless ``reset=False``).
        controller: anything implementing :class:`krl.control.types.Controller`.
        command_params: the command generator's limits and target threshold.
        on_step: called after every control step with a :class:`StepRecord`.
        on_target: called with the waypoint index each time a waypoint is reached.
    """

    def __init__(
        self,
        sim: A1Sim,
        controller: Controller,
        command_params: CommandParams | None = None,
        on_step: Callable[[StepRecord], None] | None = None,
        on_target: Callable[[int], None] | None = None,
    ) -> None:
        self.sim = sim
        self.controller = controller
        self.command_params = command_params or CommandParams()
        self.on_step = on_step
        self.on_target = on_target
        self.generator = CommandGenerator(self.command_params)
        """The command generator; its command carries over between waypoints (and between calls with
        ``reset=False``), as Algorithm 2's ramp intends."""

    def start(self, start_pose: tuple[float, float, float] | None = None) -> RobotState:
        """Reset the simulator (to ``start_pose`` (x, y, yaw) [m, m, rad], default the terrain's spawn
        point), the controller and the command generator; returns the initial state. Follow with a
        ``reset=False`` run to act between the reset and the first step (e.g. schedule a push)."""
        if start_pose is None:
            state = self.sim.reset()
        else:
            x, y, yaw = start_pose
            state = self.sim.reset(xy=(x, y), yaw=yaw)
        self.controller.reset(state)
        self.generator.reset()
        return state

    def _start(self, reset: bool, start_pose: tuple[float, float, float] | None = None) -> RobotState:
        return self.start(start_pose) if reset else self.sim.state

    def _step(
        self,
        state: RobotState,
        command: np.ndarray,
        target_index: int,
        result: RunResult,
        record_velocity: bool = True,
    ) -> StepRecord:
        joint_command = self.controller.act(state, command)
        after = self.sim.step(*joint_command)
        if record_velocity:
            result.commanded.append(command.copy())
            result.realised.append(realised_velocity(after))
        record = StepRecord(state, command, joint_command, after, target_index)
        if self.on_step is not None:
            self.on_step(record)
        return record

    def walk_to(
        self,
        targets: np.ndarray,
        target_time_limit: float | None = TARGET_TIME_LIMIT,
        reset: bool = True,
        start_pose: tuple[float, float, float] | None = None,
        time_limit: float | None = None,
        on_task_step: Callable[[StepRecord, WaypointStep], None] | None = None,
    ) -> RunResult:
        """Walk to each waypoint in turn (world (x, y) [m], shape (N, 2)); stop on a fall or time-out.

        Args:
            targets: the waypoints. Shape: (N, 2).
            target_time_limit: time allowed for each waypoint [s].
            reset: start afresh; with ``reset=False`` the run continues from the simulator's and
                controller's current state (the gait clock and the command ramp keep running), so a long
                walk can be split into calls, one per waypoint.
            start_pose: (x, y, yaw) [m, m, rad] to reset to; default the terrain's spawn point.
            time_limit: time allowed for the whole call [s] (a course's limit); None: no overall limit.
            on_task_step: called after every control step (after ``on_step``) with the step and what it
                did for the task (:class:`krl.task.waypoints.WaypointStep`), e.g. to score it.
        """
        state = self._start(reset, start_pose)
        started_at = self.sim.time
        task = WaypointTask(
            targets, target_time_limit=target_time_limit, time_limit=time_limit, generator=self.generator
        )
        task.reset(state.base_pos[:2], keep_command=True)
        result = RunResult()
        wall = time.perf_counter()
        reported = 0
        while True:
            command = task.command(state.base_pos[:2], state.rpy[2])
            for index in range(reported, task.reached_count):
                if self.on_target is not None:
                    self.on_target(index)
            reported = task.reached_count
            if command is None:
                break
            record = self._step(state, command, task.index, result)
            state = record.after
            step = task.after_step(state.base_pos[:2])
            if on_task_step is not None:
                on_task_step(record, step)
            if state.fallen:
                result.fell = True
                break
        result.targets_reached = task.reached_count
        result.timed_out = task.status is TaskStatus.TIMED_OUT
        result.sim_seconds = self.sim.time - started_at
        result.wall_seconds = time.perf_counter() - wall
        return result

    def hold_command(
        self, command: np.ndarray, duration: float, ramp: float = HOLD_RAMP, reset: bool = True
    ) -> RunResult:
        """Walk at a fixed velocity command (vx, vy, wz) for ``duration`` seconds or until a fall.

        The command rises linearly from zero over ``ramp`` seconds; the result's velocities (and so
        :meth:`RunResult.mean_velocity`) cover only the time from ``ramp + HOLD_SETTLE`` on, the steady
        part.
        """
        command = np.asarray(command, dtype=float)
        if command.shape != (3,) or not np.isfinite(command).all():
            raise ValueError(f"command must be three finite numbers (vx, vy, wz), got {command!r}")
        if not duration > ramp + HOLD_SETTLE:
            raise ValueError(
                f"duration must exceed ramp + {HOLD_SETTLE} s = {ramp + HOLD_SETTLE} s, got {duration}"
            )
        state = self._start(reset)
        started_at = self.sim.time
        result = RunResult()
        wall = time.perf_counter()
        ramp_steps = max(1, round(ramp / CONTROL_DT))
        steady_from = round((ramp + HOLD_SETTLE) / CONTROL_DT)
        for k in range(round(duration / CONTROL_DT)):
            current = command * min(1.0, (k + 1) / ramp_steps)
            state = self._step(state, current, -1, result, record_velocity=k >= steady_from).after
            if state.fallen:
                result.fell = True
                break
        result.sim_seconds = self.sim.time - started_at
        result.wall_seconds = time.perf_counter() - wall
        return result
