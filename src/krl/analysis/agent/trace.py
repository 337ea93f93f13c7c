"""Step-by-step traces of an agent walking a course, exactly as ``krl evaluate`` walks it.

:func:`trace_course_run` wraps the agent's controller in a recorder and hands it to
:func:`krl.eval.episodes.score_walk`, the function behind every course record, so a trace shows the very run
whose record says it fell. Every control step keeps what the controller saw and what it did: the trunk's
pose, the feet (world frame), their contacts and normal forces, the command, the policy's action, the
filtered residual it added to the kernel's targets, and the ground height under each foot.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from krl.agent.controller import AgentController
from krl.agent.policy import load_policy
from krl.control.types import JointCommand
from krl.eval.courses import Course
from krl.eval.episodes import score_walk
from krl.sim.robot import A1Sim, RobotState

TRACE_FIELDS: dict[str, str] = {
    "time": "simulated time at the step [s]. Shape: (T,)",
    "base_pos": "trunk position, world [m]. Shape: (T, 3)",
    "rpy": "trunk roll, pitch, yaw [rad]. Shape: (T, 3)",
    "foot_pos": "foot-sphere centres, world, FR FL RR RL [m]. Shape: (T, 4, 3)",
    "foot_contact": "foot touched something in the last physics step. Shape: (T, 4)",
    "foot_force": "normal contact force on each foot [N]. Shape: (T, 4)",
    "ground": "terrain height under each foot's centre [m]. Shape: (T, 4)",
    "command": "velocity command (v_x, v_y, ω_z) [m/s, m/s, rad/s]. Shape: (T, 3)",
    "action": "the policy's action in [-1, 1], its parts in order (krl.agent.action). Shape: (T, D)",
    "residual": "the filtered residual added this step, base frame [m]. Shape: (T, 4, 3)",
    "kernel_targets": "the kernel's foot targets, base frame [m]. Shape: (T, 4, 3)",
    "gait_inputs": "the kernel's command, step and ride heights [m], clock rate for the next step "
    "(driven, else the task's and the nominal ones). Shape: (T, 6)",
}
"""Every array of a trace, with its units and shape (T control steps; the state is the one the controller
saw at the step)."""


class RecordingController:
    """An :class:`krl.agent.controller.AgentController` that keeps every step's inputs and outputs."""

    def __init__(self, agent: AgentController, height) -> None:
        self.agent = agent
        self.height = height
        self.rows: dict[str, list[np.ndarray]] = {name: [] for name in TRACE_FIELDS}

    def reset(self, state: RobotState) -> None:
        self.agent.reset(state)

    def act(self, state: RobotState, command: np.ndarray) -> JointCommand:
        joint_command = self.agent.act(state, command)
        feet = state.foot_pos_world
        values = {
            "time": np.float64(state.time),
            "base_pos": state.base_pos,
            "rpy": state.rpy,
            "foot_pos": feet,
            "foot_contact": state.foot_contact,
            "foot_force": state.foot_force,
            "ground": np.asarray(self.height(feet[:, 0], feet[:, 1]), dtype=float),
            "command": np.asarray(command, dtype=float),
            "action": self.agent.last_action,
            "residual": self.agent.residual.filter.value[0],
            "kernel_targets": self.agent.last_targets,
            "gait_inputs": self.agent.residual.gait_inputs[0],
        }
        for name, value in values.items():
            self.rows[name].append(np.array(value, copy=True))
        return joint_command

    def arrays(self) -> dict[str, np.ndarray]:
        """The trace, ``{field: array}`` (:data:`TRACE_FIELDS`)."""
        return {name: np.array(values) for name, values in self.rows.items()}


def trace_course_run(
    policy_path: str | Path, course: Course, start: int
) -> tuple[dict[str, np.ndarray], dict]:
    """Walk the policy through ``course`` from start pose ``start`` as ``krl evaluate`` does.

    Returns ``(trace, metrics)``: the arrays of :data:`TRACE_FIELDS` and the run's metrics (those of its
    ``krl evaluate`` record).
    """
    built = course.build()
    recorder = RecordingController(AgentController(load_policy(policy_path)), built.terrain.height)
    metrics: dict[str, Any] = score_walk(
        A1Sim(built),
        recorder,
        np.array(course.waypoints),
        course.starts[start],
        course.time_limit,
        course.d_min,
    )
    return recorder.arrays(), metrics
