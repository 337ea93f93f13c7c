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
| ``vertical_velocity`` | trunk vertical velocity, world [m/s] | 0 |
| ``roll_pitch_rate`` | trunk roll and pitch rates, base frame [rad/s] | (0, 0) |
| ``stance_slip`` | planar distance the stance feet moved since the last step, summed over the feet [m] | 0 |
| ``stance_drift`` | planar distance of the stance feet from where they touched down, summed [m] | 0 |

The two stance quantities need the feet's history: a caller whose reward uses them keeps a
:class:`StanceMemory` and passes its :meth:`StanceMemory.update` to :func:`reward_terms`.

Two options shape a term (Table 4.7's experiments): ``shortfall`` counts only the part of a velocity
error that falls short of the command (moving faster than commanded costs nothing; a zero command
constrains nothing: trial 4's "prevents losing reward for exceeding the velocity commands"), and
``penalty`` makes the term ``weight * (exp(-q e²) - 1)``: zero at no error, down to ``-weight`` (the
negative RBF of Fig. 4.16b).

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
    "vertical_velocity": 1,
    "roll_pitch_rate": 2,
    "stance_slip": 1,
    "stance_drift": 1,
}
"""Quantities a term can measure, with their sizes (the table in this module's docstring)."""

_COMMAND_PART: dict[str, slice] = {"planar_velocity": slice(0, 2), "yaw_rate": slice(2, 3)}
"""The part of the (v_x, v_y, ω_z) command a ``command`` target reads, for the quantities that have one."""

STANCE_QUANTITIES: tuple[str, ...] = ("stance_slip", "stance_drift")
"""Quantities measured from the stance feet's history (:class:`StanceMemory`)."""

TERM_OPTIONS: tuple[str, ...] = ("shortfall", "penalty")
"""A term's optional switches, written in a config only when on."""

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
    shortfall: bool = False
    """Count only the error's part that falls short of a ``command`` target (module docstring)."""
    penalty: bool = False
    """``weight * (exp(-q e²) - 1)`` instead of ``weight * exp(-q e²)`` (module docstring)."""

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
        if self.shortfall and self.target != COMMAND_TARGET:
            raise RewardConfigError(f"term {self.name!r}: shortfall needs the command as its target")

    def __call__(self, squared_error: float | np.ndarray) -> float | np.ndarray:
        """The term for one squared error (a float), or for an array of them (a batch of robots)."""
        if isinstance(squared_error, np.ndarray):
            value = np.exp(-self.steepness * squared_error)
        else:
            value = math.exp(-self.steepness * squared_error)
        return self.weight * (value - 1.0 if self.penalty else value)


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

    @property
    def needs_stance(self) -> bool:
        """Whether a term measures the stance feet's history (:class:`StanceMemory`)."""
        return any(term.quantity in STANCE_QUANTITIES for term in self.terms)

    def to_json(self) -> dict[str, Any]:
        """The config as JSON data (:meth:`from_json` reads it back); a term's options only when set."""
        return {
            "terms": [
                {
                    "name": t.name,
                    "quantity": t.quantity,
                    "target": t.target if isinstance(t.target, str) else list(t.target),
                    "steepness": t.steepness,
                    "weight": t.weight,
                    **{option: True for option in TERM_OPTIONS if getattr(t, option)},
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
    extra = sorted(set(data) - set(fields) - set(TERM_OPTIONS))
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
        **{option: _flag(data, option) for option in TERM_OPTIONS if option in data},
    )


def _flag(data: Mapping[str, Any], option: str) -> bool:
    if not isinstance(data[option], bool):
        raise RewardConfigError(f"reward term {data.get('name', '?')!r}: {option} must be true or false")
    return data[option]


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


def _squared_errors(reward: RewardConfig, command: np.ndarray, state, distance, stance) -> list:
    """Each RBF term's squared error ``||target - measured||²`` (only the shortfall where the term says so):
    floats, or arrays of shape (N,)."""
    realised = realised_velocity(state)
    measured = {
        "planar_velocity": realised[..., 0:2],
        "yaw_rate": realised[..., 2:3],
        "gravity": state.projected_gravity,
        "target_distance": np.asarray(distance, dtype=float)[..., None],
        "roll_pitch": state.rpy[..., 0:2],
        "vertical_velocity": state.lin_vel_world[..., 2:3],
        "roll_pitch_rate": state.ang_vel_base[..., 0:2],
    }
    if stance is not None:
        measured.update(
            {name: np.asarray(stance[name], dtype=float)[..., None] for name in STANCE_QUANTITIES}
        )
    elif reward.needs_stance:
        raise RewardConfigError("this reward measures the stance feet: pass a StanceMemory's update")
    errors = []
    for term in reward.terms:
        if term.target == COMMAND_TARGET:
            target = command[..., _COMMAND_PART[term.quantity]]
        else:
            target = np.asarray(term.target, dtype=float)
        difference = target - measured[term.quantity]
        if term.shortfall:  # only falling short of a nonzero command counts
            difference = np.maximum(np.sign(target) * difference, 0.0)
        error = np.sum(difference**2, axis=-1)
        errors.append(float(error) if error.ndim == 0 else error)
    return errors


def reward_terms(
    reward: RewardConfig,
    command: np.ndarray,
    state,
    target_distance: float | np.ndarray,
    reached: bool | np.ndarray,
    fell: bool | np.ndarray,
    stance: Mapping[str, Any] | None = None,
) -> dict[str, float] | dict[str, np.ndarray]:
    """The named reward terms of one control step, for one robot or a batch of N.

    Args:
        reward: the reward function.
        command: the velocity command of the step (v_x, v_y, ω_z) [m/s, m/s, rad/s]. Shape: (3,) or (N, 3).
        state: the robot's state after the step: a :class:`krl.sim.state.RobotState`, or a
            :class:`krl.sim.state.StateBatch` of N robots.
        target_distance: planar distance from the base to the current waypoint after the step [m].
            A float, or shape (N,).
        reached: the step brought the robot within D_min of its waypoint. A bool, or shape (N,).
        fell: the robot fell during the step. A bool, or shape (N,).
        stance: the step's :meth:`StanceMemory.update` (needed only by a reward of stance terms).

    Returns:
        ``{term: value}`` in the order of ``reward.term_names``; the step's reward is the sum of the values.
        Floats for one robot, arrays of shape (N,) for a batch.
    """
    command = np.asarray(command, dtype=float)
    errors = _squared_errors(reward, command, state, target_distance, stance)
    terms = {term.name: term(error) for term, error in zip(reward.terms, errors, strict=True)}
    single = np.ndim(fell) == 0
    for name, value, event in (
        ("fall", reward.fall_penalty, fell),
        ("target_reached", reward.target_bonus, reached),
    ):
        if value is not None:
            terms[name] = (value if event else 0.0) if single else np.where(event, value, 0.0)
    return terms


class StanceMemory:
    """Where each stance foot was on the last control step and where it touched down, for a batch of robots
    (or one): what the ``stance_slip`` and ``stance_drift`` quantities measure. A foot is in stance on a
    step when it touches the ground now and touched it on the step before."""

    def __init__(self) -> None:
        self.previous: np.ndarray | None = None
        """Feet positions, world (x, y) [m], of the last step. Shape (..., 4, 2)."""
        self.contact: np.ndarray | None = None
        """Feet contacts of the last step. Shape (..., 4)."""
        self.touchdown: np.ndarray | None = None
        """Where each foot last touched down, world (x, y) [m]. Shape (..., 4, 2)."""

    def update(self, state) -> dict[str, np.ndarray | float]:
        """Record the step's feet (``state.foot_pos_world``, ``state.foot_contact``); returns this step's
        ``stance_slip`` and ``stance_drift`` [m] (0 on a first step)."""
        feet, contact = np.asarray(state.foot_pos_world)[..., :2], np.asarray(state.foot_contact, dtype=bool)
        if self.previous is None:
            self.previous, self.contact, self.touchdown = feet.copy(), contact.copy(), feet.copy()
        stance = contact & self.contact
        landed = contact & ~self.contact
        self.touchdown = np.where(landed[..., None], feet, self.touchdown)
        slip = np.sum(np.linalg.norm(feet - self.previous, axis=-1) * stance, axis=-1)
        drift = np.sum(np.linalg.norm(feet - self.touchdown, axis=-1) * stance, axis=-1)
        self.previous, self.contact = feet.copy(), contact.copy()
        single = slip.ndim == 0
        return {
            "stance_slip": float(slip) if single else slip,
            "stance_drift": float(drift) if single else drift,
        }

    def reset(self, rows: np.ndarray | None = None) -> None:
        """Forget the history (of the robots ``rows`` of a batch): their next step is a first step."""
        if rows is None or self.previous is None:
            self.previous = self.contact = self.touchdown = None
            return
        self.contact[rows] = False  # no foot in stance on the next step: nothing slips, all touch down
