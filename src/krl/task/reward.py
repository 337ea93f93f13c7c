"""The task reward of the thesis (Table 4.8, Eq. 4.8) plus agent-rp's roll/pitch term, as named terms.

One function, :func:`reward_terms`, scores one control step; the evaluation (``krl evaluate``) and the
residual agent's environment both use it, so the reward the agent is trained on and the reward the
tables report cannot drift apart. The total of a step is ``sum(terms.values())``.

RBF terms (Fig. 4.16a, a positive radial basis function of the error, at most ``weight``)::

    weight * exp(-q * ||target - measured||^2)

| term | target | measured | q | weight |
| --- | --- | --- | --- | --- |
| ``linear_velocity`` | commanded (v_x, v_y) | realised (v_x, v_y), heading frame [m/s] | 18.42 | 0.0076 |
| ``angular_velocity`` | commanded yaw rate | realised yaw rate [rad/s] | 7.47 | 0.0264 |
| ``gravity`` | (0, 0, -1) | gravity direction in the base frame | 2.35 | 0.0298 |
| ``target_distance`` | 0 | planar distance to the current waypoint [m] | 0.74 | 0.0169 |
| ``roll_pitch`` (agent-rp) | (0, 0) | (roll, pitch) [rad] | 7.47 | 0.0298 |

Nominal terms: ``fall`` = -19.8 on the step the robot falls; ``target_reached`` = +8.75 on the step that
brings the robot within ``D_min`` of its waypoint. The reading of each ambiguity is in ``docs/reward.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from krl.control.frames import realised_velocity

TERM_NAMES: tuple[str, ...] = (
    "linear_velocity",
    "angular_velocity",
    "gravity",
    "target_distance",
    "roll_pitch",
    "fall",
    "target_reached",
)
"""Every term :func:`reward_terms` can return, in order."""


@dataclass(frozen=True)
class RBFTerm:
    """One radial-basis reward term ``weight * exp(-steepness * error^2)``."""

    steepness: float
    """q: how fast the reward falls with the squared error [1/unit²]."""
    weight: float
    """ω: the term's value at zero error."""

    def __post_init__(self) -> None:
        if not (math.isfinite(self.steepness) and self.steepness >= 0):
            raise ValueError(f"RBF steepness must be a finite number >= 0, got {self.steepness}")
        if not math.isfinite(self.weight):
            raise ValueError(f"RBF weight must be finite, got {self.weight}")

    def __call__(self, squared_error: float | np.ndarray) -> float | np.ndarray:
        """The term for one squared error (a float), or for an array of them (a batch of robots)."""
        if isinstance(squared_error, np.ndarray):
            return self.weight * np.exp(-self.steepness * squared_error)
        return self.weight * math.exp(-self.steepness * squared_error)


@dataclass(frozen=True)
class RewardParams:
    """The reward function. Defaults: Table 4.8 with the roll/pitch term of agent-rp (the evaluation's)."""

    linear_velocity: RBFTerm = RBFTerm(steepness=18.42, weight=0.0076)
    angular_velocity: RBFTerm = RBFTerm(steepness=7.47, weight=0.0264)
    gravity: RBFTerm = RBFTerm(steepness=2.35, weight=0.0298)
    target_distance: RBFTerm = RBFTerm(steepness=0.74, weight=0.0169)
    roll_pitch: RBFTerm | None = RBFTerm(steepness=7.47, weight=0.0298)
    """agent-rp's term: "the gravity terms' weight and the angular velocity terms' steepness" (4.2.9);
    None gives agent-base's reward (Table 4.8 alone)."""
    fall_penalty: float = -19.8
    """Reward on the step the robot falls."""
    target_bonus: float = 8.75
    """Reward on the step a waypoint is reached."""


AGENT_BASE_REWARD = RewardParams(roll_pitch=None)
"""Table 4.8 as it stands (agent-base)."""

EVALUATION_REWARD = RewardParams()
"""Table 4.8 plus the roll/pitch term: the reward of the evaluation tables (Section 5.1) and agent-rp."""

_DOWN = np.array([0.0, 0.0, -1.0])


def reward_terms(
    params: RewardParams,
    command: np.ndarray,
    state,
    target_distance: float | np.ndarray,
    reached: bool | np.ndarray,
    fell: bool | np.ndarray,
) -> dict[str, float] | dict[str, np.ndarray]:
    """The named reward terms of one control step, for one robot or a batch of N.

    Args:
        params: the reward function.
        command: the velocity command of the step (v_x, v_y, ω_z) [m/s, m/s, rad/s]. Shape: (3,) or (N, 3).
        state: the robot's state after the step: a :class:`krl.sim.robot.RobotState`, or a
            :class:`krl.sim.batch.StateBatch` of N robots.
        target_distance: planar distance from the base to the current waypoint after the step [m].
            A float, or shape (N,).
        reached: the step brought the robot within D_min of its waypoint. A bool, or shape (N,).
        fell: the robot fell during the step. A bool, or shape (N,).

    Returns:
        ``{term: value}`` for :data:`TERM_NAMES` (``roll_pitch`` only when ``params.roll_pitch`` is set);
        the step's reward is the sum of the values. Floats for one robot, arrays of shape (N,) for a batch.
    """
    realised = realised_velocity(state)
    command = np.asarray(command, dtype=float)
    linear_error = (command[..., 0] - realised[..., 0]) ** 2 + (command[..., 1] - realised[..., 1]) ** 2
    yaw_error = (command[..., 2] - realised[..., 2]) ** 2
    gravity_error = np.sum((state.projected_gravity - _DOWN) ** 2, axis=-1)
    distance = np.asarray(target_distance, dtype=float)
    tilt = state.rpy[..., 0] ** 2 + state.rpy[..., 1] ** 2
    if linear_error.ndim == 0:
        linear_error, yaw_error, gravity_error = float(linear_error), float(yaw_error), float(gravity_error)
        distance, tilt = float(distance), float(tilt)
    terms = {
        "linear_velocity": params.linear_velocity(linear_error),
        "angular_velocity": params.angular_velocity(yaw_error),
        "gravity": params.gravity(gravity_error),
        "target_distance": params.target_distance(distance**2),
    }
    if params.roll_pitch is not None:
        terms["roll_pitch"] = params.roll_pitch(tilt)
    if np.ndim(fell) == 0:
        terms["fall"] = params.fall_penalty if fell else 0.0
        terms["target_reached"] = params.target_bonus if reached else 0.0
    else:
        terms["fall"] = np.where(fell, params.fall_penalty, 0.0)
        terms["target_reached"] = np.where(reached, params.target_bonus, 0.0)
    return terms
