"""Configuration of the residual agent: the action path, the environment, the observation and PPO.

One frozen dataclass per component, composed into :class:`AgentConfig`, which is saved as
``config.json`` beside every training run and inside every policy file. Defaults are the thesis's final
agent (agent-rp, Sections 4.2.8-4.2.9, Fig. 4.17 trial 3) unless a field's docstring says they are ours;
``docs/agent.md`` gives the reasoning for each of ours.
"""

from __future__ import annotations

import dataclasses
import json
import math
import types
import typing
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from krl.control.commands import CommandParams
from krl.control.filters import DEFAULT_ALPHA
from krl.robots.a1.constants import FOOT_FRICTION, NUM_LEGS
from krl.sim.pushes import Push, PushDistribution
from krl.sim.terrains import HEIGHTFIELD_MAX_HEIGHT_RANGE, MAX_GROUND_FRICTION, PYRAMIDS_STEP_HEIGHT_RANGE
from krl.task.reward import EVALUATION_REWARD, RewardConfig, RewardConfigError
from krl.task.waypoints import TARGET_DISTANCE
from krl.util.thesis import THESIS_PUSH_MAGNITUDES


class AgentConfigError(ValueError):
    """A malformed agent configuration (unknown key, wrong type, value out of range); one line."""


def _positive(name: str, value: float) -> None:
    if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
        raise AgentConfigError(f"{name} must be a positive number, got {value!r}")


def _range(name: str, value: tuple[float, float], low: float = 0.0) -> None:
    if len(value) != 2 or not all(isinstance(v, (int, float)) and math.isfinite(v) for v in value):
        raise AgentConfigError(f"{name} must be a (low, high) pair of numbers, got {value!r}")
    if not low <= value[0] <= value[1]:
        raise AgentConfigError(f"{name} must satisfy {low} <= low <= high, got {value!r}")


RESIDUAL_ACTION_SIZE: int = 3 * NUM_LEGS
"""Numbers of the residual part of an action: an (x, y, z) for each foot, leg-major (FR, FL, RR, RL)."""

RHYTHM_RANGE: tuple[float, float] = (0.5, 2.0)
"""Default bounds of a driven gait clock's rate, in multiples of the kernel's own: kernel-base alone walks
at every rate in them without a fall, its speed rising with the rate up to 2 (``krl agent rhythm``,
docs/agent-gait.md)."""

PUSH_CURRICULUM_LIMIT: float = max(THESIS_PUSH_MAGNITUDES)
"""The largest push a curriculum may train with [N]: the largest of the thesis's sweep (Table 5.5)."""

PUSH_CURRICULUM_LIMIT_DELTA_V: float = Push(0.0, [PUSH_CURRICULUM_LIMIT, 0, 0], [0, 0, 0]).delta_v
"""The speed such a push gives the free robot [m/s]."""

SYMMETRY_MODES: tuple[str, ...] = ("none", "augment", "loss")
"""The values of :attr:`PPOConfig.symmetry` (:mod:`krl.agent.symmetric_ppo` describes each)."""

GAIT_ALPHA: float = 0.05
"""Default smoothing α of the driven gait inputs' low-pass filter: a time constant of ~0.1 s at 200 Hz,
twice the residuals' (ours, docs/agent-gait.md)."""


@dataclass(frozen=True)
class ResidualConfig:
    """The action path: kernel + low-pass-filtered residual -> IK -> PD; optionally, the policy also drives
    the kernel's inputs and the gait clock (:mod:`krl.agent.action` lists the action's parts). With every
    ``drive_*`` switch off (the default) it is the thesis's residual agent."""

    kernel: str = "base"
    """The kernel giving the reference foot targets: a shipped kernel's name or a kernel file."""
    residual_bound: tuple[float, float, float] = (0.08, 0.08, 0.08)
    """Largest residual per axis (x, y, z) of each foot, base frame [m]: an action of ±1 maps to it.
    Not in the thesis; chosen by measurement (docs/agent.md)."""
    alpha: float = DEFAULT_ALPHA
    """Smoothing factor α of the residuals' low-pass filter (Eq. 4.4)."""
    residuals: bool = True
    """The policy adds foot residuals (12 action numbers). Off only where the policy drives the kernel
    alone (the alternative architecture of Section 4.2.8.4)."""
    drive_command: bool = False
    """The policy sets the velocity command the kernel receives (3 numbers, within the kernel's training
    command ranges, 0 -> standing) instead of passing on the task's (Section 4.2.8.4); the task's command
    stays the observation's ``command`` and the reward's target."""
    drive_steer: bool = False
    """The policy adds an offset to the task's velocity command before the kernel (3 numbers, ± the kernel's
    training command range's upper bounds, 0 -> none; the sum clipped to those ranges): steering the
    kernel's steps, as a capture step does after a push. Ours (docs/agent-gait.md); not with
    ``drive_command``, which sets the command whole."""
    drive_heights: bool = False
    """The policy sets kernel-ext's step and ride heights (2 numbers, within the ranges kernel-ext was
    trained on, 0 -> its nominal heights). Ours (docs/agent-gait.md); needs an ``ext`` kernel."""
    drive_rhythm: bool = False
    """The policy sets the gait clock's rate (1 number, within ``rhythm_range``, 0 -> the kernel's own
    rate), so a swing can end sooner or later. Ours (docs/agent-gait.md)."""
    rhythm_range: tuple[float, float] = RHYTHM_RANGE
    """Bounds of the driven clock rate, multiples of the kernel's gait frequency (low < 1 < high)."""
    gait_alpha: float = GAIT_ALPHA
    """Smoothing α of the low-pass filter every driven kernel input and the clock rate pass through."""

    def __post_init__(self) -> None:
        if len(self.residual_bound) != 3:
            raise AgentConfigError(
                f"residual_bound must have 3 values (x, y, z) [m], got {self.residual_bound!r}"
            )
        for axis, bound in zip("xyz", self.residual_bound, strict=True):
            _positive(f"residual_bound {axis}", bound)
        for name in ("alpha", "gait_alpha"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and 0 < value <= 1):
                raise AgentConfigError(f"{name} must be in (0, 1], got {value!r}")
        _range("rhythm_range", self.rhythm_range)
        if not 0 < self.rhythm_range[0] < 1 < self.rhythm_range[1]:
            raise AgentConfigError(f"rhythm_range must satisfy 0 < low < 1 < high, got {self.rhythm_range!r}")
        if self.action_size == 0:
            raise AgentConfigError("the action is empty: switch on residuals or one of the drive_* settings")
        if self.drive_command and self.drive_steer:
            raise AgentConfigError(
                "drive_command and drive_steer both set the kernel's command: switch on one of them"
            )

    @property
    def action_size(self) -> int:
        """Numbers in one action, each in [-1, 1] (:func:`krl.agent.action.action_parts` names them)."""
        return (
            RESIDUAL_ACTION_SIZE * self.residuals
            + 3 * self.drive_command
            + 3 * self.drive_steer
            + 2 * self.drive_heights
            + 1 * self.drive_rhythm
        )

    @property
    def drives_gait(self) -> bool:
        """Whether the policy drives any kernel input or the clock (else: the thesis's residual agent)."""
        return self.drive_command or self.drive_steer or self.drive_heights or self.drive_rhythm


@dataclass(frozen=True)
class EnvConfig:
    """The training environment (Section 4.2.9)."""

    heightfield_probability: float = 0.75
    """Probability that a new terrain is a random height field (else stepped pyramids, with
    ``pyramids_probability``, else Perlin hills)."""
    heightfield_max_height: tuple[float, float] = HEIGHTFIELD_MAX_HEIGHT_RANGE
    """Height-field perturbation h ~ U(low, high) [m] (blocks of height U(0, h))."""
    pyramids_probability: float = 0.0
    """Probability that a new terrain is a field of stepped pyramids (the terrain ``pyramids``). Ours, a
    training option: the thesis trains on height fields and hills only, the default."""
    pyramids_step_height: tuple[float, float] = PYRAMIDS_STEP_HEIGHT_RANGE
    """Each pyramid's riser height ~ U(low, high) [m]."""
    friction: tuple[float, float] = (FOOT_FRICTION, FOOT_FRICTION)
    """The ground's sliding friction μ ~ U(low, high) [-] of each new terrain (the terrains' ``friction``
    parameter). Ours, a training option: the thesis trains on μ = 1, the default, where nothing is drawn,
    so a default run makes the thesis's draws."""
    episodes_per_terrain: int = 5
    """Consecutive episodes on one terrain before a new one is drawn."""
    episode_time: float = 60.0
    """Episode length [s]: the thesis counts the targets reached in 60 s; the limit truncates."""
    d_min: float = CommandParams.d_min
    """Waypoint threshold D_min [m]."""
    target_distance: tuple[float, float] = TARGET_DISTANCE
    """Distance of each random waypoint from the previous one ~ U(low, high) [m] (as in the collection)."""
    field_margin: float = 2.0
    """Waypoints stay this far inside the terrain's edge [m] (ours: the 24 m fields end)."""
    pushes: bool = True
    """Random pushes on the trunk (Section 4.2.9)."""
    push_interval: tuple[float, float] = PushDistribution.interval
    """Time between pushes ~ U(low, high) [s]."""
    push_magnitude: tuple[float, float] = PushDistribution.magnitude
    """Push force ~ U(low, high) [N], for 0.3 s, at a random trunk point, directed slightly upwards."""
    push_top_share: float | None = None
    """Probability that a training push strikes the trunk's top face, the other faces sharing the rest by
    area (ours, docs/agent-robust.md: sideways pushes on the top roll every krl agent over); None: points
    uniform over the surface, the top taking its share of the area (0.248)."""
    push_curriculum: bool = False
    """The pushes' upper magnitude grows as the agent survives them (ours, :mod:`krl.agent.curriculum`):
    from ``push_magnitude``'s high, by ``push_curriculum_step`` after each rollout whose pushes were
    survived at ``push_curriculum_raise`` or more, back by a step below ``push_curriculum_lower``."""
    push_curriculum_max: float = PUSH_CURRICULUM_LIMIT
    """The curriculum's largest upper magnitude [N], at most :data:`PUSH_CURRICULUM_LIMIT`."""
    push_curriculum_step: float = 50.0
    """The curriculum's step [N]."""
    push_curriculum_raise: float = 0.9
    """Fraction of a rollout's pushes survived at or above which the ceiling rises."""
    push_curriculum_lower: float = 0.7
    """Fraction of a rollout's pushes survived below which the ceiling falls."""
    reward: RewardConfig = EVALUATION_REWARD
    """The reward trained on (:mod:`krl.task.reward`): in a config file a name of
    :data:`krl.task.reward.REWARDS` (``rp``: Table 4.8 + roll/pitch, agent-rp; ``base``: Table 4.8,
    agent-base; ``initial``: Table 4.6) or the whole table; saved whole in config.json and policy files."""

    def __post_init__(self) -> None:
        if not 0 <= self.heightfield_probability <= 1:
            raise AgentConfigError(
                f"heightfield_probability must be in [0, 1], got {self.heightfield_probability!r}"
            )
        _range("heightfield_max_height", self.heightfield_max_height)
        if self.heightfield_max_height[0] <= 0:
            raise AgentConfigError("heightfield_max_height must be > 0 m")
        if not 0 <= self.pyramids_probability <= 1 - self.heightfield_probability:
            raise AgentConfigError(
                "pyramids_probability must be in [0, 1 - heightfield_probability], got "
                f"{self.pyramids_probability!r}"
            )
        _range("pyramids_step_height", self.pyramids_step_height)
        if self.pyramids_step_height[0] <= 0:
            raise AgentConfigError("pyramids_step_height must be > 0 m")
        _range("friction", self.friction)
        if not 0 < self.friction[0] <= self.friction[1] <= MAX_GROUND_FRICTION:
            raise AgentConfigError(
                f"friction must satisfy 0 < low <= high <= {MAX_GROUND_FRICTION:g}, got {self.friction!r}"
            )
        if not (isinstance(self.episodes_per_terrain, int) and self.episodes_per_terrain >= 1):
            raise AgentConfigError(
                f"episodes_per_terrain must be an integer >= 1, got {self.episodes_per_terrain!r}"
            )
        _positive("episode_time", self.episode_time)
        _positive("d_min", self.d_min)
        _range("target_distance", self.target_distance)
        if self.target_distance[0] <= 0:
            raise AgentConfigError("target_distance must be > 0 m")
        if not (isinstance(self.field_margin, (int, float)) and 0 <= self.field_margin < 10):
            raise AgentConfigError(f"field_margin must be in [0, 10) m, got {self.field_margin!r}")
        _range("push_interval", self.push_interval)
        if self.push_interval[0] <= 0:
            raise AgentConfigError("push_interval must be > 0 s")
        _range("push_magnitude", self.push_magnitude)
        share = self.push_top_share
        if share is not None and (
            isinstance(share, bool) or not isinstance(share, (int, float)) or not 0 <= share <= 1
        ):
            raise AgentConfigError(f"push_top_share must be in [0, 1] or null, got {share!r}")
        self._check_curriculum()
        if not isinstance(self.reward, RewardConfig):
            raise AgentConfigError(f"reward must be a reward configuration, got {self.reward!r}")

    def _check_curriculum(self) -> None:
        _positive("push_curriculum_step", self.push_curriculum_step)
        _range(
            "push_curriculum_lower, push_curriculum_raise",
            (self.push_curriculum_lower, self.push_curriculum_raise),
        )
        if self.push_curriculum_raise > 1:
            raise AgentConfigError(f"push_curriculum_raise must be <= 1, got {self.push_curriculum_raise!r}")
        high, limit = self.push_magnitude[1], PUSH_CURRICULUM_LIMIT
        maximum = self.push_curriculum_max
        if not (isinstance(maximum, (int, float)) and (not self.push_curriculum or high <= maximum <= limit)):
            raise AgentConfigError(
                f"push_curriculum_max must be in [push_magnitude's high {high:g}, {limit:g}] N (the largest "
                f"push the thesis measures, {PUSH_CURRICULUM_LIMIT_DELTA_V:.1f} m/s on the free robot), "
                f"got {maximum!r}"
            )


CORE_FEATURES: tuple[str, ...] = (
    "base_lin_vel",
    "base_ang_vel",
    "command",
    "joint_pos",
    "joint_vel",
    "gravity",
    "roll_pitch",
)
"""The observation's core attributes, in every agent and study (4.2.8: v, a of the base and the command, q,
q̇, CoM, pitch, roll)."""


@dataclass(frozen=True)
class ObservationConfig:
    """Which features the policy observes (:mod:`krl.agent.observation` documents each)."""

    features: tuple[str, ...] = (*CORE_FEATURES, "residual", "foot_contact")
    """Feature names in order: the thesis's final set (4.2.8.3): the core attributes, the previous
    filtered residual and the foot contacts. Optional: ``phase``, ``kernel_targets``, ``contact_force``
    (Fig. 4.20), and for a policy that drives the kernel ``kernel_command``, ``heights``, ``clock_rate``."""

    def __post_init__(self) -> None:
        from krl.agent.observation import FEATURES

        unknown = [name for name in self.features if name not in FEATURES]
        if unknown:
            raise AgentConfigError(
                f"unknown observation feature {unknown[0]!r}; known: {', '.join(FEATURES)}"
            )
        if len(set(self.features)) != len(self.features) or not self.features:
            raise AgentConfigError(
                f"observation features must be distinct and not empty, got {self.features!r}"
            )


@dataclass(frozen=True)
class PPOConfig:
    """PPO (Stable-Baselines3) settings: Fig. 4.17's trial 3 unless marked ours."""

    learning_rate: float = 1e-3
    """Initial learning rate."""
    lr_decay_horizon: float = 2e7
    """The learning rate falls linearly from ``learning_rate`` towards 0 at this many env steps ..."""
    lr_decay_stop: float = 3e6
    """... but stops falling after this many env steps (4.2.9: "we stop decaying the learning rate after
    3e6 timesteps"), staying at ``learning_rate * (1 - lr_decay_stop / lr_decay_horizon)``."""
    batch_size: int = 4000
    """Minibatch size [samples]."""
    n_epochs: int = 10
    """Passes over each rollout."""
    rollout_steps: int = 200_000
    """Env steps per rollout, summed over all environments (2e5)."""
    ent_coef: float = 5e-6
    """Entropy coefficient."""
    shared: tuple[int, ...] = (128, 128)
    """Hidden layers shared by actor and critic ("feature extractor 128x2")."""
    actor: tuple[int, ...] = (128,)
    """Actor hidden layers after the shared ones."""
    critic: tuple[int, ...] = (64,)
    """Critic hidden layers after the shared ones."""
    gamma: float = 0.99
    """Discount factor (SB3's default; the thesis does not give it)."""
    gae_lambda: float = 0.95
    """GAE λ (SB3's default)."""
    clip_range: float = 0.2
    """PPO clip range (SB3's default)."""
    log_std_init: float = -1.0
    """Initial log standard deviation of the Gaussian actions (ours: σ ≈ 0.37 of the residual bound)."""
    normalize_observations: bool = True
    """Running mean/std normalisation of observations (ours; exported with the policy)."""
    normalize_rewards: bool = True
    """Scale rewards by a running estimate of the return's std (ours; training only)."""
    symmetry: str = "none"
    """Left-right mirror symmetry asked of the policy (ours, :mod:`krl.agent.symmetric_ppo`): ``none`` (the
    thesis's PPO), ``augment`` (each minibatch joined by its mirror image) or ``loss`` (a mirror loss on the
    mean action and the value)."""
    mirror_loss_coef: float = 1.0
    """Weight of the mirror loss with ``symmetry = "loss"`` (ours)."""

    def __post_init__(self) -> None:
        if self.symmetry not in SYMMETRY_MODES:
            raise AgentConfigError(
                f"unknown symmetry mode {self.symmetry!r}; known: {', '.join(SYMMETRY_MODES)}"
            )
        names = ("learning_rate", "lr_decay_horizon", "ent_coef", "gamma", "gae_lambda", "clip_range")
        for name in (*names, "mirror_loss_coef"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise AgentConfigError(f"{name} must be a finite number >= 0, got {value!r}")
        if not 0 <= self.lr_decay_stop <= self.lr_decay_horizon:
            raise AgentConfigError("lr_decay_stop must be in [0, lr_decay_horizon]")
        for name in ("batch_size", "n_epochs", "rollout_steps"):
            value = getattr(self, name)
            if not (isinstance(value, int) and value >= 1):
                raise AgentConfigError(f"{name} must be an integer >= 1, got {value!r}")
        for name in ("shared", "actor", "critic"):
            value = getattr(self, name)
            if not all(isinstance(width, int) and width >= 1 for width in value):
                raise AgentConfigError(f"{name} must be a list of positive layer widths, got {value!r}")

    def learning_rate_at(self, steps: float) -> float:
        """The learning rate after ``steps`` env steps."""
        return self.learning_rate * (1.0 - min(steps, self.lr_decay_stop) / self.lr_decay_horizon)


DEFAULT_NUM_ENVS: int = 16
"""Environments per worker process unless a config says otherwise."""


@dataclass(frozen=True)
class AgentConfig:
    """Everything that defines a residual agent and its training."""

    residual: ResidualConfig = field(default_factory=ResidualConfig)
    env: EnvConfig = field(default_factory=EnvConfig)
    observation: ObservationConfig = field(default_factory=ObservationConfig)
    ppo: PPOConfig = field(default_factory=PPOConfig)
    num_envs: int = DEFAULT_NUM_ENVS
    """Environments per worker process (ours; benchmarks/README.md measured the choice)."""
    workers: int | None = None
    """Worker processes stepping environments; None: one per usable core, resolved when a run starts and
    saved so in its ``config.json``."""
    total_steps: int = 20_000_000
    """Env steps to train for (thesis: 2e7)."""
    checkpoint_every: int = 1_000_000
    """Env steps between checkpoints, taken at the end of the rollout that passes each multiple (an
    interruption loses fewer than this and one rollout together)."""

    def __post_init__(self) -> None:
        for name in ("num_envs", "workers", "total_steps", "checkpoint_every"):
            value = getattr(self, name)
            if name == "workers" and value is None:
                continue
            if not (isinstance(value, int) and value >= 1):
                raise AgentConfigError(f"{name} must be an integer >= 1, got {value!r}")

    def to_json(self) -> dict[str, Any]:
        """The config as JSON data; the reward as :meth:`krl.task.reward.RewardConfig.to_json` writes it."""
        data = json.loads(json.dumps(dataclasses.asdict(self)))
        data["env"]["reward"] = self.env.reward.to_json()
        return data

    @classmethod
    def from_json(cls, data: Any, source: str = "config") -> AgentConfig:
        """Build from a JSON-like mapping (missing keys: defaults); one-line errors name the bad key."""
        return _from_mapping(cls, data, source)

    @classmethod
    def load(cls, path: str | Path) -> AgentConfig:
        """Read a JSON (``.json``) or TOML (``.toml``) config file."""
        return cls.from_json(read_table(path), str(path))

    @classmethod
    def load_layers(cls, paths: Sequence[str | Path]) -> AgentConfig:
        """Read config files and lay each over those before it (:func:`lay_over`): the first a recipe, the
        rest its changes (``{"ppo": {"symmetry": "loss"}}``). An invalid result names the first file whose
        layer made it so."""
        if not paths:
            raise AgentConfigError("no agent config file to read")
        merged: list[dict[str, Any]] = []
        for table in map(read_table, paths):
            merged.append(lay_over(merged[-1], table) if merged else table)
        try:
            return cls.from_json(merged[-1], " + ".join(map(str, paths)))
        except AgentConfigError:
            for path, table in zip(paths, merged, strict=True):
                cls.from_json(table, str(path))
            raise


def read_table(path: str | Path) -> dict[str, Any]:
    """The settings of a JSON (``.json``) or TOML (``.toml``) config file, unchecked."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as error:
        raise AgentConfigError(f"cannot read agent config {path}: {error.strerror}") from None
    try:
        if path.suffix == ".toml":
            import tomllib

            return tomllib.loads(text)
        return json.loads(text)
    except ValueError as error:
        raise AgentConfigError(
            f"agent config {path} is not valid {path.suffix[1:] or 'JSON'}: {error}"
        ) from None


def lay_over(base: Any, layer: Any) -> Any:
    """``layer`` laid over ``base``: where both are tables, key by key (recursively); anything else in
    ``layer`` replaces what ``base`` has (a list, a number, a reward named over a reward table)."""
    if not (isinstance(base, dict) and isinstance(layer, dict)):
        return layer
    return {**base, **{key: lay_over(base.get(key), value) for key, value in layer.items()}}


def _from_mapping(cls: type, data: Any, where: str):
    """``cls`` from a JSON-like table: every key known, every value of its field's type (a list for a
    tuple, an integer for a float); the sections of :class:`AgentConfig` and the reward recursively."""
    if not isinstance(data, dict):
        raise AgentConfigError(f"{where}: expected a table of settings, got {type(data).__name__}")
    hints = typing.get_type_hints(cls)
    known = [f.name for f in dataclasses.fields(cls)]
    unknown = sorted(set(data) - set(known))
    if unknown:
        raise AgentConfigError(f"{where}: unknown setting {unknown[0]!r}; known: {', '.join(known)}")
    values: dict[str, Any] = {}
    for name, value in data.items():
        sub = _SECTIONS.get(name) if cls is AgentConfig else None
        if sub is not None:
            values[name] = _from_mapping(sub, value, f"{where}.{name}")
        elif hints[name] is RewardConfig:
            try:
                values[name] = RewardConfig.from_json(value)
            except RewardConfigError as error:
                raise AgentConfigError(f"{where}.{name}: {error}") from None
        else:
            values[name] = _typed(f"{where}.{name}", value, hints[name])
    try:
        return cls(**values)
    except AgentConfigError as error:
        raise AgentConfigError(f"{where}: {error}") from None
    except (TypeError, ValueError) as error:
        raise AgentConfigError(f"{where}: {error}") from None


def _typed(where: str, value: Any, hint: Any) -> Any:
    """``value`` as the type ``hint`` names (bool, int, float, str or a tuple of them), or a one-line
    AgentConfigError: ``"no"`` is not a bool, ``true`` is not a number, ``1.5`` is not an integer."""
    if isinstance(hint, types.UnionType):  # X | None: None, or an X
        kind = next(arg for arg in typing.get_args(hint) if arg is not type(None))
        return None if value is None else _typed(where, value, kind)
    if typing.get_origin(hint) is tuple:
        if not isinstance(value, (list, tuple)):
            raise AgentConfigError(f"{where} must be a list, got {value!r}")
        kinds = typing.get_args(hint)
        if len(kinds) == 2 and kinds[1] is Ellipsis:
            kinds = (kinds[0],) * len(value)
        elif len(kinds) != len(value):
            raise AgentConfigError(f"{where} must be a list of {len(kinds)} values, got {value!r}")
        return tuple(_typed(where, item, kind) for item, kind in zip(value, kinds, strict=True))
    is_number = isinstance(value, (int, float)) and not isinstance(value, bool)
    if hint is float and is_number:
        return float(value)
    if (hint is int and is_number and isinstance(value, int)) or (
        hint in (bool, str) and isinstance(value, hint)
    ):
        return value
    raise AgentConfigError(f"{where} must be {_KIND_NAMES[hint]}, got {value!r}")


_KIND_NAMES: dict[type, str] = {bool: "true or false", int: "an integer", float: "a number", str: "a text"}


_SECTIONS: dict[str, type] = {
    "residual": ResidualConfig,
    "env": EnvConfig,
    "observation": ObservationConfig,
    "ppo": PPOConfig,
}
