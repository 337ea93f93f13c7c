"""The convex-MPC expert: gait clock, Raibert swing, MPC stance, at 200 Hz (thesis Section 4.2.6.1).

Each control step: the gait generator says which legs stand; stance legs are torque-controlled with
``tau = −Jᵀ f`` from the MPC's ground-reaction forces ``f``; swing legs follow the Raibert swing path
through inverse kinematics and the Table 4.2 PD. ``docs/expert.md`` lists every choice.
"""

from __future__ import annotations

import logging
import time
from collections import deque
from dataclasses import dataclass, field, replace

import numpy as np

from krl.control.gait import GaitGenerator, gait_params, leg_phases, stance_mask
from krl.control.kinematics import foot_jacobians, inverse_kinematics
from krl.control.mpc import GRAVITY, ConvexMPC, MPCError, MPCParams
from krl.control.swing import NOMINAL_FOOT_XY, raibert_landing, swing_position
from krl.control.types import JointCommand
from krl.robots.a1.constants import FOOT_RADIUS, KD, KP, NUM_JOINTS, NUM_LEGS
from krl.sim.state import RobotState

_log = logging.getLogger(__name__)

MAX_CONSECUTIVE_MPC_FAILURES: int = 5
"""MPC failures in a row bridged with the previous plan before the expert gives up (25 ms)."""

STEP_HEIGHT_RANGE: tuple[float, float] = (0.05, 0.18)
"""Allowed step heights [m] (thesis 4.2.6.5)."""

RIDE_HEIGHT_RANGE: tuple[float, float] = (0.18, 0.28)
"""Allowed ride heights [m] (thesis 4.2.6.5)."""

NOMINAL_STEP_HEIGHT: float = 0.08
"""The expert's default step height [m] (kept wherever a height is not varied)."""

NOMINAL_RIDE_HEIGHT: float = 0.25
"""The expert's default ride height [m] (kept wherever a height is not varied)."""


@dataclass(frozen=True)
class ExpertParams:
    """Parameters of the MPC expert."""

    gait: str = "trot"
    """Gait name from Table 4.1 (its initial phases and swing ratio)."""
    stance_duration: float = 0.2
    """τ_stance [s]; 0.2 s gives the steady expert the kernel learns from (thesis Table 4.3)."""
    step_height: float = NOMINAL_STEP_HEIGHT
    """Swing apex above the default foot height [m], in STEP_HEIGHT_RANGE."""
    ride_height: float = NOMINAL_RIDE_HEIGHT
    """Desired base-origin height above the ground [m], in RIDE_HEIGHT_RANGE."""
    raibert_gain: float = 0.03
    """Raibert velocity-feedback gain k of the landing point [s]."""
    velocity_window: int = 5
    """Control steps in the moving average of the measured base velocity (25 ms)."""
    mpc: MPCParams = field(default_factory=MPCParams)
    """The stance controller's parameters."""

    def __post_init__(self) -> None:
        if not (np.isfinite(self.stance_duration) and self.stance_duration > 0):
            raise ValueError(f"stance_duration must be > 0 s, got {self.stance_duration}")
        low, high = STEP_HEIGHT_RANGE
        if not low <= self.step_height <= high:
            raise ValueError(f"step_height must be in [{low}, {high}] m, got {self.step_height}")
        low, high = RIDE_HEIGHT_RANGE
        if not low <= self.ride_height <= high:
            raise ValueError(f"ride_height must be in [{low}, {high}] m, got {self.ride_height}")
        if self.raibert_gain < 0:
            raise ValueError(f"raibert_gain must be >= 0 s, got {self.raibert_gain}")
        if self.velocity_window < 1:
            raise ValueError(f"velocity_window must be >= 1 step, got {self.velocity_window}")
        gait_params(self.gait, stance_duration=self.stance_duration)  # validates the gait name


def _rotation_z(yaw: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@dataclass
class ExpertStep:
    """What the expert decided in one control step (for recording)."""

    stance: np.ndarray
    """Legs in stance. Shape: (4,), bool."""
    foot_targets: np.ndarray
    """Swing targets (swing legs) or current positions (stance legs), base frame [m]. Shape: (4, 3)."""
    forces: np.ndarray
    """MPC ground-reaction forces on the robot, heading frame [N]. Shape: (4, 3)."""
    mpc_seconds: float
    """Wall time of the MPC update [s]."""


class MPCExpert:
    """The expert controller; implements :class:`krl.control.types.Controller`."""

    def __init__(self, params: ExpertParams | None = None) -> None:
        self.params = p = params or ExpertParams()
        self.gait = GaitGenerator(gait_params(p.gait, stance_duration=p.stance_duration))
        self.mpc = ConvexMPC(p.mpc)
        self._horizon_times = np.arange(p.mpc.horizon) * p.mpc.dt
        self._velocities: deque[np.ndarray] = deque(maxlen=p.velocity_window)
        self._lift_off = np.zeros((NUM_LEGS, 3))
        self._was_stance = np.ones(NUM_LEGS, dtype=bool)
        self._fallback_plan: np.ndarray | None = None
        self._consecutive_failures = 0
        self.mpc_failures = 0
        """MPC updates that failed and were bridged with the previous plan, since construction."""
        self.last: ExpertStep | None = None

    def set_heights(self, step_height: float | None = None, ride_height: float | None = None) -> None:
        """Change step and/or ride height between targets (validated like the constructor)."""
        self.params = replace(
            self.params,
            step_height=self.params.step_height if step_height is None else step_height,
            ride_height=self.params.ride_height if ride_height is None else ride_height,
        )

    def reset(self, state: RobotState) -> None:
        self.gait.reset()
        self._velocities.clear()
        self._lift_off = state.foot_pos_base.copy()
        self._was_stance = self.gait.stance_mask.copy()
        self._fallback_plan = None
        self._consecutive_failures = 0
        self.last = None

    def act(self, state: RobotState, command: np.ndarray) -> JointCommand:
        p = self.params
        self.gait.step()
        gait = self.gait.params
        phases = self.gait.phases
        stance = stance_mask(phases, gait.swing_ratio)
        fraction = self.gait.state_fraction
        self._velocities.append(state.lin_vel_world)
        vel_world = np.mean(self._velocities, axis=0)

        yaw = state.rpy[2]
        heading = _rotation_z(yaw)
        body_to_heading = heading.T @ state.base_rot
        vel_heading = heading.T @ vel_world
        omega_heading = heading.T @ state.ang_vel_world
        vx, vy, wz = (float(c) for c in command)

        # --- stance: convex MPC ---------------------------------------------------------------
        feet_heading = state.foot_pos_base @ body_to_heading.T  # relative to base origin
        com_heading = heading.T @ (state.com - state.base_pos)
        support = stance if stance.any() else np.ones(NUM_LEGS, dtype=bool)
        height = -feet_heading[support, 2].mean() + FOOT_RADIUS
        x0 = np.array(
            [state.rpy[0], state.rpy[1], 0.0, 0.0, 0.0, height, *omega_heading, *vel_heading, GRAVITY]
        )
        reference = self._reference(vx, vy, wz, height)
        future = leg_phases(self.gait.time + self._horizon_times, gait)
        contacts = stance_mask(future, gait.swing_ratio)
        start = time.perf_counter()
        forces = self._plan_forces(x0, reference, feet_heading - com_heading, body_to_heading, contacts)
        mpc_seconds = time.perf_counter() - start
        forces_base = forces @ body_to_heading  # heading -> base: R^T f, row-wise
        jacobians = foot_jacobians(state.joint_pos)  # (4, 3, 3)
        stance_torque = -np.einsum("lij,li->lj", jacobians, forces_base)  # (4, 3)

        # --- swing: Raibert -------------------------------------------------------------------
        started = self._was_stance & ~stance
        self._lift_off[started] = state.foot_pos_base[started]
        self._was_stance = stance.copy()
        hips = np.concatenate((NOMINAL_FOOT_XY, np.zeros((NUM_LEGS, 1))), axis=1)
        hip_velocity = state.lin_vel_base + np.cross(state.ang_vel_base, hips)
        cmd_velocity = np.array([vx, vy, 0.0]) @ body_to_heading  # heading -> base
        hip_velocity_cmd = cmd_velocity + np.cross(np.array([0.0, 0.0, wz]), hips)
        landing = raibert_landing(
            hip_velocity, hip_velocity_cmd, p.stance_duration, p.ride_height, p.raibert_gain
        )
        apex = -p.ride_height + FOOT_RADIUS + p.step_height
        targets = state.foot_pos_base.copy()
        swing = ~stance
        if swing.any():
            targets[swing] = swing_position(fraction[swing], self._lift_off[swing], landing[swing], apex)
        q_swing = inverse_kinematics(targets).q

        stance_joints = np.repeat(stance, 3)
        q_target = np.where(stance_joints, state.joint_pos, q_swing)
        kp = np.where(stance_joints, 0.0, KP)
        kd = np.where(stance_joints, 0.0, KD)
        tau_ff = np.where(stance_joints, stance_torque.reshape(NUM_JOINTS), 0.0)
        self.last = ExpertStep(stance=stance, foot_targets=targets, forces=forces, mpc_seconds=mpc_seconds)
        return JointCommand(q_target, kp, kd, tau_ff)

    def _plan_forces(self, x0, reference, foot_rel_com, body_to_heading, contacts) -> np.ndarray:
        """The MPC's first-step forces; on a QP failure, the previous plan's next step (counted, logged).

        Raises MPCError after ``MAX_CONSECUTIVE_MPC_FAILURES`` failures in a row.
        """
        try:
            solution = self.mpc.solve(x0, reference, foot_rel_com, body_to_heading, contacts)
        except MPCError as error:
            self.mpc_failures += 1
            self._consecutive_failures += 1
            if self._consecutive_failures > MAX_CONSECUTIVE_MPC_FAILURES or self._fallback_plan is None:
                raise MPCError(
                    f"{error} ({self._consecutive_failures} consecutive failures, no usable plan)"
                ) from None
            _log.warning(
                "MPC failed (%s); reusing the previous plan (%d failures so far)", error, self.mpc_failures
            )
            self._fallback_plan = np.concatenate((self._fallback_plan[1:], self._fallback_plan[-1:]))
            return self._fallback_plan[0] * contacts[0][:, None]
        self._consecutive_failures = 0
        self._fallback_plan = solution.plan
        return solution.forces

    def _reference(self, vx: float, vy: float, wz: float, height: float) -> np.ndarray:
        """Desired states at prediction steps 1..horizon in the current heading frame. Shape: (h, 13)."""
        h, dt = self.params.mpc.horizon, self.params.mpc.dt
        t = np.arange(1, h + 1) * dt
        yaw = wz * t
        c, s = np.cos(yaw), np.sin(yaw)
        reference = np.zeros((h, 13))
        reference[:, 2] = yaw
        reference[:, 3] = vx * t
        reference[:, 4] = vy * t
        reference[:, 5] = self.params.ride_height
        reference[:, 8] = wz
        reference[:, 9] = c * vx - s * vy
        reference[:, 10] = s * vx + c * vy
        reference[:, 12] = GRAVITY
        return reference


__all__ = ["RIDE_HEIGHT_RANGE", "STEP_HEIGHT_RANGE", "ExpertParams", "ExpertStep", "MPCExpert"]
