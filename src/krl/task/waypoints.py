"""One walk through a list of waypoints (thesis Section 4.2.2, Algorithm 2; D_min of Section 4.2.1).

:class:`WaypointTask` owns the waypoints, the command generator that steers towards the current one, the
threshold ``D_min`` that decides when it is reached, the time allowed per waypoint and for the whole walk,
and the distance to the current waypoint. Every control step of a walk goes::

    command = task.command(base_xy, yaw)   # None once the walk is over (all reached, or out of time)
    state = <one control step with command>
    step = task.after_step(base_xy)        # distance to the waypoint and whether it is now reached

A waypoint reached by a step is counted (and rewarded, :mod:`krl.task.reward`) by that step's
:meth:`WaypointTask.after_step`; the next :meth:`WaypointTask.command` then moves on to the next one. The
command generator is stepped once more at that switch (on the same pose), as the runner always did, so
the command sequence of a walk is unchanged by this object.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np

from krl.control.commands import CommandGenerator, CommandParams
from krl.util.timing import CONTROL_DT

TARGET_TIME_LIMIT: float = 40.0
"""Default time allowed to reach one waypoint before the walk gives up [s]."""

TARGET_DISTANCE: tuple[float, float] = (2.5, 3.5)
"""Distance of each random waypoint from the previous one ~ U(low, high) [m]: the thesis's data
collection's "minimum distance of 2.5 m"; the upper end is ours."""


def random_targets(
    rng: np.random.Generator,
    count: int,
    start_xy: tuple[float, float] = (0.0, 0.0),
    distance: tuple[float, float] = TARGET_DISTANCE,
    bounds: tuple[float, float, float, float] | None = None,
) -> np.ndarray:
    """Consecutive waypoints, each at a distance ~ U(distance) [m] in a direction ~ U(-π, π) from the last.

    The thesis's data collection walks to targets "at a minimum distance of 2.5 m in a random direction".
    ``bounds`` (x_min, y_min, x_max, y_max) [m]: a waypoint outside them is drawn again (up to 100 times,
    then clipped into them), so a long walk stays on a terrain of finite size. Shape: (count, 2).
    """
    if count < 0:
        raise ValueError(f"target count must be >= 0, got {count}")
    low, high = distance
    if not 0 < low <= high:
        raise ValueError(f"target distance range must satisfy 0 < low <= high, got {distance}")
    # one (distance, direction) pair per target, in order, so a longer list extends a shorter one
    offsets = np.zeros((count, 2))
    point = np.asarray(start_xy, dtype=float)
    for index in range(count):
        for _ in range(100):
            step = rng.uniform(low, high)
            angle = rng.uniform(-np.pi, np.pi)
            offsets[index] = step * np.cos(angle), step * np.sin(angle)
            if bounds is None or _inside(point + offsets[index], bounds):
                break
        else:
            offsets[index] = np.clip(point + offsets[index], bounds[:2], bounds[2:]) - point
        point = point + offsets[index]
    return np.asarray(start_xy, dtype=float) + np.cumsum(offsets, axis=0)


def _inside(point: np.ndarray, bounds: tuple[float, float, float, float]) -> bool:
    return bounds[0] <= point[0] <= bounds[2] and bounds[1] <= point[1] <= bounds[3]


class TaskStatus(enum.Enum):
    """Where a walk stands."""

    WALKING = "walking"
    FINISHED = "finished"
    """Every waypoint reached."""
    TIMED_OUT = "timed_out"
    """A waypoint was not reached within its time, or the whole walk ran out of time."""


@dataclass(frozen=True)
class WaypointStep:
    """What one control step did for the task (returned by :meth:`WaypointTask.after_step`)."""

    target_index: int
    """The waypoint walked to during the step."""
    distance: float
    """Planar distance from the base to that waypoint after the step [m]."""
    reached: bool
    """The step ended within D_min of the waypoint."""


class WaypointTask:
    """Walk to each waypoint in turn.

    Args:
        targets: the waypoints, world (x, y) [m]. Shape: (N, 2).
        command_params: the command generator's limits; its ``d_min`` is the threshold D_min [m].
        target_time_limit: time allowed for each waypoint [s]; None: no per-waypoint limit.
        time_limit: time allowed for the whole walk [s] (a course's limit); None: no overall limit.
        generator: a command generator to steer with (its parameters replace ``command_params``), so
            that a walk split into several tasks keeps one command ramp; default: a new one.
    """

    def __init__(
        self,
        targets: np.ndarray,
        command_params: CommandParams | None = None,
        target_time_limit: float | None = TARGET_TIME_LIMIT,
        time_limit: float | None = None,
        generator: CommandGenerator | None = None,
    ) -> None:
        targets = np.asarray(targets, dtype=float)
        if targets.size % 2 or not np.isfinite(targets).all():
            raise ValueError(f"waypoints must be finite (x, y) pairs, got an array of shape {targets.shape}")
        targets = targets.reshape(-1, 2)
        for name, limit in (("target_time_limit", target_time_limit), ("time_limit", time_limit)):
            if limit is not None and not (math.isfinite(limit) and limit > 0):
                raise ValueError(f"{name} must be a positive number of seconds, got {limit}")
        self.targets = targets
        self.generator = generator or CommandGenerator(command_params or CommandParams())
        """Steers towards the current waypoint; its command carries over between waypoints, as
        Algorithm 2's ramp intends."""
        self.target_steps = None if target_time_limit is None else round(target_time_limit / CONTROL_DT)
        """Control steps allowed per waypoint (None: unlimited)."""
        self.total_steps = None if time_limit is None else round(time_limit / CONTROL_DT)
        """Control steps allowed for the whole walk (None: unlimited)."""
        self.index = 0
        self.status = TaskStatus.WALKING
        self.steps = 0
        """Control steps taken since :meth:`reset`."""
        self.steps_on_target = 0
        self.distance = math.nan
        """Planar distance to the current waypoint at the last observed pose [m]."""
        self._within = False

    @property
    def d_min(self) -> float:
        """The waypoint threshold D_min [m]."""
        return self.generator.params.d_min

    @property
    def target(self) -> np.ndarray | None:
        """The current waypoint [m] (shape (2,)), or None when the walk is over."""
        return self.targets[self.index] if self.index < len(self.targets) else None

    @property
    def reached_count(self) -> int:
        """Waypoints reached and left behind."""
        return self.index

    def reset(self, base_xy: np.ndarray, keep_command: bool = False) -> None:
        """Start the walk from the base position ``base_xy`` [m] (shape (2,)).

        ``keep_command``: keep the command generator's command and clock (a walk continued from a previous
        one, :meth:`krl.task.runner.Runner.walk_to` with ``reset=False``); otherwise they restart from zero.
        """
        if not keep_command:
            self.generator.reset()
        self.index = 0
        self.steps = 0
        self.steps_on_target = 0
        self.status = TaskStatus.WALKING if len(self.targets) else TaskStatus.FINISHED
        if len(self.targets):
            self.generator.set_target(self.targets[0])
            self._observe(base_xy)

    def _observe(self, base_xy: np.ndarray) -> None:
        target = self.targets[self.index]
        self.distance = math.hypot(target[0] - base_xy[0], target[1] - base_xy[1])
        self._within = self.distance < self.d_min

    def command(self, base_xy: np.ndarray, yaw: float) -> np.ndarray | None:
        """The velocity command (v_x, v_y, ω_z) for the next control step [m/s, m/s, rad/s] (shape (3,)),
        or None when the walk is over (see :attr:`status`).

        A waypoint reached at the last observed pose is left for the next one here; the time limits are
        checked after that, so a waypoint reached on the last allowed step counts.
        """
        while self.status is TaskStatus.WALKING:
            command = self.generator.step(base_xy, yaw)
            if self._within:
                self.index += 1
                self.steps_on_target = 0
                if self.index == len(self.targets):
                    self.status = TaskStatus.FINISHED
                    break
                self.generator.set_target(self.targets[self.index])
                self._observe(base_xy)
                continue
            if (self.target_steps is not None and self.steps_on_target >= self.target_steps) or (
                self.total_steps is not None and self.steps >= self.total_steps
            ):
                self.status = TaskStatus.TIMED_OUT
                break
            return command
        return None

    def after_step(self, base_xy: np.ndarray) -> WaypointStep:
        """Count one control step and observe the base position after it ([m], shape (2,))."""
        self.steps += 1
        self.steps_on_target += 1
        self._observe(base_xy)
        return WaypointStep(self.index, self.distance, self._within)


def commanded_path(
    task: WaypointTask,
    start_pose: tuple[float, float, float],
    tracking_lag: float = 0.0,
    max_time: float = 600.0,
) -> np.ndarray:
    """The path of a robot that follows ``task``'s velocity commands ideally, from ``start_pose``.

    The robot is a planar body moving at the commanded base-frame velocity (v_x, v_y, ω_z), reached
    through a first-order lag of time constant ``tracking_lag`` [s] (0: exactly), integrated at the
    control rate. It shows where a course's commands lead whatever the controller: a course whose
    commanded path leaves a prop tests the command generator's ramp, not the controller (the shipped
    courses keep it on their props; ``docs/evaluation.md``). ``task`` is reset and walked to its end (all
    waypoints, its time limits, or ``max_time`` [s]).

    Args:
        task: the walk; reset here.
        start_pose: (x [m], y [m], yaw [rad]).
        tracking_lag: time constant of the velocity tracking [s], >= 0.
        max_time: longest walk simulated [s].

    Returns:
        (x, y, yaw) after every control step [m, m, rad]. Shape: (steps + 1, 3), the start first.
    """
    if not tracking_lag >= 0.0:
        raise ValueError(f"tracking_lag must be >= 0 s, got {tracking_lag}")
    pose = np.array(start_pose, dtype=float)
    velocity = np.zeros(3)
    blend = 1.0 if tracking_lag == 0.0 else min(1.0, CONTROL_DT / tracking_lag)
    task.reset(pose[:2])
    poses = [pose.copy()]
    for _ in range(round(max_time / CONTROL_DT)):
        command = task.command(pose[:2], float(pose[2]))
        if command is None:
            break
        velocity += blend * (command - velocity)
        cos, sin = math.cos(pose[2]), math.sin(pose[2])
        pose += CONTROL_DT * np.array(
            [cos * velocity[0] - sin * velocity[1], sin * velocity[0] + cos * velocity[1], velocity[2]]
        )
        task.after_step(pose[:2])
        poses.append(pose.copy())
    return np.array(poses)
