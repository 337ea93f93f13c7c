"""The task reward as data: a :class:`RewardConfig` of named terms, and the thesis's rewards by name.

A reward (Eq. 4.7-4.8) is a sum of radial-basis terms, each comparing one measured quantity with its target,
plus two nominal terms paid on events::

    R_t = sum_i  weight_i * exp(-q_i * ||target_i - measured_i||^2)  +  fall penalty  +  target bonus

A :class:`RewardConfig` holds exactly that: its :class:`RBFTerm` s (name, quantity, target, q, weight) and
the nominal terms. It is frozen, saved whole in an agent's ``config.json`` and in every policy file, and
selectable by name (:data:`REWARDS`) or given in full in a config file, so the agent studies (Table 4.7's
trials, the weight and RBF searches) are reward configurations, not code. One function,
:func:`reward_terms`, scores one control step for the evaluation (``krl evaluate``) and the residual
agent's environment alike, so the reward trained on and the reward reported cannot drift apart. The total
of a step is ``sum(terms.values())``.

Quantities (:data:`QUANTITIES`) a term can measure:

| quantity | measured | target |
| --- | --- | --- |
| ``planar_velocity`` | realised (v_x, v_y), heading frame [m/s] | ``command``: commanded (v_x, v_y) |
| ``yaw_rate`` | realised yaw rate [rad/s] | ``command``: commanded yaw rate |
| ``gravity`` | gravity direction in the base frame | (0, 0, -1) |
| ``target_distance`` | planar distance to the current waypoint [m] | 0 |
| ``roll_pitch`` | (roll, pitch) [rad] | (0, 0) |

Named rewards (:data:`REWARDS`): ``initial`` (Table 4.6), ``base`` (Table 4.8: agent-base) and ``rp``
(Table 4.8 plus the roll/pitch term: agent-rp and the evaluation tables). The reading of each ambiguity is
in ``docs/reward.md``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from krl.control.frames import realised_velocity

COMMAND_TARGET: str = "command"
"""A term's target that is the step's velocity command (its planar or yaw part)."""

QUANTITIES: dict[str, int] = {
    "planar_velocity": 2,
    "yaw_rate": 1,
    "gravity": 3,
    "target_distance": 1,
    "roll_pitch": 2,
}
"""Quantities a term can measure, with their sizes (the table in this module's docstring)."""

_COMMAND_PART: dict[str, slice] = {"planar_velocity": slice(0, 2), "yaw_rate": slice(2, 3)}
"""The part of the (v_x, v_y, ω_z) command a ``command`` target reads, for the quantities that have one."""

NOMINAL_TERMS: tuple[str, ...] = ("fall", "target_reached")
"""The nominal terms' names, after the RBF terms in :func:`reward_terms`' output."""


class RewardConfigError(ValueError):
    """A malformed reward configuration (unknown quantity, bad target, non-finite number); one line."""


def _finite(name: str, value: Any) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise RewardConfigError(f"{name} must be a finite number, got {value!r}")


@dataclass(frozen=True)
class RBFTerm:
    """One radial-basis reward term ``weight * exp(-steepness * ||target - measured||^2)``."""

    name: str
    """The term's name in ``reward_terms``' output and the training logs (``reward_terms/<name>``)."""
    quantity: str
    """What the term measures: a key of :data:`QUANTITIES`."""
    target: str | tuple[float, ...]
    """γ': ``"command"`` (for ``planar_velocity`` and ``yaw_rate``) or a tuple of the quantity's size."""
    steepness: float
    """q: how fast the reward falls with the squared error [1/unit²]."""
    weight: float
    """ω: the term's value at zero error."""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name or self.name in NOMINAL_TERMS:
            raise RewardConfigError(
                f"a term's name must be a text other than {NOMINAL_TERMS}, got {self.name!r}"
            )
        if self.quantity not in QUANTITIES:
            raise RewardConfigError(
                f"term {self.name!r}: unknown quantity {self.quantity!r}; known: {', '.join(QUANTITIES)}"
            )
        if self.target == COMMAND_TARGET:
            if self.quantity not in _COMMAND_PART:
                raise RewardConfigError(f"term {self.name!r}: {self.quantity} has no commanded value")
        elif not isinstance(self.target, tuple) or len(self.target) != QUANTITIES[self.quantity]:
            raise RewardConfigError(
                f"term {self.name!r}: target must be {COMMAND_TARGET!r} or "
                f"{QUANTITIES[self.quantity]} numbers, got {self.target!r}"
            )
        else:
            for value in self.target:
                _finite(f"term {self.name!r}: target", value)
        _finite(f"term {self.name!r}: steepness", self.steepness)
        _finite(f"term {self.name!r}: weight", self.weight)
        if self.steepness < 0:
            raise RewardConfigError(f"term {self.name!r}: steepness must be >= 0, got {self.steepness}")

    def __call__(self, squared_error: float | np.ndarray) -> float | np.ndarray:
        """The term for one squared error (a float), or for an array of them (a batch of robots)."""
        if isinstance(squared_error, np.ndarray):
            return self.weight * np.exp(-self.steepness * squared_error)
        return self.weight * math.exp(-self.steepness * squared_error)


@dataclass(frozen=True)
class RewardConfig:
    """A reward function: RBF terms (Eq. 4.7) and the nominal terms of Eq. 4.8."""

    terms: tuple[RBFTerm, ...]
    """The RBF terms, in the order they are reported and summed."""
    fall_penalty: float | None = -19.8
    """Reward on the step the robot falls (term ``fall``); None: no such term (Table 4.6)."""
    target_bonus: float | None = 8.75
    """Reward on the step a waypoint is reached (term ``target_reached``); None: no such term."""

    def __post_init__(self) -> None:
        if not isinstance(self.terms, tuple) or not all(isinstance(t, RBFTerm) for t in self.terms):
            raise RewardConfigError(f"terms must be a list of RBF terms, got {self.terms!r}")
        names = [term.name for term in self.terms]
        if len(set(names)) != len(names):
            raise RewardConfigError(f"reward term names must be distinct, got {names}")
        for name in ("fall_penalty", "target_bonus"):
            if getattr(self, name) is not None:
                _finite(name, getattr(self, name))

    @property
    def term_names(self) -> tuple[str, ...]:
        """The names :func:`reward_terms` returns, in order."""
        nominal = (("fall", self.fall_penalty), ("target_reached", self.target_bonus))
        return (*(term.name for term in self.terms), *(name for name, value in nominal if value is not None))

    def to_json(self) -> dict[str, Any]:
        """The config as JSON data (:meth:`from_json` reads it back)."""
        return {
            "terms": [
                {
                    "name": t.name,
                    "quantity": t.quantity,
                    "target": t.target if isinstance(t.target, str) else list(t.target),
                    "steepness": t.steepness,
                    "weight": t.weight,
                }
                for t in self.terms
            ],
            "fall_penalty": self.fall_penalty,
            "target_bonus": self.target_bonus,
        }

    @classmethod
    def from_json(cls, data: Any) -> RewardConfig:
        """A named reward (``"rp"``) or a full table as :meth:`to_json` writes it; one-line errors."""
        if isinstance(data, str):
            return named_reward(data)
        if not isinstance(data, Mapping):
            raise RewardConfigError(f"a reward is a name or a table, got {type(data).__name__}")
        unknown = sorted(set(data) - {"terms", "fall_penalty", "target_bonus"})
        if unknown:
            raise RewardConfigError(
                f"unknown reward setting {unknown[0]!r}; known: terms, fall_penalty, target_bonus"
            )
        terms = data.get("terms")
        if not isinstance(terms, list) or not all(isinstance(term, Mapping) for term in terms):
            raise RewardConfigError(
                "reward terms must be a list of tables (name, quantity, target, steepness, weight)"
            )
        return cls(
            terms=tuple(_term_from_json(term) for term in terms),
            fall_penalty=data.get("fall_penalty", cls.fall_penalty),
            target_bonus=data.get("target_bonus", cls.target_bonus),
        )


def _term_from_json(data: Mapping[str, Any]) -> RBFTerm:
    fields = ("name", "quantity", "target", "steepness", "weight")
    missing = [name for name in fields if name not in data]
    extra = sorted(set(data) - set(fields))
    if missing or extra:
        what = f"missing {missing[0]!r}" if missing else f"unknown setting {extra[0]!r}"
        raise RewardConfigError(
            f"reward term {data.get('name', '?')!r}: {what}; a term has {', '.join(fields)}"
        )
    target = data["target"]
    return RBFTerm(
        name=data["name"],
        quantity=data["quantity"],
        target=tuple(target) if isinstance(target, list) else target,
        steepness=data["steepness"],
        weight=data["weight"],
    )


def _table_4_8_terms(**weights: float) -> tuple[RBFTerm, ...]:
    """Table 4.6/4.8's four RBF terms (the q of Table 4.6) with the given weights."""
    return (
        RBFTerm("linear_velocity", "planar_velocity", COMMAND_TARGET, 18.42, weights["linear_velocity"]),
        RBFTerm("angular_velocity", "yaw_rate", COMMAND_TARGET, 7.47, weights["angular_velocity"]),
        RBFTerm("gravity", "gravity", (0.0, 0.0, -1.0), 2.35, weights["gravity"]),
        RBFTerm("target_distance", "target_distance", (0.0,), 0.74, weights["target_distance"]),
    )


INITIAL_REWARD = RewardConfig(
    terms=_table_4_8_terms(linear_velocity=0.01, angular_velocity=0.01, gravity=0.01, target_distance=0.01),
    fall_penalty=None,
    target_bonus=None,
)
"""Table 4.6: the initial reward of the agent studies (four RBF terms of weight 0.01, no nominal terms)."""

AGENT_BASE_REWARD = RewardConfig(
    terms=_table_4_8_terms(
        linear_velocity=0.0076, angular_velocity=0.0264, gravity=0.0298, target_distance=0.0169
    )
)
"""Table 4.8 as it stands (agent-base): the optimised weights, fall penalty -19.8, target bonus 8.75."""

EVALUATION_REWARD = RewardConfig(
    terms=(
        *AGENT_BASE_REWARD.terms,
        RBFTerm("roll_pitch", "roll_pitch", (0.0, 0.0), 7.47, 0.0298),
    )
)
"""Table 4.8 plus agent-rp's roll/pitch term, "using the gravity terms' weight and the angular velocity
terms' steepness" (4.2.9): the reward of agent-rp and of the evaluation tables (Section 5.1)."""

REWARDS: dict[str, RewardConfig] = {
    "rp": EVALUATION_REWARD,
    "base": AGENT_BASE_REWARD,
    "initial": INITIAL_REWARD,
}
"""The thesis's rewards by name."""


def named_reward(name: str) -> RewardConfig:
    """The reward :data:`REWARDS` calls ``name``; RewardConfigError listing the names otherwise."""
    if name not in REWARDS:
        raise RewardConfigError(f"unknown reward {name!r}; known: {', '.join(REWARDS)}")
    return REWARDS[name]


def reward_name(reward: RewardConfig) -> str | None:
    """The name of a reward in :data:`REWARDS` equal to ``reward``, None for any other."""
    return next((name for name, known in REWARDS.items() if known == reward), None)


_DOWN = np.array([0.0, 0.0, -1.0])


def _squared_errors(reward: RewardConfig, command: np.ndarray, state, distance) -> list:
    """Each RBF term's squared error ``||target - measured||²``: floats, or arrays of shape (N,)."""
    realised = realised_velocity(state)
    measured = {
        "planar_velocity": realised[..., 0:2],
        "yaw_rate": realised[..., 2:3],
        "gravity": state.projected_gravity,
        "target_distance": np.asarray(distance, dtype=float)[..., None],
        "roll_pitch": state.rpy[..., 0:2],
    }
    errors = []
    for term in reward.terms:
        if term.target == COMMAND_TARGET:
            target = command[..., _COMMAND_PART[term.quantity]]
        else:
            target = np.asarray(term.target, dtype=float)
        error = np.sum((target - measured[term.quantity]) ** 2, axis=-1)
        errors.append(float(error) if error.ndim == 0 else error)
    return errors


def reward_terms(
    reward: RewardConfig,
    command: np.ndarray,
    state,
    target_distance: float | np.ndarray,
    reached: bool | np.ndarray,
    fell: bool | np.ndarray,
) -> dict[str, float] | dict[str, np.ndarray]:
    """The named reward terms of one control step, for one robot or a batch of N.

    Args:
        reward: the reward function.
        command: the velocity command of the step (v_x, v_y, ω_z) [m/s, m/s, rad/s]. Shape: (3,) or (N, 3).
        state: the robot's state after the step: a :class:`krl.sim.robot.RobotState`, or a
            :class:`krl.sim.batch.StateBatch` of N robots.
        target_distance: planar distance from the base to the current waypoint after the step [m].
            A float, or shape (N,).
        reached: the step brought the robot within D_min of its waypoint. A bool, or shape (N,).
        fell: the robot fell during the step. A bool, or shape (N,).

    Returns:
        ``{term: value}`` in the order of ``reward.term_names``; the step's reward is the sum of the values.
        Floats for one robot, arrays of shape (N,) for a batch.
    """
    command = np.asarray(command, dtype=float)
    errors = _squared_errors(reward, command, state, target_distance)
    terms = {term.name: term(error) for term, error in zip(reward.terms, errors, strict=True)}
    single = np.ndim(fell) == 0
    for name, value, event in (
        ("fall", reward.fall_penalty, fell),
        ("target_reached", reward.target_bonus, reached),
    ):
        if value is not None:
            terms[name] = (value if event else 0.0) if single else np.where(event, value, 0.0)
    return terms
