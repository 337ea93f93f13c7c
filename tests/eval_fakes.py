"""A point robot and a do-nothing controller, to score runs whose every number is known by hand; a short
course for the tests that walk the real robot."""

import dataclasses
import math
from pathlib import Path

import numpy as np

from krl.control.types import JointCommand
from krl.sim.batch import SimulationUnstableError
from krl.sim.state import RobotState, StateBatch
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


class PointBatch:
    """The interface of :class:`krl.sim.batch.SimBatch` for one point robot: every control step it turns
    ``turn_per_step`` [rad] and moves ``speed_per_step`` metres along its heading, level; it falls on step
    ``fall_at`` and its physics diverges on step ``diverge_at``."""

    def __init__(self, speed_per_step, turn_per_step=0.0, fall_at=None, diverge_at=None):
        self.speed_per_step, self.turn_per_step = speed_per_step, turn_per_step
        self.fall_at, self.diverge_at = fall_at, diverge_at
        self.unstable = np.zeros(1, dtype=bool)
        self.pushed = None
        self.reset(0)

    def __len__(self):
        return 1

    @property
    def step_counts(self):
        return np.array([self.steps])

    @property
    def states(self):
        return self._states

    def reset(self, index, xy=(0.0, 0.0), yaw=0.0):
        self.steps, self.yaw = 0, yaw
        self.unstable[:] = False
        self._set(make_state(xy=xy, yaw=yaw))
        return self.state

    def _set(self, state):
        self.state, self._states = state, StateBatch.from_states([state])

    def push(self, index, push):
        self.pushed = push

    def divergence(self, index):
        if self.unstable[0]:
            return SimulationUnstableError(f"simulation diverged at t={(self.steps - 1) * CONTROL_DT:.3f} s")
        return None

    def step(self, q_target, kp=None, kd=None, tau_ff=None, rows=None):
        if rows is not None and 0 not in rows:
            return self._states
        self.steps += 1
        if self.steps == self.diverge_at:
            self.unstable[0] = True
            self._set(dataclasses.replace(self.state, fallen=True))
            return self._states
        self.yaw += self.turn_per_step
        xy = self.state.base_pos[:2] + self.speed_per_step * np.array(
            [math.cos(self.yaw), math.sin(self.yaw)]
        )
        time = self.steps * CONTROL_DT
        self._set(make_state(xy=tuple(xy), yaw=self.yaw, time=time, fallen=self.steps == self.fall_at))
        return self._states


class PointSim:
    """A point robot as :class:`krl.sim.robot.A1Sim` is one robot: a :class:`PointBatch` of one as its
    ``backend`` (by default walking +x 0.25 m per control step)."""

    def __init__(self, speed_per_step=0.25, fall_at=None, turn_per_step=0.0, diverge_at=None):
        self.backend = PointBatch(speed_per_step, turn_per_step, fall_at, diverge_at)

    @property
    def state(self):
        return self.backend.state

    @property
    def step_count(self):
        return self.backend.steps

    @property
    def time(self):
        return self.backend.steps * CONTROL_DT

    @property
    def pushed(self):
        return self.backend.pushed

    def reset(self, xy=(0.0, 0.0), yaw=0.0):
        return self.backend.reset(0, xy, yaw)


class StandStill:
    """A controller that does nothing."""

    def reset(self, state):
        pass

    def act(self, state, command):
        return JointCommand(np.zeros(12))


def TurningPointSim(speed_per_step=0.001, turn_per_step=0.05, fall_at=None):
    """A :class:`PointSim` that turns ``turn_per_step`` [rad] every control step and walks slowly along its
    heading, so the heading at a push is known by hand."""
    return PointSim(speed_per_step, fall_at, turn_per_step)


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


def complete_record(record: dict, label: str) -> dict:
    """``record`` (a run of controller ``label``, reduced to what a test reads) with every other field a
    stored record holds (:mod:`krl.eval.record_schema`) at a neutral value, so that the readers take it."""
    from krl.eval.record_schema import FRICTION_DIR, PUSH_DIR

    metrics = {
        "targets": 5,
        "targets_reached": 0,
        "success": False,
        "fell": False,
        "timed_out": False,
        "error": None,
        "steps": 1,
        "reward_total": 0.0,
        "reward_per_step": 0.0,
        "reward_terms": {},
        "time_to_finish": None,
        "distance_walked": 0.0,
        "sim_seconds": 0.0,
        "wall_seconds": 0.0,
    }
    defaults = {"controller": {"kind": "agent", "label": label, "options": {}, "model_sha256": None}}
    group = record["run"].partition("/")[0]
    if group == PUSH_DIR:
        push = {
            "magnitude": 0.0,
            "force": [0.0, 0.0, 0.0],
            "point": [0.0, 0.0, 0.0],
            "impulse": 0.0,
            "delta_v": 0.0,
        }
        defaults.update(sweep={}, magnitude=0.0, attempt=0, metrics={**metrics, "push": push})
    else:
        defaults.update(course=group, course_fingerprint="0" * 64, start=0, metrics=metrics)
        if group == FRICTION_DIR:
            defaults["friction"] = 1.0

    def merged(given: dict, default: dict) -> dict:
        result = {**default, **given}
        for key, value in default.items():
            if isinstance(value, dict) and isinstance(given.get(key), dict):
                result[key] = merged(given[key], value)
        return result

    return merged(record, defaults)
