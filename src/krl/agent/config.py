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
from krl.control.filters import RESIDUAL_ALPHA
from krl.robots.a1.constants import FOOT_FRICTION, NUM_LEGS, STANDING_HEIGHT
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
    residual_alpha: float = RESIDUAL_ALPHA
    """Smoothing factor α of the residuals' low-pass filter (Eq. 4.4); read from ``alpha`` in configs
    written before it was renamed (:data:`RENAMED_SETTINGS`)."""
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
        for name in ("residual_alpha", "gait_alpha"):
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


CURRICULUM_TILES: tuple[str, ...] = ("pyramids", "pits", "rough", "slope")
"""The tile kinds a terrain curriculum draws from (:mod:`krl.agent.terrain_curriculum` builds each)."""

MAX_CURRICULUM_RISER: float = 0.25
"""The highest riser a curriculum may train on [m] (about the A1's upper leg; legged_gym goes to 0.23)."""


@dataclass(frozen=True)
class TerrainCurriculumConfig:
    """A terrain curriculum (ours, :mod:`krl.agent.terrain_curriculum`, docs/agent-perceptive.md): each
    robot has a level; its terrains are drawn from ``tiles`` at that level's difficulty, interpolated
    linearly from each range's low (level 0) to its high (the top level); it is promoted after an episode
    that reached ``promote_targets`` waypoints and demoted after one that reached fewer than
    ``demote_targets``. Replaces the terrain draw of ``heightfield_probability`` and
    ``pyramids_probability``."""

    levels: int = 10
    """Number of levels."""
    tiles: tuple[str, ...] = CURRICULUM_TILES
    """Tile kinds drawn from (:data:`CURRICULUM_TILES`): ``pyramids`` (stairs up and down), ``pits`` (stairs
    down and up), ``rough`` (the random height field), ``slope`` (a ramp up and down)."""
    tile_weights: tuple[float, ...] = (0.35, 0.25, 0.25, 0.15)
    """Probability weight of each tile kind, in ``tiles``' order."""
    riser: tuple[float, float] = (0.03, 0.15)
    """Riser height of the pyramids and pits at level 0 and at the top level [m]."""
    roughness: tuple[float, float] = (0.02, 0.10)
    """Block height bound of the rough height field at level 0 and at the top level [m]."""
    incline: tuple[float, float] = (0.05, 0.35)
    """Angle of the slopes at level 0 and at the top level [rad]."""
    start_levels: int = 3
    """A robot starts on a level drawn uniformly from 0 ... start_levels - 1."""
    promote_targets: int = 4
    """Waypoints an episode must reach for a promotion (to a random level after the top, as legged_gym)."""
    demote_targets: int = 2
    """An episode reaching fewer waypoints demotes (never below level 0)."""

    def __post_init__(self) -> None:
        if not (isinstance(self.levels, int) and self.levels >= 1):
            raise AgentConfigError(f"terrain curriculum levels must be an integer >= 1, got {self.levels!r}")
        if not self.tiles:
            raise AgentConfigError(
                f"the terrain curriculum has no tiles; give some of {', '.join(CURRICULUM_TILES)}"
            )
        unknown = [tile for tile in self.tiles if tile not in CURRICULUM_TILES]
        if unknown or len(set(self.tiles)) != len(self.tiles):
            raise AgentConfigError(
                f"terrain curriculum tiles must be distinct kinds of {', '.join(CURRICULUM_TILES)}, got "
                f"{list(self.tiles)!r}"
            )
        weights = self.tile_weights
        if len(weights) != len(self.tiles) or not all(
            isinstance(w, (int, float)) and math.isfinite(w) and w > 0 for w in weights
        ):
            raise AgentConfigError(
                f"tile_weights must be one positive number per tile ({len(self.tiles)}), "
                f"got {list(weights)!r}"
            )
        _range("terrain curriculum riser", self.riser)
        _range("terrain curriculum roughness", self.roughness)
        _range("terrain curriculum incline", self.incline)
        if self.riser[0] <= 0 or self.riser[1] > MAX_CURRICULUM_RISER:
            raise AgentConfigError(
                f"terrain curriculum riser must lie in (0, {MAX_CURRICULUM_RISER:g}] m, "
                f"got {list(self.riser)!r}"
            )
        if self.roughness[0] <= 0 or not 0 < self.incline[0] <= self.incline[1] < 0.6:
            raise AgentConfigError("terrain curriculum roughness must be > 0 m and incline in (0, 0.6) rad")
        if not (isinstance(self.start_levels, int) and 1 <= self.start_levels <= self.levels):
            raise AgentConfigError(
                f"start_levels must be an integer in [1, levels = {self.levels}], got {self.start_levels!r}"
            )
        if not (
            isinstance(self.promote_targets, int)
            and isinstance(self.demote_targets, int)
            and 0 <= self.demote_targets <= self.promote_targets
        ):
            raise AgentConfigError(
                "promote_targets and demote_targets must be integers with "
                "0 <= demote_targets <= promote_targets"
            )


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
    terrain_curriculum: TerrainCurriculumConfig | None = None
    """A terrain curriculum (ours, :class:`TerrainCurriculumConfig`); None (the default): the terrain draw
    above."""
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


SCAN_REACH: float = 2.0
"""Farthest a height-scan point may lie from the trunk along either heading axis [m]: the training fields'
waypoints stay ``field_margin`` (2 m) inside their edges, so such a scan stays on the field."""


@dataclass(frozen=True)
class ScanConfig:
    """The height scan's grid and scaling (the features ``height_scan`` and ``height_scan_clean``, ours,
    docs/agent-perceptive.md). Points lie on a grid in the robot's heading frame (yaw-aligned, origin under
    the trunk; x forward, y left), x-major: point ``i * len(y) + j`` is ``(x[i], y[j])``. The defaults are
    legged_gym's rough-terrain grid: 1.6 m x 1.0 m at 0.1 m, 187 points."""

    x_range: tuple[float, float] = (-0.8, 0.8)
    """First and last x of the grid [m] (behind, ahead of the trunk)."""
    half_width: float = 0.5
    """The grid's y runs from -half_width to half_width [m] (symmetric, so the scan has a mirror)."""
    spacing: float = 0.1
    """Distance between neighbouring points along x and y [m]."""
    offset: float = STANDING_HEIGHT
    """Each value is ``trunk height - terrain height - offset`` [m]: 0 under a robot standing on level
    ground, positive over a step down, negative over a step up."""
    clip: float = 1.0
    """Values are clipped to [-clip, clip] [m] (the observation normaliser scales them after)."""
    noise: float = 0.0
    """Training only: each value of the actor's ``height_scan`` gets a U(-noise, noise) [m] error, drawn
    anew every step; evaluation and ``height_scan_clean`` are noise-free."""

    def __post_init__(self) -> None:
        _range("scan x_range", self.x_range, low=-SCAN_REACH)
        for name in ("spacing", "clip"):
            _positive(f"scan {name}", getattr(self, name))
        for name in ("half_width", "noise", "offset"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise AgentConfigError(f"scan {name} must be a number >= 0, got {value!r}")
        if max(abs(self.x_range[0]), abs(self.x_range[1]), self.half_width) > SCAN_REACH:
            raise AgentConfigError(
                f"the scan grid reaches beyond the terrain: its points must stay within {SCAN_REACH:g} m of "
                f"the trunk (x_range {list(self.x_range)}, half_width {self.half_width:g})"
            )
        for name, span in (
            ("x_range", self.x_range[1] - self.x_range[0]),
            ("half_width", 2 * self.half_width),
        ):
            if abs(span / self.spacing - round(span / self.spacing)) > 1e-6:
                raise AgentConfigError(
                    f"scan {name} must span a whole number of spacings ({self.spacing:g} m), got {span:g} m"
                )

    @property
    def x(self) -> tuple[float, ...]:
        """The grid's x values [m], ascending."""
        count = round((self.x_range[1] - self.x_range[0]) / self.spacing) + 1
        return tuple(self.x_range[0] + self.spacing * k for k in range(count))

    @property
    def y(self) -> tuple[float, ...]:
        """The grid's y values [m], ascending and symmetric about 0."""
        count = round(2 * self.half_width / self.spacing) + 1
        return tuple(-self.half_width + self.spacing * k for k in range(count))

    @property
    def size(self) -> int:
        """Points of the grid."""
        return len(self.x) * len(self.y)

    def points(self) -> list[tuple[float, float]]:
        """The grid's (x, y) points in the heading frame [m], x-major. Length: :attr:`size`."""
        return [(x, y) for x in self.x for y in self.y]


@dataclass(frozen=True)
class ObservationConfig:
    """Which features the policy observes, and which more its critic sees (:mod:`krl.agent.observation`
    documents each)."""

    features: tuple[str, ...] = (*CORE_FEATURES, "residual", "foot_contact")
    """Feature names in order: the thesis's final set (4.2.8.3): the core attributes, the previous
    filtered residual and the foot contacts. Optional: ``phase``, ``kernel_targets``, ``contact_force``
    (Fig. 4.20), for a policy that drives the kernel ``kernel_command``, ``heights``, ``clock_rate``, and
    the terrain around it ``height_scan`` (ours)."""
    critic_features: tuple[str, ...] = ()
    """Features only the critic (the value function) sees, after the actor's: the privileged ones
    (``height_scan_clean``, ``ground_friction``, ``push_force``, ``terrain_level``) or any other. Empty (the
    default): actor and critic see the same observation through shared layers (the thesis's network);
    otherwise each has its own layers (:class:`krl.agent.network.PrivilegedCriticPolicy`), ours."""
    scan: ScanConfig = field(default_factory=ScanConfig)
    """The height scan's grid and scaling (read where ``height_scan`` or ``height_scan_clean`` is
    observed)."""

    def __post_init__(self) -> None:
        from krl.agent.observation import FEATURES

        for role, names in (("observation", self.features), ("critic", self.critic_features)):
            unknown = [name for name in names if name not in FEATURES]
            if unknown:
                raise AgentConfigError(f"unknown {role} feature {unknown[0]!r}; known: {', '.join(FEATURES)}")
        if len(set(self.features)) != len(self.features) or not self.features:
            raise AgentConfigError(
                f"observation features must be distinct and not empty, got {self.features!r}"
            )
        privileged = [name for name in self.features if FEATURES[name].privileged]
        if privileged:
            raise AgentConfigError(
                f"observation feature {privileged[0]!r} is privileged (no robot measures it): give it to "
                "critic_features"
            )
        both = self.features + self.critic_features
        if len(set(both)) != len(both):
            raise AgentConfigError(
                f"critic_features must be distinct and not among the actor's features, got "
                f"{list(self.critic_features)!r}"
            )
        if not isinstance(self.scan, ScanConfig):
            raise AgentConfigError(f"scan must be a scan configuration, got {self.scan!r}")

    @property
    def all_features(self) -> tuple[str, ...]:
        """The environment's observation: the actor's features, then the critic's own."""
        return self.features + self.critic_features


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
        for path in paths:
            table = with_current_names(read_table(path), str(path))
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


RENAMED_SETTINGS: dict[tuple[str, str], str] = {("residual", "alpha"): "residual_alpha"}
"""Settings renamed since configs were first saved, ``(section, old name) -> new name``: a config read
with the old name means the same as with the new one (every saved ``config.json`` and policy file keeps
loading); a config is written with the new names only."""


def with_current_names(data: Any, where: str) -> Any:
    """The JSON-like config table ``data`` with each setting of :data:`RENAMED_SETTINGS` under its new
    name; a one-line AgentConfigError where a section gives both names. Anything not a table of tables is
    returned as it is (:func:`_from_mapping` refuses it)."""
    if not isinstance(data, dict):
        return data
    renamed = dict(data)
    for (section, old), new in RENAMED_SETTINGS.items():
        table = renamed.get(section)
        if not (isinstance(table, dict) and old in table):
            continue
        if new in table:
            raise AgentConfigError(
                f"{where}.{section}: both {old!r} and {new!r} are given; {old!r} is the old name of "
                f"{new!r}: keep one"
            )
        renamed[section] = {(new if key == old else key): value for key, value in table.items()}
    return renamed


def _from_mapping(cls: type, data: Any, where: str):
    """``cls`` from a JSON-like table: every key known, every value of its field's type (a list for a
    tuple, an integer for a float); the sections of :class:`AgentConfig` and the reward recursively."""
    if not isinstance(data, dict):
        raise AgentConfigError(f"{where}: expected a table of settings, got {type(data).__name__}")
    if cls is AgentConfig:
        data = with_current_names(data, where)
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
        elif _section_of(hints[name]) is not None:
            values[name] = (
                None if value is None else _from_mapping(_section_of(hints[name]), value, f"{where}.{name}")
            )
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


def _section_of(hint: Any) -> type | None:
    """The settings dataclass a field holds (``ScanConfig``, ``TerrainCurriculumConfig``, alone or with
    ``| None``), else None."""
    kinds = typing.get_args(hint) if isinstance(hint, types.UnionType) else (hint,)
    return next((k for k in kinds if dataclasses.is_dataclass(k) and k is not RewardConfig), None)


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
