"""A point robot and a do-nothing controller, to score runs whose every number is known by hand; a short
course for the tests that walk the real robot."""

import math
from pathlib import Path

import numpy as np

from krl.control.types import JointCommand
from krl.sim.robot import RobotState
from krl.util.timing import CONTROL_DT


def make_state(
    xy=(0.0, 0.0), yaw=0.0, roll=0.0, lin_vel=(0.0, 0.0, 0.0), ang_vel=(0.0, 0.0, 0.0), time=0.0, fallen=False
) -> RobotState:
    """A RobotState of a trunk at ``xy`` with the given roll and yaw [rad] (pitch 0)."""
    cr, sr, cy, sy = math.cos(roll), math.sin(roll), math.cos(yaw), math.sin(yaw)
    rot = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]]) @ np.array(
        [[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]]
    )
    base = np.array([xy[0], xy[1], 0.3])
    return RobotState(
        time=time,
        base_pos=base,
        base_quat=np.array([1.0, 0.0, 0.0, 0.0]),
        base_rot=rot,
        rpy=np.array([roll, 0.0, yaw]),
        projected_gravity=rot.T @ np.array([0.0, 0.0, -1.0]),
        lin_vel_world=np.asarray(lin_vel, float),
        lin_vel_base=rot.T @ np.asarray(lin_vel, float),
        ang_vel_world=np.asarray(ang_vel, float),
        ang_vel_base=rot.T @ np.asarray(ang_vel, float),
        joint_pos=np.zeros(12),
        joint_vel=np.zeros(12),
        joint_torque=np.zeros(12),
        foot_pos_world=np.zeros((4, 3)),
        foot_pos_base=np.zeros((4, 3)),
        foot_force=np.zeros(4),
        foot_contact=np.ones(4, bool),
        com=base.copy(),
        trunk_contact=fallen,
        fallen=fallen,
    )


class PointSim:
    """Moves ``speed_per_step`` metres along +x every control step, level, and falls on step ``fall_at``."""

    def __init__(self, speed_per_step=0.25, fall_at=None):
        self.speed_per_step = speed_per_step
        self.fall_at = fall_at
        self.steps = 0
        self.state = make_state()

    @property
    def time(self):
        return self.steps * CONTROL_DT

    def reset(self, xy=(0.0, 0.0), yaw=0.0):
        self.steps = 0
        self.state = make_state(xy=xy, yaw=yaw)
        return self.state

    def step(self, q_target, kp=None, kd=None, tau_ff=None):
        self.steps += 1
        x = self.state.base_pos[0] + self.speed_per_step
        self.state = make_state(
            xy=(x, self.state.base_pos[1]), time=self.time, fallen=self.steps == self.fall_at
        )
        return self.state

    def push(self, push):
        self.pushed = push


class StandStill:
    """A controller that does nothing."""

    def reset(self, state):
        pass

    def act(self, state, command):
        return JointCommand(np.zeros(12))


class TurningPointSim(PointSim):
    """A PointSim that turns ``turn_per_step`` [rad] every control step and walks along its heading, counting
    its control steps as A1Sim does (``step_count``), so the heading at a push is known by hand."""

    def __init__(self, speed_per_step=0.001, turn_per_step=0.05, fall_at=None):
        super().__init__(speed_per_step, fall_at)
        self.turn_per_step = turn_per_step
        self.yaw = 0.0

    @property
    def step_count(self):
        return self.steps

    def reset(self, xy=(0.0, 0.0), yaw=0.0):
        self.yaw = yaw
        return super().reset(xy, yaw)

    def step(self, q_target, kp=None, kd=None, tau_ff=None):
        self.steps += 1
        self.yaw += self.turn_per_step
        x, y = self.state.base_pos[:2] + self.speed_per_step * np.array(
            [math.cos(self.yaw), math.sin(self.yaw)]
        )
        self.state = make_state(xy=(x, y), yaw=self.yaw, time=self.time, fallen=self.steps == self.fall_at)
        return self.state


SHORT_FLAT = """format = 1
name = "short-flat"
description = "flat's four starts, one waypoint 1 m ahead"
time_limit = 6.0
d_min = 0.5
waypoints = [[1.0, 0.0]]
starts = [[0.0, 0.0, 0.0], [0.0, 0.3, -0.3], [0.0, -0.3, 0.3], [-0.5, 0.0, 0.0]]

[terrain]
name = "flat"
seed = 0
"""
"""The shipped flat course cut short: its four starts, one waypoint, 6 s."""


def short_flat(folder: Path) -> Path:
    """Write :data:`SHORT_FLAT` into ``folder``; its path."""
    path = folder / "short-flat.toml"
    path.write_text(SHORT_FLAT)
    return path


def stored_record(out, label: str, run: str) -> dict:
    """The record of run ``run`` (``tiny/start0``) of controller ``label`` in the results folder ``out``."""
    from krl.eval.records import read_runs

    return read_runs(out / label, label)[run].record


def as_json_layout(out) -> None:
    """Rewrite an evaluation folder's Parquet parts as the older layout, one JSON file per run (as krl
    evaluate wrote them before Parquet), to test that older folders are still read."""
    import json

    from krl.eval.records import part_files, read_runs

    for folder in sorted(path for path in out.iterdir() if path.is_dir()):
        for run, stored in read_runs(folder).items():
            path = folder / f"{run}.json"
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(json.dumps(stored.record, indent=1))
        for part in part_files(folder):
            part.unlink()
