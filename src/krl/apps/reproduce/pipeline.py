"""The pipeline's steps in order (:func:`pipeline`), as rows of :mod:`krl.apps.reproduce.table`, with the
wall time each took on the 2-core development machine (``docs/reproduce.md``)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from krl.apps.reproduce.robust import robust_rows
from krl.apps.reproduce.table import (
    AGENT_SEED_EVALUATION_MINUTES,
    EXPERT_EVALUATION_MINUTES,
    ByMode,
    Fragment,
    Row,
    chosen_seed_rows,
)
from krl.util.thesis import COMPARISON_EPOCHS, THESIS_SEEDS

COURSES: tuple[str, ...] = ("tabletop", "seesaw", "stairs", "sinusoid", "flat", "slope", "heightfield")
"""The courses pictured in ``docs/figures/courses``."""
STANCES: tuple[str, ...] = ("0.3", "0.25", "0.2")
"""τ_stance of Table 4.3's datasets [s]."""
QUICK_SEEDS: tuple[int, ...] = THESIS_SEEDS[:1]
"""The seeds of ``--quick`` (the full pipeline's are the thesis's four): one kernel-study run, one agent of
each kind."""
AGENTS: tuple[str, ...] = ("rp", "base")
"""The agents trained, one per seed each: agent-rp (Table 4.8's reward with the roll and pitch term) and
agent-base (without it)."""


def places(runs: str, docs: str, seeds: Sequence[int]) -> dict[str, str]:
    """What the templates' placeholders stand for, for the run folder ``runs``, documents ``docs`` and the
    training ``seeds`` (``{seed}`` is the first: the one kernel-ind the figures show)."""
    return {
        "runs": runs,
        "docs": docs,
        "data": f"{runs}/data",
        "seeds": ",".join(map(str, seeds)),
        "seed": str(seeds[0]),
        "kernel": f"{runs}/kernel-base/kernel.npz",
    }


def _stance_data(tau: str) -> str:
    """Template of the folder of Table 4.3's dataset with a stance of ``tau`` seconds."""
    return "{data}/s" + tau


def _collect_stance(tau: str) -> Row:
    """Expert data of Table 4.3 with a stance of ``tau`` seconds."""
    return Row(
        f"collect-stance{tau}",
        f"Table 4.3's data, τ {tau} s",
        ByMode(4, 0.5),
        (
            f"collect --out {_stance_data(tau)}",
            "--targets",
            ByMode("100", "12"),
            f"--seed 3 --stance-duration {tau}",
            "--quiet",
        ),
    )


_COURSE_CAMERAS: dict[str, str] = {"slope": " --azimuth 90 --elevation -8"}
"""Cameras other than ``krl render``'s default: a ramp along x shows its rise only from the side."""


def _course_picture(course: str) -> Row:
    """The picture of ``course`` in ``docs/figures/courses``."""
    return Row(
        f"course-{course}",
        f"picture of the {course} course",
        0.1,
        (
            f"render --course {course}{_COURSE_CAMERAS.get(course, '')}",
            "--out {docs}/figures/courses/" + course + ".png",
        ),
    )


_STUDY: tuple[Fragment, ...] = (
    "--runs {runs}/studies --threads 1 --seeds {seeds}",
    ByMode(f"--epochs {COMPARISON_EPOCHS}", "--epochs 2"),
    ByMode("--walk-targets 5", "--walk-targets 1"),
    "--quiet",
)
"""The options every kernel study shares."""
_EVALUATE = "--workers 2 --out {runs}/eval --quiet"
"""The options both evaluations share."""
_QUICK_AGENT: dict[str, Any] = {
    "total_steps": 20000,
    "checkpoint_every": 10000,
    "num_envs": 4,
    "ppo": {"rollout_steps": 4000, "batch_size": 1000, "n_epochs": 3},
}
"""A short agent training."""
_RESIDUAL = {"kernel": "{kernel}"}
"""The agents' residual part: the kernel the pipeline trained."""
_AGENT_RECIPE: dict[str, Any] = {"workers": 2, "num_envs": 16, "checkpoint_every": 500_000}
"""How the shipped seed groups were trained (docs/agent.md): 2 workers of 16 environments, whatever the
machine's cores (more workers would change the rollout the recipe was measured with)."""

# The pipeline's steps before the agents, one row per step in order; a pure table, longer than a function
# may be.
DATA_AND_KERNELS: tuple[Row, ...] = (
    Row(
        "collect-base",
        "expert data, stance 0.2 s",
        ByMode(14, 1.5),
        ("collect --out {data}/base --targets", ByMode("500", "40"), "--seed 0 --quiet"),
    ),
    Row(
        "collect-ext",
        "kernel-ext's data",
        ByMode(19, 1),
        ("collect --out {data}/ext --mode ext --targets", ByMode("500", "20"), "--seed 1 --quiet"),
    ),
    Row(
        "collect-dyn2",
        "kernel-dyn2's data",
        ByMode(16, 1),
        ("collect --out {data}/dyn2 --mode dyn2 --targets", ByMode("500", "20"), "--seed 2 --quiet"),
    ),
    *(_collect_stance(tau) for tau in STANCES),
    Row(
        "kernel-base",
        "kernel-base",
        ByMode(13, 1),
        (
            "kernel train --data {data}/base --out {runs}/kernel-base --threads 1",
            ByMode("", "--epochs 3"),
            "--quiet",
        ),
    ),
    Row(
        "kernel-ext",
        "kernel-ext",
        ByMode(19, 1),
        (
            "kernel train --data {data}/ext --variant ext --out {runs}/kernel-ext --threads 1",
            ByMode("", "--epochs 3"),
            "--quiet",
        ),
    ),
    Row(
        "study-variants",
        "Table 4.4",
        ByMode(200, 4),
        (
            "kernel study variants --data-base {data}/base --data-ext {data}/ext --data-dyn2 {data}/dyn2",
            "--out {docs}/results/kernel",
            *_STUDY,
        ),
    ),
    Row(
        "study-data-size",
        "Table 4.5",
        ByMode(120, 2),
        (
            "kernel study data-size --data {data}/base --out {docs}/results/kernel",
            ByMode("", "--sizes 10,25"),
            *_STUDY,
        ),
    ),
    Row(
        "study-stance",
        "Table 4.3",
        ByMode(60, 2),
        (
            "kernel study stance",
            *(f"--data-stance {tau}={_stance_data(tau)}" for tau in STANCES),
            "--out {docs}/results/kernel",
            *_STUDY,
        ),
    ),
    Row(
        "tune",
        "Optuna trials (trials.csv)",
        ByMode(25, 2),
        (
            "kernel tune --data {data}/base --out {runs}/tune",
            ByMode("--trials 8", "--trials 2"),
            "--threads 1",
            ByMode("", "--epochs 2"),
            "--quiet",
        ),
    ),
    Row(
        "expert-figures",
        "Figs. 4.8, 4.15 (MPC), A.2, A.3",
        ByMode(15, 2),
        ("expert plot all --out {docs}/figures/expert --seed 0", ByMode("", "--quick")),
    ),
    Row(
        "kernel-figures",
        "Figs. 4.9-4.13, 4.15",
        ByMode(15, 2),
        (
            "kernel figures all --out {docs}/figures/kernel --model {kernel}",
            "--ext-model {runs}/kernel-ext/kernel.npz",
            "--ind-model {runs}/studies/variants/ind-seed{seed}/kernel.npz",
            ByMode("", "--quick"),
        ),
    ),
    *(_course_picture(course) for course in COURSES),
)
"""Expert data, kernels, kernel studies and figures, course pictures: the steps before the agents."""


def _agent_row(agent: str, seed: int) -> Row:
    """Training of agent-``agent`` from ``seed`` into ``RUNS/agent-<agent>/seed<S>``, with the recipe of
    the shipped seed groups (:data:`_AGENT_RECIPE`)."""
    config: dict[str, Any] = {"residual": _RESIDUAL}
    if agent != "rp":
        config["env"] = {"reward": agent}
    return Row(
        f"agent-{agent}-seed{seed}",
        f"agent-{agent} (seed {seed})",
        ByMode(120, 4),
        (f"agent train --out {{runs}}/agent-{agent}/seed{seed} --seed {seed} --config {{config}} --quiet",),
        config=ByMode({**config, **_AGENT_RECIPE}, {**config, **_QUICK_AGENT}),
    )


def _scoring_rows(seeds: Sequence[int]) -> tuple[Row, ...]:
    """Evaluation of the trained kernel and seed groups, the report and the training curves."""
    groups = " ".join(f"--controller agent:{{runs}}/agent-{agent}" for agent in AGENTS)
    return (
        Row(
            "evaluate-courses",
            "Tables 5.1-5.4 runs",
            ByMode(6 + 2 * len(seeds), 6),
            (
                "evaluate --controller expert --controller expert:stance=0.3 --controller kernel:{kernel}",
                groups,
                "--seeds {seeds} --course thesis --course flat",
                _EVALUATE,
            ),
        ),
        # 50 attempts per magnitude, as docs/results: the thesis's 10 leave each rate's interval ±0.3 wide
        Row(
            "evaluate-pushes",
            "Table 5.5 runs",
            ByMode(30 * (2 + len(seeds)), 2),
            (
                "evaluate --controller expert --controller kernel:{kernel}",
                "--controller agent:{runs}/agent-rp --seeds {seeds}",
                ByMode("--push-sweep --attempts 50", "--push-sweep --attempts 1"),
                _EVALUATE,
            ),
        ),
        Row("report", "Tables 5.1-5.5", 0.2, ("report --results {runs}/eval --out {docs}/results",)),
        Row(
            "level-base",
            "Fig. 4.22",
            ByMode(10, 4),
            (
                "agent study level-base --policy agent-base={runs}/agent-base@{seed}",
                "--policy agent-rp={runs}/agent-rp@{seed} --report-out {docs}/results/agent",
            ),
        ),
        Row(
            "agent-curves",
            "training curves, Fig. 4.23",
            0.1,
            (
                "agent curves {runs}/agent-rp/seed{seed}",
                " ".join(f"--group agent-{agent}={{runs}}/agent-{agent}" for agent in AGENTS),
                "--out {docs}/figures/agent",
            ),
        ),
    )


GAIT_ABLATION_SEEDS: int = 2
"""How many of the training seeds (the first) the gait ablation trains each variant from, as
``examples/gait/agent-gait.sh`` (150 and 215); agent-gait's other seeds train from the chosen recipe."""
_QUICK_GAIT_BUDGET: int = 8000
"""Env steps of each quick gait-ablation run: two of the quick agent's rollouts."""
_QUICK_GAIT_EPISODE: float = 2.0
"""Episode length of the quick gait-ablation runs [s]: their 1000 control steps (200 Hz) of each of 8
robots end two episodes, as a study's run must (a 60 s episode is 12 000 steps)."""
_AGENT_STUDIES = "{runs}/agent-studies"
"""Where each agent study's folder is (``<study>``)."""
_ABLATION = f"{_AGENT_STUDIES}/gait-ablation"
"""The gait ablation's study folder."""
_TRIALS = f"{_ABLATION}/trials/list"
"""Where the gait ablation's run folders are (``VARIANT-seedS``)."""


def _gait_seed_split(seeds: Sequence[int]) -> tuple[Sequence[int], Sequence[int]]:
    """(the seeds the gait studies train each variant from, the seeds a chosen recipe trains alone)."""
    return seeds[:GAIT_ABLATION_SEEDS], seeds[GAIT_ABLATION_SEEDS:]


def _gait_study_row(study: str, makes: str, minutes: ByMode[float], seeds: Sequence[int]) -> Row:
    """``krl agent study STUDY`` (a gait study) from ``seeds`` into ``RUNS/agent-studies/STUDY``, on the
    pipeline's kernel-ext in place of the shipped one; ``--quick`` with the quick agent's settings and
    episodes short enough to end in a run, as a study's must."""
    kernel = {"residual": {"kernel": "{runs}/kernel-ext/kernel.npz"}}
    quick = {key: value for key, value in _QUICK_AGENT.items() if key != "total_steps"}
    quick["env"] = {"episode_time": _QUICK_GAIT_EPISODE}
    return Row(
        study,
        makes,
        minutes,
        (
            f"agent study {study} --out {_AGENT_STUDIES}/{study}",
            f"--seeds {','.join(map(str, seeds))} --jobs 2 --config {{config}}",
            ByMode("", f"--budget {_QUICK_GAIT_BUDGET}"),
            "--quiet",
        ),
        config=ByMode(kernel, {**kernel, **quick}),
    )


def _gait_rows(seeds: Sequence[int]) -> tuple[Row, ...]:
    """agent-gait as ``examples/gait/agent-gait.sh`` makes it (docs/agent-gait.md): the ablation on the
    pipeline's kernel-ext, the choice on held-out episodes, the chosen recipe's other seeds."""
    from krl.agent.studies.designs import GAIT_DRIVES

    variants = [name for name, *_ in GAIT_DRIVES]
    driving = [name for name, _, drives, _ in GAIT_DRIVES if drives]  # agent-gait's candidates
    ablation, more = _gait_seed_split(seeds)
    policies = " ".join(f"--policy {name}={_TRIALS}/{name}-seed*" for name in variants)
    return (
        _gait_study_row(
            "gait-ablation",
            "the gait ablation's runs",
            ByMode(66 * len(variants) * len(ablation), 6),
            ablation,
        ),
        Row(
            "heldout-gait",
            "agent-gait chosen on held-out episodes",
            ByMode(25, 2),
            (
                f"agent heldout {policies}",
                ByMode("--episodes 32", "--episodes 2"),
                f"--choose {','.join(driving)} --out {{runs}}/heldout-gait",
                "--seed-group {runs}/agent-gait --quiet",
            ),
        ),
        *chosen_seed_rows("agent-gait", "heldout-gait", more),
    )


_GROUND = f"{_AGENT_STUDIES}/gait-ground"
"""The ground study's folder."""
_GROUND_TRIALS = f"{_GROUND}/trials/list"
"""Where the ground study's run folders are (``VARIANT-seedS``)."""


def _ground_rows(seeds: Sequence[int]) -> tuple[Row, ...]:
    """agent-gait-ground as ``examples/gait/agent-gait-ground.sh`` makes it (docs/agent-gait.md): the ground
    study on the pipeline's kernel-ext from the ablation's seeds, the rule written before its runs on
    held-out episodes (the choice must stand against agent-gait's recipe), the chosen recipe's other seeds.
    Where the choice does not stand (``RUNS/heldout-ground/choice.json``) there is no chosen config and
    the next step stops the pipeline: nothing ships from the study then."""
    from krl.agent.studies.designs import GAIT_GROUND_RECIPE, STUDIES

    variants = [variant.name for variant in STUDIES["gait-ground"].variants]
    broad = variants[-1]  # pyramids-pushes: pyramids and the stronger pushes, the broadest ground
    ablation, more = _gait_seed_split(seeds)
    policies = " ".join(f"--policy {name}={_GROUND_TRIALS}/{name}-seed*" for name in variants)
    return (
        # a run's minutes: benchmarks/README.md, "Wall times of the reproduce pipeline"
        _gait_study_row(
            "gait-ground",
            "the ground study's runs",
            ByMode(63 * len(variants) * len(ablation), 2.5),
            ablation,
        ),
        Row(
            "heldout-ground",
            "agent-gait-ground chosen on held-out episodes",
            ByMode(18, 2),
            (
                f"agent heldout --policy agent-gait={_TRIALS}/{GAIT_GROUND_RECIPE}-seed* {policies}",
                f"--env {_GROUND_TRIALS}/{broad}-seed{{seed}}/config.json --choose {','.join(variants)}",
                "--baseline agent-gait",
                f"--baseline-env {_TRIALS}/{GAIT_GROUND_RECIPE}-seed{{seed}}/config.json",
                ByMode("--episodes 32", "--episodes 2"),
                "--out {runs}/heldout-ground --seed-group {runs}/agent-gait-ground --quiet",
            ),
        ),
        *chosen_seed_rows("agent-gait-ground", "heldout-ground", more),
    )


def _gait_scoring_rows(seeds: Sequence[int]) -> tuple[Row, ...]:
    """Every gait variant, the seed groups and the baselines on the thesis's and the harder courses, the
    push and the friction sweeps, and their report."""
    from krl.agent.studies.designs import GAIT_DRIVES, STUDIES

    variants = [name for name, *_ in GAIT_DRIVES]
    ground = [variant.name for variant in STUDIES["gait-ground"].variants]
    ablation, more = _gait_seed_split(seeds)
    # the seed group agent-gait-ground exists where the ground study's choice stood; --quick's runs are too
    # short for that, so it scores the study's runs only
    return (
        Row(
            "evaluate-gait",
            "agent-gait's tables' runs",
            # the chosen variants' seeds are the seed groups' files, whose runs krl evaluate makes once
            ByMode(
                AGENT_SEED_EVALUATION_MINUTES
                * (2 * len(more) + len(seeds) + (len(variants) + len(ground)) * len(ablation))
                + EXPERT_EVALUATION_MINUTES,
                6,
            ),
            (
                "evaluate --controller agent:{runs}/agent-gait",
                ByMode("--controller agent:{runs}/agent-gait-ground", ""),
                " ".join(f"--controller agent:{_TRIALS}/{name}-seed*" for name in variants),
                " ".join(f"--controller agent:{_GROUND_TRIALS}/{name}-seed*" for name in ground),
                "--controller agent:{runs}/agent-rp --controller expert --controller kernel:{kernel}",
                ByMode(
                    "--course thesis --course harder --push-sweep --attempts 50 --friction-sweep",
                    "--course flat --push-sweep --attempts 1 --friction-sweep --frictions 0.5 "
                    "--friction-course flat",
                ),
                "--workers 2 --out {runs}/eval-gait --quiet",
            ),
        ),
        Row(
            "report-gait",
            "agent-gait's tables",
            0.2,
            ("report --results {runs}/eval-gait --out {docs}/results/gait",),
        ),
    )


def pipeline(seeds: Sequence[int]) -> tuple[Row, ...]:
    """Every step, in order (expert data -> kernels -> studies, figures -> agents of each seed ->
    evaluation -> report -> agent-gait -> agent-gait-ground -> their evaluation and report -> agent-robust,
    its evaluation and report) for the training ``seeds``."""
    agents = tuple(_agent_row(agent, seed) for agent in AGENTS for seed in seeds)
    gait = (*_gait_rows(seeds), *_ground_rows(seeds), *_gait_scoring_rows(seeds))
    return (*DATA_AND_KERNELS, *agents, *_scoring_rows(seeds), *gait, *robust_rows(*_gait_seed_split(seeds)))
