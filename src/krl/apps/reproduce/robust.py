"""The pipeline's rows of agent-robust (issue 45, docs/agent-robust.md) as ``examples/robust/agent-robust.sh``
makes it: the symmetry pilot, the candidate arms, the rule on held-out episodes, the chosen recipe's other
seeds, the evaluation, the reports, the sample-efficiency curves and the left-right sweep.

The arms are agent-gait-ground's recipe (the ground study's ``pyramids-pushes`` variant as run from the
first seed, on the pipeline's kernel-ext) with one change each, laid over it by ``krl agent config``
(:data:`LAYERS`). Two things differ from the script, since the pipeline is a fixed table of commands: sym's
first seed trains from the start rather than going on from the pilot's winner (the same recipe and seed,
4e6 env steps more), and the baselines are scored again rather than copied from earlier records. rp-sym,
from which nothing is chosen and nothing ships, is the script's alone.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from krl.apps.reproduce.table import (
    AGENT_PUSHES_PER_MINUTE,
    AGENT_SEED_EVALUATION_MINUTES,
    EXPERT_EVALUATION_MINUTES,
    EXPERT_PUSHES_PER_MINUTE,
    ByMode,
    Fragment,
    Row,
    chosen_seed_rows,
)
from krl.util.thesis import THESIS_PUSH_MAGNITUDES

LAYERS: dict[str, dict[str, Any]] = {
    "augment": {"ppo": {"symmetry": "augment"}},
    "loss": {"ppo": {"symmetry": "loss"}},
    "curriculum": {"env": {"push_curriculum": True, "push_curriculum_max": 900.0}},
    "broad-pushes": {"env": {"push_magnitude": [100.0, 900.0]}},
}
"""The changes to agent-gait-ground's recipe the study lays over it (``examples/robust/*.json`` are the
recipe with each, a test checks): the pilot's two symmetry modes, the push curriculum, and the broad push
ground the rule walks."""
ARMS: tuple[str, ...] = ("sym", "curriculum", "sym-curriculum")
"""The candidate arms, in the rule's order."""
PILOT_STEPS: ByMode[int] = ByMode(4_000_000, 4000)
"""Env steps of each pilot run."""
QUICK_STEPS: int = 8000
"""Env steps of each arm's run with ``--quick``: two of the quick agent's rollouts."""
BALANCED_ATTEMPTS: int = 48
"""Attempts per force of the balanced push sweep: 12 per quarter."""
LEFT_RIGHT_ATTEMPTS: int = 400
"""Attempts per force of the left-right sweep: 100 per quarter."""
LEFT_RIGHT_MAGNITUDES: tuple[int, int, int] = (350, 600, 50)
"""Forces of the left-right sweep [N]: first, last, step."""

_R = "{runs}/robust"
"""The study's folder: run folders ``ARM-seedS``, ``configs/``, the rules' records."""
_GROUND = "{runs}/agent-studies/gait-ground/trials/list/pyramids-pushes-seed"
"""agent-gait-ground's recipe's runs in the ground study (``<S>``), on the pipeline's kernel-ext."""
_RECIPE = _GROUND + "{seed}/config.json"
"""agent-gait-ground's recipe, as run from the first seed."""
_CHOSEN_SYMMETRY = f"{_R}/heldout-pilot/chosen-config.json"
"""The recipe with the pilot's chosen symmetry mode."""


def _config_row(name: str, base: str, layer: str | None = None) -> Row:
    """``RUNS/robust/configs/NAME.json``: the config file ``base`` with :data:`LAYERS`' ``layer`` over it."""
    return Row(
        f"robust-config-{name}",
        f"the {name} recipe",
        0.1,
        (f"agent config {base}", "{config}" if layer else "", f"--out {_R}/configs/{name}.json"),
        config=ByMode(LAYERS[layer], LAYERS[layer]) if layer else None,
    )


def _train_row(run: str, seed: int, config: str, minutes: ByMode[float], steps: Fragment) -> Row:
    """Training of ``RUNS/robust/RUN-seedS`` from ``seed`` with ``RUNS/robust/configs/CONFIG.json``."""
    return Row(
        f"robust-{run}-seed{seed}",
        f"{run} (seed {seed})",
        minutes,
        (
            f"agent train --out {_R}/{run}-seed{seed} --seed {seed} --config {_R}/configs/{config}.json",
            steps,
            "--quiet",
        ),
    )


def _pilot_rows(seed: int) -> tuple[Row, ...]:
    """Both symmetry modes from ``seed`` to :data:`PILOT_STEPS` (a fifth of a 2 h run each), the choice."""
    steps = ByMode(f"--steps {PILOT_STEPS.full}", f"--steps {PILOT_STEPS.quick}")
    modes = ("augment", "loss")
    return (
        *(_config_row(mode, _RECIPE, mode) for mode in modes),
        *(_train_row(f"pilot-{mode}", seed, mode, ByMode(24, 0.5), steps) for mode in modes),
        Row(
            "robust-heldout-pilot",
            "the pilot's symmetry chosen on held-out episodes",
            ByMode(8, 1),
            (
                f"agent heldout --policy augment={_R}/pilot-augment-seed{seed}",
                f"--policy loss={_R}/pilot-loss-seed{seed}",
                ByMode("--episodes 32", "--episodes 2"),
                f"--choose augment,loss --out {_R}/heldout-pilot --quiet",
            ),
        ),
    )


def _rule_rows(ablation: Sequence[int]) -> tuple[Row, ...]:
    """The arms' recipes and runs from the ``ablation`` seeds, and the rule choosing among them."""
    quick = f"--steps {QUICK_STEPS}"
    policies = " ".join(f"--policy {arm}={_R}/{arm}-seed*" for arm in ARMS)
    return (
        _config_row("sym", _CHOSEN_SYMMETRY),
        _config_row("curriculum", _RECIPE, "curriculum"),
        _config_row("sym-curriculum", _CHOSEN_SYMMETRY, "curriculum"),
        _config_row("broad-pushes", _RECIPE, "broad-pushes"),
        # one 2e7-step training alone on the machine, as the other agents' rows
        *(_train_row(arm, seed, arm, ByMode(120, 1), ByMode("", quick)) for arm in ARMS for seed in ablation),
        Row(
            "robust-heldout",
            "agent-robust chosen on held-out episodes",
            ByMode(34, 2),
            (
                f"agent heldout --policy baseline={_GROUND}* {policies}",
                f"--env {_R}/configs/broad-pushes.json --choose {','.join(ARMS)} --baseline baseline",
                f"--baseline-env {_RECIPE}",
                ByMode("--episodes 32", "--episodes 2"),
                f"--out {_R}/heldout-robust --seed-group {{runs}}/agent-robust --quiet",
            ),
        ),
    )


def _scoring_rows(ablation: Sequence[int], more: Sequence[int]) -> tuple[Row, ...]:
    """agent-robust (the arms' runs from the ``ablation`` seeds and its own from ``more``), the arms and the
    baselines (a seed group from each seed) on the courses and the sweeps, the
    reports, the curves. ``--quick``'s runs are too short to earn a seed group agent-robust or
    agent-gait-ground, so it scores the study's runs only."""
    controllers: tuple[Fragment, ...] = (
        ByMode("--controller agent:{runs}/agent-robust", ""),
        " ".join(f"--controller agent:{_R}/{arm}-seed*" for arm in ARMS),
        ByMode("--controller agent:{runs}/agent-gait-ground", f"--controller agent:{_GROUND}*"),
        "--controller agent:{runs}/agent-rp --controller expert",
    )
    agents = 2 * (len(ablation) + len(more)) + len(ARMS) * len(ablation) + len(more)
    groups = " ".join(
        f"--group {arm}={','.join(f'{_R}/{arm}-seed{seed}' for seed in ablation)}" for arm in ARMS
    )
    baseline = ",".join(f"{_GROUND}{seed}" for seed in ablation)
    return (
        Row(
            "robust-evaluate",
            "agent-robust's tables' runs",
            ByMode(AGENT_SEED_EVALUATION_MINUTES * agents + EXPERT_EVALUATION_MINUTES, 4),
            (
                "evaluate",
                *controllers,
                ByMode(
                    "--course thesis --course harder --push-sweep --attempts 50 --friction-sweep",
                    "--course flat --push-sweep --attempts 1 --friction-sweep --frictions 0.5 "
                    "--friction-course flat",
                ),
                "--workers 2 --out {runs}/eval-robust --quiet",
            ),
        ),
        Row(
            "robust-evaluate-balanced",
            "the balanced push sweep's runs",
            ByMode(_push_minutes(agents, BALANCED_ATTEMPTS * len(THESIS_PUSH_MAGNITUDES)), 2),
            (
                "evaluate",
                *controllers,
                "--push-sweep --push-directions balanced",
                ByMode(f"--attempts {BALANCED_ATTEMPTS}", "--attempts 4 --magnitudes 350,600"),
                "--workers 2 --out {runs}/eval-robust-balanced --quiet",
            ),
        ),
        Row(
            "robust-report",
            "agent-robust's tables",
            0.2,
            ("report --results {runs}/eval-robust --out {docs}/results/robust",),
        ),
        Row(
            "robust-report-balanced",
            "the balanced sweep's tables",
            0.2,
            ("report --results {runs}/eval-robust-balanced --out {docs}/results/robust-balanced",),
        ),
        Row(
            "robust-curves",
            "the arms' sample efficiency",
            0.1,
            (
                f"agent curves --group baseline={baseline} {groups}",
                "--reach baseline --out {docs}/results/robust/curves",
            ),
        ),
        *_left_right_rows(len(ablation) + len(more)),
    )


def _push_minutes(agent_seeds: int, attempts: int) -> float:
    """Wall time of a push sweep of ``attempts`` per controller seed (over all its forces) for
    ``agent_seeds`` agent seeds and the expert [min]."""
    return round(agent_seeds * attempts / AGENT_PUSHES_PER_MINUTE + attempts / EXPERT_PUSHES_PER_MINUTE)


def _left_right_rows(seeds: int) -> tuple[Row, ...]:
    """agent-robust and agent-gait-ground (``seeds`` seeds each) and the expert on the balanced sweep at
    350-600 N with 400 attempts per force (100 distinct pushes per side each, docs/agent-robust.md's step 7),
    and its report. ``--quick`` scores the study's sym-curriculum and agent-gait-ground's recipe's runs, as
    :func:`_scoring_rows`."""
    first, last, step = LEFT_RIGHT_MAGNITUDES
    return (
        Row(
            "robust-evaluate-left-right",
            "left and right at the target's forces",
            ByMode(_push_minutes(2 * seeds, LEFT_RIGHT_ATTEMPTS * len(range(first, last + 1, step))), 2),
            (
                "evaluate",
                ByMode(
                    "--controller agent:{runs}/agent-robust", f"--controller agent:{_R}/sym-curriculum-seed*"
                ),
                ByMode("--controller agent:{runs}/agent-gait-ground", f"--controller agent:{_GROUND}*"),
                "--controller expert --push-sweep --push-directions balanced",
                ByMode(
                    f"--magnitudes {first}:{last}:{step} --attempts {LEFT_RIGHT_ATTEMPTS}",
                    "--magnitudes 350,600 --attempts 4",
                ),
                "--workers 2 --out {runs}/eval-robust-left-right --quiet",
            ),
        ),
        Row(
            "robust-report-left-right",
            "the left-right sweep's tables",
            0.2,
            ("report --results {runs}/eval-robust-left-right --out {docs}/results/robust-left-right",),
        ),
    )


def robust_rows(ablation: Sequence[int], more: Sequence[int]) -> tuple[Row, ...]:
    """agent-robust's rows: the pilot from the first of the ``ablation`` seeds, the arms from each, the rule,
    agent-robust's ``more`` seeds (where the rule's choice stands: else the first of them stops the
    pipeline, as docs/agent-robust.md's rule says nothing ships), the scoring."""
    return (
        *_pilot_rows(ablation[0]),
        *_rule_rows(ablation),
        *chosen_seed_rows("agent-robust", "robust/heldout-robust", more),
        *_scoring_rows(ablation, more),
    )
