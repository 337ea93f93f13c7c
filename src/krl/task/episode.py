"""The one episode loop: N robots of a simulator backend (:class:`krl.sim.backend.SimBackend`), each
walking its own task.

Training (:class:`krl.agent.env.ResidualEnvBatch`, with automatic resets), evaluation and data collection
(:class:`krl.task.runner.Runner`, one robot, no reset) and every analysis that walks a robot run their
episodes through :class:`EpisodeBatch`, so what an agent is trained on and what it is scored on are one
piece of code. One control step of the batch (:meth:`EpisodeBatch.step`), given the joint command a
controller made from :attr:`EpisodeBatch.commands` and :attr:`EpisodeBatch.states`:

1. **pushes**: each robot's push events (:class:`PushEvents`) are asked whether a push starts now, and a
   due push is scheduled on its robot;
2. **physics**: the batch steps (:meth:`krl.sim.backend.SimBackend.step`; a diverged robot comes back fallen
   and ``unstable``);
3. **task**: each task counts the step and observes the base (:meth:`krl.task.waypoints.WaypointTask.
   after_step`: distance to the waypoint, reached or not);
4. **reward**: the named terms of :func:`krl.task.reward.reward_terms` for every robot;
5. **termination**: a fall (or divergence) ends a robot's episode; otherwise its task gives the next
   step's command, and a task that is over (every waypoint reached, or out of time) ends it.

A robot whose episode ended is held (not stepped: its state and clock stay) until
:meth:`EpisodeBatch.start` begins its next episode; its rows of a step's results are not an episode's.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from krl.sim.backend import SimBackend
from krl.sim.pushes import Push
from krl.sim.state import StateBatch
from krl.task.reward import RewardConfig, StanceMemory, reward_terms
from krl.task.waypoints import TaskStatus, WaypointStep
from krl.util.timing import CONTROL_DT

__all__ = ["ENDINGS", "EpisodeBatch", "EpisodeStep", "PushEvents", "RobotTask", "ending"]

ENDINGS: tuple[str, ...] = ("finished", "fell", "timed_out", "error")
"""Why an episode ended: its task's every waypoint (or its whole time at a held command) done; a fall;
out of time (a waypoint's or the whole walk's); an ``error`` (the simulation diverged, the controller
gave up)."""


def ending(error: str | None, fell: bool, timed_out: bool) -> str:
    """Why a walk ended (:data:`ENDINGS`) from its record's ``error``, ``fell`` and ``timed_out``: an error
    before a fall before running out of time; otherwise it finished."""
    return "error" if error else "fell" if fell else "timed_out" if timed_out else "finished"


class RobotTask(Protocol):
    """What a robot walks: the velocity command of each step and the step's progress
    (:class:`krl.task.waypoints.WaypointTask`, :class:`krl.task.runner.HoldTask`)."""

    status: TaskStatus

    @property
    def reached_count(self) -> int:
        """Waypoints reached and left behind."""

    def command(self, base_xy: np.ndarray, yaw: float) -> np.ndarray | None:
        """The next step's command (v_x, v_y, ω_z) [m/s, m/s, rad/s] (shape (3,)), None when over."""

    def after_step(self, base_xy: np.ndarray) -> WaypointStep:
        """Count one step and observe the base position after it [m] (shape (2,))."""


class PushEvents(Protocol):
    """When a robot is pushed (:class:`krl.sim.pushes.PushSchedule`, :class:`krl.sim.pushes.OnePush`)."""

    def due(self, time: float, heading: float) -> Push | None:
        """The push to schedule before the control step starting at ``time`` [s], with the base heading
        ``heading`` [rad] then, or None. Called once per control step."""


@dataclass(frozen=True)
class EpisodeStep:
    """What one control step of the batch did; arrays over the N robots (an ended robot's entries are
    not its episode's)."""

    before: StateBatch
    """The states the controller saw."""
    commands: np.ndarray
    """The velocity commands the step ran with [m/s, m/s, rad/s]. Shape: (N, 3)."""
    states: StateBatch
    """The states after the step."""
    target: np.ndarray
    """The index of the waypoint each robot walked to during the step (-1 without one). Shape: (N,), int."""
    distance: np.ndarray
    """Planar distance from the base to its waypoint after the step [m] (NaN without one). Shape: (N,)."""
    reached: np.ndarray
    """The step brought the robot within D_min of its waypoint. Shape: (N,), bool."""
    terms: dict[str, np.ndarray]
    """The step's reward terms, each of shape (N,); they sum to the step's reward."""
    fell: np.ndarray
    """The robot fell (or its physics diverged) during the step. Shape: (N,), bool."""
    unstable: np.ndarray
    """The robot's physics diverged during the step. Shape: (N,), bool."""
    ended: np.ndarray
    """The robot's episode ended with this step (it fell, or its task is over). Shape: (N,), bool."""
    pushes: tuple[Push | None, ...]
    """The push scheduled on each robot before this step, or None. Length N."""


class EpisodeBatch:
    """N robots' episodes over one simulator batch.

    Args:
        sims: the robots (reset a robot there before :meth:`start` begins its episode).
        reward: the reward function of every robot.
    """

    def __init__(self, sims: SimBackend, reward: RewardConfig) -> None:
        n = len(sims)
        self.sims = sims
        self.reward = reward
        self.tasks: list[RobotTask | None] = [None] * n
        self.pushes: list[PushEvents | None] = [None] * n
        self.active = np.zeros(n, dtype=bool)
        """Robots whose episode is under way. Shape: (N,), bool."""
        self.commands = np.zeros((n, 3))
        """The velocity command of each robot's coming step (zero where none) [m/s, m/s, rad/s]. Shape:
        (N, 3)."""
        self.stance = StanceMemory() if reward.needs_stance else None
        """The stance feet's history, for a reward that measures it."""

    def __len__(self) -> int:
        return len(self.sims)

    @property
    def states(self) -> StateBatch:
        """The robots' current states (:attr:`krl.sim.backend.SimBackend.states`)."""
        return self.sims.states

    def start(self, rows: Sequence[int] | np.ndarray, tasks: Sequence[RobotTask], pushes) -> np.ndarray:
        """Begin the episodes of robots ``rows`` from their current states with ``tasks`` (already reset
        to those states) and push events (a sequence like ``tasks``, entries None for no pushes); their
        first commands are prepared in :attr:`commands`. Returns which of them have a task over already
        (every waypoint within reach at the start; shape (len(rows),), bool): a walk ends such an
        episode (:meth:`stop`) before its first step."""
        rows = np.atleast_1d(np.asarray(rows, dtype=np.int64))
        for index, task, events in zip(rows, tasks, pushes, strict=True):
            self.tasks[index] = task
            self.pushes[index] = events
        self.active[rows] = True
        if self.stance is not None:
            self.stance.reset(rows)
        return self._next_commands(self.states, rows)

    def stop(self, index: int) -> None:
        """End robot ``index``'s episode now (e.g. its controller failed)."""
        self.active[index] = False

    def _next_commands(self, states: StateBatch, rows: np.ndarray) -> np.ndarray:
        """Each robot of ``rows``' next command from its task into :attr:`commands` (zero where the task is
        over); returns which tasks are over. Shape: (len(rows),), bool."""
        over = np.zeros(len(rows), dtype=bool)
        base_xy, yaws = states.base_pos[:, :2], states.rpy[:, 2].tolist()
        for k, index in enumerate(rows.tolist()):
            command = self.tasks[index].command(base_xy[index], yaws[index])
            over[k] = command is None
            self.commands[index] = 0.0 if command is None else command
        return over

    def step(
        self,
        q_target: np.ndarray,
        kp: np.ndarray | None = None,
        kd: np.ndarray | None = None,
        tau_ff: np.ndarray | None = None,
    ) -> EpisodeStep:
        """One control step of every robot whose episode is under way, with the joint command (shapes
        (N, 12), :meth:`krl.sim.backend.SimBackend.step`; the other robots' rows are not used); returns what
        it did."""
        sims, before, commands = self.sims, self.states, self.commands.copy()
        pushes = self._schedule_pushes(before)
        walking = np.flatnonzero(self.active)
        states = sims.step(q_target, kp, kd, tau_ff, rows=walking)
        steps = [_NO_STEP] * len(self)
        for index in walking.tolist():
            steps[index] = self.tasks[index].after_step(states.base_pos[index, :2])
        target = np.array([step.target_index for step in steps], dtype=np.int64)
        distance = np.array([step.distance for step in steps])
        reached = np.array([step.reached for step in steps], dtype=bool)
        fell = states.fallen.copy()
        stance = None if self.stance is None else self.stance.update(states)
        terms = reward_terms(self.reward, commands, states, distance, reached, fell, stance)
        ended = np.zeros(len(self), dtype=bool)
        # a robot that fell still asks its task: a waypoint reached on the step of the fall counts
        ended[walking] = self._next_commands(states, walking) | fell[walking]
        self.active &= ~ended
        unstable = sims.unstable.copy()
        return EpisodeStep(
            before, commands, states, target, distance, reached, terms, fell, unstable, ended, pushes
        )

    def _schedule_pushes(self, before: StateBatch) -> tuple[Push | None, ...]:
        """Ask every active robot's push events before the step; schedule the due pushes. Returns the push
        each robot got, or None."""
        pushed: list[Push | None] = [None] * len(self)
        times = self.sims.step_counts * CONTROL_DT
        for index in np.flatnonzero(self.active).tolist():
            events = self.pushes[index]
            if events is not None:
                push = events.due(float(times[index]), float(before.rpy[index, 2]))
                if push is not None:
                    self.sims.push(index, push)
                    pushed[index] = push
        return tuple(pushed)


_NO_STEP = WaypointStep(-1, float("nan"), False)
"""What a step did for a robot without a task."""
