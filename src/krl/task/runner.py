"""Walking one controller to waypoints (or at a fixed command) in one simulator.

Shared by ``krl expert run``, data collection, the kernel and the evaluation courses. :class:`Runner`
walks a single robot through the one episode loop (:class:`krl.task.episode.EpisodeBatch`, the loop
training runs too): each control step the task (:class:`krl.task.waypoints.WaypointTask`: the command
generator of Algorithm 2 and the D_min and time-limit rules; or :class:`HoldTask`, a fixed command) gives
the velocity command, the controller turns it into a joint command, and the loop pushes, steps, scores
and ends the walk.
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from krl.control.commands import CommandGenerator, CommandParams
from krl.control.frames import realised_velocity
from krl.control.types import Controller, JointCommand, attach_scene
from krl.sim.robot import A1Sim, RobotState
from krl.task.episode import EpisodeBatch, EpisodeStep, PushEvents, RobotTask
from krl.task.reward import EVALUATION_REWARD, RewardConfig
from krl.task.waypoints import TARGET_TIME_LIMIT, TaskStatus, WaypointStep, WaypointTask
from krl.util.timing import CONTROL_DT

__all__ = ["HOLD_RAMP", "HOLD_SETTLE", "HoldTask", "RunResult", "Runner", "StepRecord"]

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


class HoldTask:
    """A fixed velocity command for ``steps`` control steps, rising linearly from zero over the first
    ``ramp_steps`` (a :class:`krl.task.episode.RobotTask` without waypoints).

    Args:
        velocity: the command (v_x, v_y, ω_z) [m/s, m/s, rad/s]. Shape: (3,).
        steps: control steps to hold it.
        ramp_steps: control steps of the ramp (>= 1).
    """

    reached_count = 0

    def __init__(self, velocity: np.ndarray, steps: int, ramp_steps: int) -> None:
        self.velocity = np.asarray(velocity, dtype=float)
        self.total_steps = steps
        self.ramp_steps = ramp_steps
        self.steps = 0
        """Control steps taken."""
        self.status = TaskStatus.WALKING

    def command(self, base_xy: np.ndarray, yaw: float) -> np.ndarray | None:
        """The command of the coming step, None after the last."""
        if self.steps >= self.total_steps:
            self.status = TaskStatus.FINISHED
            return None
        return self.velocity * min(1.0, (self.steps + 1) / self.ramp_steps)

    def after_step(self, base_xy: np.ndarray) -> WaypointStep:
        self.steps += 1
        return WaypointStep(-1, math.nan, False)


class Runner:
    """Runs one controller in one simulator.

    Args:
        sim: the simulator (reset by :meth:`walk_to` / :meth:`hold_command` unless ``reset=False``).
        controller: anything implementing :class:`krl.control.types.Controller`.
        command_params: the command generator's limits and target threshold.
        on_step: called after every control step with a :class:`StepRecord`.
        on_target: called with the waypoint index each time a waypoint is reached.
        reward: the reward terms each step reports to ``on_task_step`` (:meth:`walk_to`).
    """

    def __init__(
        self,
        sim: A1Sim,
        controller: Controller,
        command_params: CommandParams | None = None,
        on_step: Callable[[StepRecord], None] | None = None,
        on_target: Callable[[int], None] | None = None,
        reward: RewardConfig = EVALUATION_REWARD,
    ) -> None:
        self.sim = sim
        self.episodes = EpisodeBatch(sim.backend, reward)
        """The episode loop over the simulator's batch of one."""
        self.controller = controller
        attach_scene(controller, sim.backend)
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

    def _run(
        self,
        task: RobotTask,
        pushes: PushEvents | None = None,
        on_task_step: Callable[[StepRecord, EpisodeStep], None] | None = None,
        steady_from: int = 0,
    ) -> RunResult:
        """Walk ``task`` through the episode loop (one robot) until it ends; ``steady_from``: the first
        control step whose velocities the result keeps. Raises the simulator's
        :class:`krl.sim.robot.SimulationUnstableError` if the physics diverges."""
        episodes, sim = self.episodes, self.sim
        started_at = sim.time
        if episodes.start([0], [task], [pushes])[0]:
            episodes.stop(0)  # over before the first step
        result = RunResult()
        wall = time.perf_counter()
        reported = 0
        for k in itertools.count():
            for index in range(reported, task.reached_count):
                if self.on_target is not None:
                    self.on_target(index)
            reported = task.reached_count
            if not episodes.active[0]:
                break
            state, command = sim.state, episodes.commands[0].copy()
            joint_command = self.controller.act(state, command)
            step = episodes.step(
                *(None if part is None else np.asarray(part)[None] for part in joint_command)
            )
            if step.unstable[0]:
                raise sim.backend.divergence(0)
            after = sim.state
            if k >= steady_from:
                result.commanded.append(command.copy())
                result.realised.append(realised_velocity(after))
            record = StepRecord(state, command, joint_command, after, int(step.target[0]))
            if self.on_step is not None:
                self.on_step(record)
            if on_task_step is not None:
                on_task_step(record, step)
            result.fell = result.fell or bool(step.fell[0])
        result.targets_reached = task.reached_count
        result.timed_out = task.status is TaskStatus.TIMED_OUT and not result.fell
        result.sim_seconds = sim.time - started_at
        result.wall_seconds = time.perf_counter() - wall
        return result

    def walk_to(
        self,
        targets: np.ndarray,
        target_time_limit: float | None = TARGET_TIME_LIMIT,
        reset: bool = True,
        start_pose: tuple[float, float, float] | None = None,
        time_limit: float | None = None,
        on_task_step: Callable[[StepRecord, EpisodeStep], None] | None = None,
        pushes: PushEvents | None = None,
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
            on_task_step: called after every control step (after ``on_step``) with the step and what the
                episode loop made of it (:class:`krl.task.episode.EpisodeStep` of one robot: the task's
                distance and waypoint, the reward terms of ``reward``), e.g. to score it.
            pushes: when the robot is pushed (:class:`krl.task.episode.PushEvents`); None: never.
        """
        state = self._start(reset, start_pose)
        task = WaypointTask(
            targets, target_time_limit=target_time_limit, time_limit=time_limit, generator=self.generator
        )
        task.reset(state.base_pos[:2], keep_command=True)
        return self._run(task, pushes, on_task_step)

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
        self._start(reset)
        ramp_steps = max(1, round(ramp / CONTROL_DT))
        task = HoldTask(command, round(duration / CONTROL_DT), ramp_steps)
        return self._run(task, steady_from=round((ramp + HOLD_SETTLE) / CONTROL_DT))
