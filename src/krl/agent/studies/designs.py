"""The thesis's agent studies (Sections 4.2.8.1-4.2.8.4) and our gait-driving ablation and ground study as
data: what each trains and what it compares.

A study is either a **list** (named variants, each trained from every seed: Table 4.7's rewards, Fig.
4.20's observation sets) or a **search** (random trials drawn from a space, each trained from one seed,
then the best few trained again from every seed: Table A.3's PPO settings). Every trial is one
``krl agent train`` run of an :class:`krl.agent.config.AgentConfig` made of the study's base settings and
the variant's or the drawn trial's overrides (nested JSON tables, as a ``--config`` file holds).

The base of every study is the thesis's optimisation set-up (4.2.1, Fig. 4.2b): the kernel-base agent on
"a moderately difficult height-field terrain with perturbations 0.35cm", krl's ``heightfield_mild`` (h = 2
cm: 3.5 mm is nearly flat for a 2 cm foot and 3.5 cm no milder than the final agent's 3-4.5 cm, the reading
docs/terrains.md gives). No Perlin hills and no pushes: the thesis adds both only for the final agent
(4.2.9). The gait-driving ablation (ours) trains as the final agent does instead: its terrains, pushes,
reward (agent-rp's) and 16 environments per worker, for 2e7 steps; the ground study (ours) trains the
ablation's chosen recipe so on ground with stepped pyramids, and with stronger pushes. The budgets and the
seeds are the thesis's; ``krl agent study --budget/--seeds/--trials`` cut them down (docs/studies.md).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from krl.agent.config import CORE_FEATURES
from krl.sim.terrains import HEIGHTFIELD_MILD_MAX_HEIGHT
from krl.task.reward import COMMAND_TARGET, INITIAL_REWARD, RBFTerm, RewardConfig
from krl.util.thesis import THESIS_SEEDS

Overrides = Mapping[str, Any]
"""A nested table of :class:`krl.agent.config.AgentConfig` settings (``{"ppo": {"n_epochs": 5}}``)."""

OPTIMISATION_TERRAIN: dict[str, Any] = {
    "heightfield_probability": 1.0,
    "heightfield_max_height": [HEIGHTFIELD_MILD_MAX_HEIGHT, HEIGHTFIELD_MILD_MAX_HEIGHT],
    "pushes": False,
}
"""The environment of the studies (module docstring): ``heightfield_mild``'s height field, no hills, no
pushes."""

INITIAL_OPTIONAL: tuple[str, ...] = ("phase", "foot_contact")
"""The optional attributes of the initial observation (4.2.8), used until the state-space study."""


@dataclass(frozen=True)
class Variant:
    """One named configuration of a list study."""

    name: str
    """File-name-safe name (trial folders, table rows)."""
    description: str
    """What it changes, as the thesis's table says."""
    overrides: Overrides
    """Settings on top of the study's base."""


@dataclass(frozen=True)
class StudyDesign:
    """One study: its base settings and either its variants or its search space, with the thesis's budget."""

    name: str
    title: str
    """What of the thesis it reproduces (``Table A.3, Fig. 4.17``)."""
    base: Overrides
    """Settings every trial shares."""
    budget: int
    """Env steps per trial (the search's trials, or every variant's)."""
    variants: tuple[Variant, ...] = ()
    """The list study's variants (empty for a search)."""
    space: Callable[[Any], Overrides] | None = None
    """A search's space: ``optuna trial -> overrides`` (None for a list study)."""
    trials: int = 0
    """A search's random trials."""
    top: int = 0
    """A search's best trials trained again from every seed."""
    confirm_budget: int = 0
    """Env steps of each of those confirming runs."""
    seeds: tuple[int, ...] = THESIS_SEEDS

    @property
    def is_search(self) -> bool:
        return self.space is not None

    def __post_init__(self) -> None:
        if self.is_search == bool(self.variants):
            raise ValueError(f"study {self.name}: give either variants or a search space")


def merged(*tables: Overrides) -> dict[str, Any]:
    """The tables merged left to right, nested tables key by key (the later wins)."""
    out: dict[str, Any] = {}
    for table in tables:
        for key, value in table.items():
            if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
                out[key] = merged(out[key], value)
            else:
                out[key] = dict(value) if isinstance(value, Mapping) else value
    return out


STUDY_NUM_ENVS: int = 4
"""Environments per worker of a study's trials (2 workers: 8 in all), against the shipped agents' 16: closer
to the thesis's five, and enough 60 s episodes (12 000 steps each) end within a cut-down trial's budget
for its targets reached to be measured (16 x 2 environments would end none before 3.8e5 steps)."""


def _study_base(features: tuple[str, ...], reward: str = "initial") -> dict[str, Any]:
    return {
        "env": {**OPTIMISATION_TERRAIN, "reward": reward},
        "observation": {"features": list(features)},
        "num_envs": STUDY_NUM_ENVS,
    }


# --- ppo-search: Table A.3 --------------------------------------------------------------------------

PPO_NETWORKS: dict[str, list[int]] = {"large": [256, 256, 256], "medium": [256, 256], "small": [128, 128]}
"""Table A.3's network sizes: the layers shared by actor and critic (Fig. A.1); the actor adds one of 128,
the critic one of 64, in every size."""
PPO_LEARNING_RATES: tuple[float, ...] = (3e-3, 1e-3, 5e-4, 5e-5)
PPO_EPOCHS: tuple[int, ...] = (5, 10, 20)
PPO_BATCH_SIZES: tuple[int, ...] = (500, 2000, 4000)
PPO_ENTROPY_RANGE: tuple[float, float] = (1e-6, 1e-3)
"""Table A.3's entropy coefficient range, drawn log-uniformly (ours: the thesis says "range"; drawn
uniformly, its selected 5e-6 would lie in the bottom 0.4 % of the range)."""
PPO_ROLLOUT_STEPS: int = 20_000
"""Table A.3's fixed roll-out length (Fig. 4.17's caption gives 2e5 for the selected trial; the shipped
agents use 2e5)."""


def ppo_space(trial) -> dict[str, Any]:
    """One draw of Table A.3's space (a :class:`optuna.trial.Trial`)."""
    return {
        "ppo": {
            "learning_rate": trial.suggest_categorical("learning_rate", list(PPO_LEARNING_RATES)),
            "ent_coef": trial.suggest_float("ent_coef", *PPO_ENTROPY_RANGE, log=True),
            "shared": PPO_NETWORKS[trial.suggest_categorical("network", list(PPO_NETWORKS))],
            "n_epochs": trial.suggest_categorical("n_epochs", list(PPO_EPOCHS)),
            "batch_size": trial.suggest_categorical("batch_size", list(PPO_BATCH_SIZES)),
        }
    }


# --- state-space: Fig. 4.20 -------------------------------------------------------------------------

STATE_SETS: tuple[tuple[str, str, tuple[str, ...]], ...] = (
    ("core", "the core attributes alone", ()),
    ("phase", "+ leg phases", ("phase",)),
    ("contacts", "+ foot contacts", ("foot_contact",)),
    ("phase-contacts", "+ leg phases and foot contacts (the initial set)", INITIAL_OPTIONAL),
    (
        "targets-contacts",
        "+ the kernel's foot targets instead of the phases",
        ("kernel_targets", "foot_contact"),
    ),
    (
        "phase-contacts-force",
        "+ leg phases, foot contacts and contact forces",
        (*INITIAL_OPTIONAL, "contact_force"),
    ),
    (
        "residual-phase-contacts",
        "+ the filtered residual, leg phases, foot contacts",
        ("residual", *INITIAL_OPTIONAL),
    ),
    (
        "residual-contacts",
        "+ the filtered residual and foot contacts (the thesis's final set)",
        ("residual", "foot_contact"),
    ),
)
"""Fig. 4.20's observation sets: (name, description, optional features after the core)."""


def _state_variants() -> tuple[Variant, ...]:
    return tuple(
        Variant(name, description, {"observation": {"features": [*CORE_FEATURES, *optional]}})
        for name, description, optional in STATE_SETS
    )


# --- reward-features: Table 4.7 ----------------------------------------------------------------------

NOMINAL_EXPERIMENT: float = 5.0
"""Table 4.7's fall penalty (trials 5, 7) and target bonus (trials 6, 7)."""
CONSTRAINT_STEEPNESS: dict[str, float] = {"vertical_velocity": 18.42, "roll_pitch_rate": 7.47}
"""Trial 3's added terms (vertical velocity; roll and pitch rates; target 0): the thesis gives no q, we take
the linear and the angular velocity terms' (Table 4.6); weight 0.01 as every initial term."""
SLIP_STEEPNESS: float = 2.5e5
"""q of the per-step stance slip terms (trials 8, 9) [1/m²] (ours: the thesis gives none): a reward of
exp(-1) at 2 mm of summed slip in one 5 ms step (0.4 m/s of sliding), weight 0.01."""
DRIFT_STEEPNESS: float = 1e4
"""q of trial 10's stance drift since touch-down [1/m²] (ours): exp(-1) at 1 cm summed over the stance
feet, weight 0.01."""


def _trial_rewards() -> dict[str, tuple[str, RewardConfig]]:
    """Table 4.7's rewards, by variant name: (what it changes, the reward)."""
    initial = INITIAL_REWARD
    without = lambda name: tuple(t for t in initial.terms if t.name != name)  # noqa: E731
    constraints = tuple(
        RBFTerm(quantity, quantity, (0.0,) * (1 if quantity == "vertical_velocity" else 2), q, 0.01)
        for quantity, q in CONSTRAINT_STEEPNESS.items()
    )
    shortfall = tuple(
        RBFTerm(t.name, t.quantity, t.target, t.steepness, t.weight, shortfall=t.target == COMMAND_TARGET)
        for t in initial.terms
    )
    trial4 = RewardConfig(shortfall, fall_penalty=None, target_bonus=None)
    trial7 = RewardConfig(shortfall, fall_penalty=-NOMINAL_EXPERIMENT, target_bonus=NOMINAL_EXPERIMENT)
    slip = RBFTerm("stance_slip", "stance_slip", (0.0,), SLIP_STEEPNESS, 0.01)
    return {
        "initial": ("the initial reward (Table 4.6)", initial),
        "t1-no-com": ("trial 1: without the CoM term", RewardConfig(without("gravity"), None, None)),
        "t2-no-target": (
            "trial 2: without the target distance term",
            RewardConfig(without("target_distance"), None, None),
        ),
        "t3-constraints": (
            "trial 3: + vertical, roll and pitch velocities at 0",
            RewardConfig((*initial.terms, *constraints), None, None),
        ),
        "t4-shortfall": ("trial 4: no loss for exceeding the velocity commands", trial4),
        "t5-fall": (
            "trial 5: trial 4 + a fall penalty of 5",
            RewardConfig(shortfall, -NOMINAL_EXPERIMENT, None),
        ),
        "t6-target": (
            "trial 6: trial 4 + a target reward of 5",
            RewardConfig(shortfall, None, NOMINAL_EXPERIMENT),
        ),
        "t7-both": ("trial 7: trial 4 + both", trial7),
        "t8-slip-reward": (
            "trial 8: trial 7 + a stance slip reward (t to t-1)",
            RewardConfig((*shortfall, slip), -NOMINAL_EXPERIMENT, NOMINAL_EXPERIMENT),
        ),
        "t9-slip-penalty": (
            "trial 9: trial 7 + a stance slip penalty (t to t-1)",
            RewardConfig(
                (
                    *shortfall,
                    RBFTerm("stance_slip", "stance_slip", (0.0,), SLIP_STEEPNESS, 0.01, penalty=True),
                ),
                -NOMINAL_EXPERIMENT,
                NOMINAL_EXPERIMENT,
            ),
        ),
        "t10-drift-penalty": (
            "trial 10: trial 7 + a penalty on the stance feet's drift since touch-down",
            RewardConfig(
                (
                    *shortfall,
                    RBFTerm("stance_drift", "stance_drift", (0.0,), DRIFT_STEEPNESS, 0.01, penalty=True),
                ),
                -NOMINAL_EXPERIMENT,
                NOMINAL_EXPERIMENT,
            ),
        ),
    }


TRIAL_REWARDS: dict[str, tuple[str, RewardConfig]] = _trial_rewards()
"""Table 4.7's eleven rewards: (what it changes, the reward), by variant name."""
TRIAL_7_REWARD: RewardConfig = TRIAL_REWARDS["t7-both"][1]
"""The reward the RBF and weight searches start from (4.2.8.2: "we continue with the reward function from
trial 7")."""


def _reward_variants() -> tuple[Variant, ...]:
    return tuple(
        Variant(name, description, {"env": {"reward": reward.to_json()}})
        for name, (description, reward) in TRIAL_REWARDS.items()
    )


# --- reward-rbf and reward-weights: Table A.4 and the weight range --------------------------------------

RBF_RANGES: dict[str, tuple[float, float]] = {
    "linear_velocity": (15.0, 20.0),
    "angular_velocity": (5.0, 10.0),
    "gravity": (1.0, 4.0),
    "target_distance": (1.0, 4.0),
}
"""Table A.4's four ranges of q, given to the terms whose initial q they hold (ours: as printed, the table's
rows give the linear velocity [1, 4] and the CoM [15, 20], which hold neither the initial 18.42 nor 2.35;
the target distance's 0.74 lies in none, so it takes the range left, [1, 4])."""
WEIGHT_RANGE: tuple[float, float] = (0.001, 0.005)
"""The weight search's range (4.2.8.2), for each of the four RBF terms (Table 4.8's final weights,
0.0076-0.0298, lie outside it: the thesis does not say how; we search the range it states)."""


def _reward_table(**changes: dict[str, float]) -> dict[str, Any]:
    """Trial 7's reward with some terms' steepness or weight replaced, as a config table."""
    terms = tuple(
        RBFTerm(
            t.name,
            t.quantity,
            t.target,
            changes.get("steepness", {}).get(t.name, t.steepness),
            changes.get("weight", {}).get(t.name, t.weight),
            t.shortfall,
            t.penalty,
        )
        for t in TRIAL_7_REWARD.terms
    )
    reward = RewardConfig(terms, TRIAL_7_REWARD.fall_penalty, TRIAL_7_REWARD.target_bonus)
    return {"env": {"reward": reward.to_json()}}


def rbf_space(trial) -> dict[str, Any]:
    """One draw of Table A.4's steepness ranges (uniform)."""
    return _reward_table(
        steepness={name: trial.suggest_float(f"q_{name}", *r) for name, r in RBF_RANGES.items()}
    )


def weight_space(trial) -> dict[str, Any]:
    """One draw of the four RBF weights in :data:`WEIGHT_RANGE` (uniform)."""
    return _reward_table(
        weight={name: trial.suggest_float(f"w_{name}", *WEIGHT_RANGE) for name in RBF_RANGES}
    )


def _reward_search(name: str, title: str, space: Callable[[Any], Overrides]) -> StudyDesign:
    """A search over trial 7's reward (4.2.8.2): 100 random trials of 3e6 steps on the initial observation,
    the best 5 trained from every seed for 3e6 steps."""
    return StudyDesign(
        name=name,
        title=title,
        base=_study_base((*CORE_FEATURES, *INITIAL_OPTIONAL)),
        budget=3_000_000,
        space=space,
        trials=100,
        top=5,
        confirm_budget=3_000_000,
    )


# --- alternative: Section 4.2.8.4 -------------------------------------------------------------------

FINAL_OPTIONAL: tuple[str, ...] = ("residual", "foot_contact")
"""The optional attributes the state-space study kept (4.2.8.3), the observation of the alternative study's
residual agent."""


def _alternative_variants() -> tuple[Variant, ...]:
    """The residual agent, as the state-space study left it, and the alternative architecture: the policy
    sets the kernel's velocity command and adds no residual (4.2.8.4, after Kasaei et al.). It observes the
    command it gave the kernel where the residual agent observes its residual."""
    commands = {
        "residual": {"residuals": False, "drive_command": True},
        "observation": {"features": [*CORE_FEATURES, "kernel_command", "foot_contact"]},
    }
    return (
        Variant("residual", "the residual agent (final observation set)", {}),
        Variant("commands", "the policy gives the kernel its velocity command; no residuals", commands),
    )


# --- gait-ablation: ours (issue #25) ------------------------------------------------------------------

GAIT_DRIVES: tuple[tuple[str, str, dict[str, bool], tuple[str, ...]], ...] = (
    ("residual-ext", "residuals alone, on kernel-ext (the faithful agent's action path)", {}, ()),
    ("heights", "+ the kernel's step and ride heights", {"drive_heights": True}, ("heights",)),
    ("rhythm", "+ the gait clock's rate", {"drive_rhythm": True}, ("clock_rate",)),
    (
        "both",
        "+ heights and the clock's rate",
        {"drive_heights": True, "drive_rhythm": True},
        ("heights", "clock_rate"),
    ),
    (
        "steer-both",
        "+ steering the kernel's command, heights and the clock's rate",
        {"drive_steer": True, "drive_heights": True, "drive_rhythm": True},
        ("kernel_command", "heights", "clock_rate"),
    ),
)
"""The gait-driving ablation's variants: (name, description, drive switches, the features observing them).
``steer-both`` (a capture step's steering beside the issue's four) is there because scripted rules
through one push found steering with a faster clock and a lower ride to keep kernel-ext up where no drive
alone did (docs/agent-gait.md)."""

GAIT_ABLATION_ALPHA: float = 0.5
"""The drive filter's α in the ablation's driving variants: a scripted rule steering, stepping faster and
lowering the ride kept kernel-ext up through a 600 N lateral push at α = 0.2, 0.5 and 1, and fell at the
default 0.05 (a 0.1 s lag beside a 0.3 s push); docs/agent-gait.md."""


GAIT_ABLATION_FRICTION: tuple[float, float] = (0.4, 1.0)
"""The ground's sliding μ ~ U(low, high) per training terrain in every ablation variant (the thesis: μ = 1).
Issue #25 asks for success at μ = 0.5, so training covers it with a margin; the range is MuJoCo
Playground's Go1 floor randomisation. Chosen before any ablation run, from no evaluation (the friction
sweep's 0.3 stays outside it); docs/agent-gait.md."""


def _drive_filter(drives: dict[str, bool]) -> dict[str, float]:
    """The ablation's drive filter setting for a variant with ``drives`` (none without any)."""
    return {"gait_alpha": GAIT_ABLATION_ALPHA} if drives else {}


def _gait_variants() -> tuple[Variant, ...]:
    """Each drive on top of the residuals (on the study base's kernel-ext), the policy observing what it
    drives beside the final set."""
    return tuple(
        Variant(
            name,
            description,
            {
                "residual": {**drives, **_drive_filter(drives)},
                "observation": {"features": [*CORE_FEATURES, *FINAL_OPTIONAL, *observed]},
            },
        )
        for name, description, drives, observed in GAIT_DRIVES
    )


# --- gait-ground: ours (issue #25) -------------------------------------------------------------------

GAIT_GROUND_TERRAINS: dict[str, float] = {"heightfield_probability": 0.5, "pyramids_probability": 0.25}
"""The ground study's terrains: stepped pyramids (risers U(4, 8) cm) a quarter of the time, taken from the
height field's share; Perlin hills keep their quarter (the thesis: height field 0.75, hills 0.25)."""

GAIT_GROUND_PUSH_MAGNITUDE: tuple[float, float] = (100.0, 600.0)
"""Training pushes U(low, high) [N] of the ground study's ``pyramids-pushes`` (the thesis: U(100, 350) N):
up to the 600 N of the lateral push target, where agent-gait's seed 150 fell (docs/agent-gait.md)."""

GAIT_GROUND_RECIPE: str = "steer-both"
"""The gait ablation's variant the ground study trains on other ground: agent-gait's (held-out choice)."""


def _gait_ground_variants() -> tuple[Variant, ...]:
    """agent-gait's action path on ground that asks for its drives: pyramids, and pyramids with pushes up to
    :data:`GAIT_GROUND_PUSH_MAGNITUDE`."""
    (recipe,) = [v for v in _gait_variants() if v.name == GAIT_GROUND_RECIPE]
    pushes = {"push_magnitude": list(GAIT_GROUND_PUSH_MAGNITUDE)}
    return (
        Variant(
            "pyramids",
            "agent-gait's recipe, a quarter of its terrains stepped pyramids",
            merged(recipe.overrides, {"env": GAIT_GROUND_TERRAINS}),
        ),
        Variant(
            "pyramids-pushes",
            "the same, and pushes up to 600 N",
            merged(recipe.overrides, {"env": {**GAIT_GROUND_TERRAINS, **pushes}}),
        ),
    )


_GAIT_BASE: dict[str, Any] = {
    "num_envs": 16,
    "env": {"friction": list(GAIT_ABLATION_FRICTION)},
    "residual": {"kernel": "ext"},
}
"""The base of both gait studies: the final agent's training with friction drawn, on kernel-ext (the kernel
in the base, so a --config's, krl reproduce's own kernel-ext, can take its place)."""


STUDIES: dict[str, StudyDesign] = {
    "ppo-search": StudyDesign(
        name="ppo-search",
        title="Table A.3, Fig. 4.17",
        base=merged(
            _study_base((*CORE_FEATURES, *INITIAL_OPTIONAL)), {"ppo": {"rollout_steps": PPO_ROLLOUT_STEPS}}
        ),
        budget=3_000_000,
        space=ppo_space,
        trials=100,
        top=5,
        confirm_budget=5_000_000,
    ),
    "reward-features": StudyDesign(
        name="reward-features",
        title="Table 4.7, Fig. 4.18",
        base=_study_base((*CORE_FEATURES, *INITIAL_OPTIONAL)),
        budget=3_000_000,
        variants=_reward_variants(),
    ),
    "reward-rbf": _reward_search("reward-rbf", "Table A.4, Fig. 4.19a", rbf_space),
    "reward-weights": _reward_search("reward-weights", "Fig. 4.19b", weight_space),
    "state-space": StudyDesign(
        name="state-space",
        title="Fig. 4.20",
        base=_study_base(CORE_FEATURES, reward="base"),
        budget=3_000_000,
        variants=_state_variants(),
    ),
    "alternative": StudyDesign(
        name="alternative",
        title="Section 4.2.8.4, Fig. 4.21",
        base=_study_base((*CORE_FEATURES, *FINAL_OPTIONAL), reward="base"),
        budget=3_000_000,
        variants=_alternative_variants(),
    ),
    "gait-ablation": StudyDesign(
        name="gait-ablation",
        title="ours: what driving the gait buys (issue #25)",
        base=_GAIT_BASE,
        budget=20_000_000,
        variants=_gait_variants(),
    ),
    "gait-ground": StudyDesign(
        name="gait-ground",
        title="ours: agent-gait on ground that asks for its drives (issue #25)",
        base=_GAIT_BASE,
        budget=20_000_000,
        variants=_gait_ground_variants(),
    ),
}
"""Every agent study ``krl agent study NAME`` runs, by name."""
