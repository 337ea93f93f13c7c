"""An agent study's tables and figures from its Optuna storage, of whatever has finished so far.

Every number comes from the trials' user attributes (:mod:`krl.agent.studies.runner`), so any machine
that reaches the storage can write the report. ``NAME.md`` holds the table with the budget used beside the
thesis's and the command that regenerates it; ``NAME.csv`` one row per trained run; ``NAME.png`` the mean
learning curves with their spread over seeds. A search adds its trials (``NAME-search.csv``) and, when it
ran unpruned, what the pruner would have saved on exactly those trials (:func:`replay_pruning`).
"""

from __future__ import annotations

import statistics
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from krl.agent.studies.designs import StudyDesign
from krl.agent.studies.runner import (
    CONFIRM,
    LIST,
    SEARCH,
    StudySettings,
    best_trials,
    open_stage,
    plan_entries,
    pruner,
    pruner_rule,
)
from krl.util.optuna_storage import masked
from krl.util.output import csv_bytes, distinct_colours, figure_bytes, write_atomic

THESIS_FINDINGS: dict[str, str] = {
    "ppo-search": "100 random trials of 3e6 steps, the best 5 trained from 4 seeds for 5e6 steps (Fig. 4.17, "
    "curves only); trial 3 chosen: lr 1e-3, 10 epochs, batch 4000, entropy 5e-6, the small network.",
    "reward-features": "Fig. 4.18 (curves only): without the CoM (trial 1) or the target distance (2) fewer "
    "targets and successes; trial 4 more targets but fewer successes; the fall penalty and target reward "
    "together (7) best; the slip penalties (9, 10) cut foot slip at a small cost in targets; trial 7 kept.",
    "reward-rbf": "Fig. 4.19a (curves only): the search over the terms' q did not beat the initial ones.",
    "reward-weights": "Fig. 4.19b (curves only): the best weights found became Table 4.8's (0.0076, 0.0264, "
    "0.0298, 0.0169).",
    "state-space": "Fig. 4.20 (curves only): phases and contacts help; the residual helps more, and with it "
    "the phases no longer do; the best set is the residual and the foot contacts.",
    "alternative": "Fig. 4.21 (curves only): some runs of the command-giving agent reach targets, others "
    "never do while their training reward keeps rising; the thesis suspects the CoM term rewards giving "
    "the kernel zero commands, where the robot is most stable.",
    "gait-ablation": "not in the thesis: its agent drives residuals only, and its conclusion proposes "
    "letting the agent choose the kernel's step and ride heights and the gait's parameters.",
    "gait-ground": "not in the thesis: its conclusion finds that the agent cannot take steps much greater "
    "than its training required; this study trains agent-gait's recipe where greater steps are required.",
}
"""What the thesis reports for each study (its studies give figures, not numbers)."""


def _finished(study) -> list:
    from optuna.trial import TrialState

    return [
        t
        for t in study.get_trials(deepcopy=False, states=(TrialState.COMPLETE, TrialState.PRUNED))
        if not t.user_attrs.get("surplus")
    ]


def _mean_std(values: Sequence[float]) -> tuple[float | None, float | None]:
    values = [v for v in values if v is not None]
    if not values:
        return None, None
    return statistics.fmean(values), (statistics.stdev(values) if len(values) > 1 else 0.0)


def group_rows(trials: Sequence[Any], group_of) -> list[dict[str, Any]]:
    """One row per group (``group_of(trial)``): seeds trained, final targets reached and success rate,
    mean and sample std over the seeds, mean env steps per run."""
    groups: dict[str, list[Any]] = {}
    for trial in trials:
        groups.setdefault(group_of(trial), []).append(trial)
    rows = []
    for name, members in groups.items():
        targets = _mean_std([t.user_attrs.get("targets_reached") for t in members])
        success = _mean_std([t.user_attrs.get("success_rate") for t in members])
        rows.append(
            {
                "group": name,
                "runs": len(members),
                "seeds": ",".join(str(t.user_attrs.get("seed")) for t in members),
                "targets_mean": targets[0],
                "targets_std": targets[1],
                "success_mean": success[0],
                "success_std": success[1],
                "env_steps": round(statistics.fmean(t.user_attrs.get("env_steps", 0) for t in members)),
            }
        )
    return sorted(rows, key=lambda row: -(row["targets_mean"] or 0.0))


def mean_curves(trials: Sequence[Any], group_of, grid_steps: float) -> dict[str, dict[str, np.ndarray]]:
    """Per group, the runs' targets reached, success rate and episode reward (the last missing from trials
    recorded before it was) on a common grid of env steps (every ``grid_steps``, up to the shortest run)."""
    groups: dict[str, list[np.ndarray]] = {}
    for trial in trials:
        rows = trial.user_attrs.get("curve", [])
        curve = np.full((len(rows), len(CURVE_SERIES) + 1), np.nan)
        for index, row in enumerate(rows):
            curve[index, : len(row)] = [np.nan if v is None else v for v in row]
        if len(curve):
            groups.setdefault(group_of(trial), []).append(curve)
    out = {}
    for name, curves in groups.items():
        end = min(c[-1, 0] for c in curves)
        grid = np.arange(grid_steps, end + 1, grid_steps) if end >= grid_steps else np.array([end])
        series = {}
        for column, label in enumerate(CURVE_SERIES, start=1):
            stacked = []
            for curve in curves:
                known = np.isfinite(curve[:, column])
                if known.any():
                    stacked.append(np.interp(grid, curve[known, 0], curve[known, column]))
            if stacked:
                series[label] = np.array(stacked)
        out[name] = {"steps": grid, **series, "runs": len(curves)}
    return out


CURVE_SERIES: tuple[str, ...] = ("targets", "success", "reward")
"""The series of a trial's recorded learning curve after its env steps (:func:`runner.final_metrics`)."""


def replay_pruning(trials: Sequence[Any], pruner) -> dict[str, Any]:
    """What ``pruner`` (an Optuna pruner) would have done to a search run unpruned: the recorded learning
    curves replayed in trial order through a fresh in-memory study. Returns the env steps it would have
    trained (a pruned trial stops at the rollout it was pruned after), against those trained, and the
    numbers of the trials it would have kept (the ones it prunes cannot be chosen)."""
    import optuna

    study = optuna.create_study(direction="maximize", pruner=pruner)
    used, full, kept = 0, 0, []
    for trial in sorted(trials, key=lambda t: t.number):
        curve = [row for row in trial.user_attrs.get("curve", []) if row[1] is not None]
        replay = study.ask()
        steps = trial.user_attrs.get("env_steps", curve[-1][0] if curve else 0)
        stopped = steps
        for step, targets, *_ in curve:
            replay.report(targets, step)
            if replay.should_prune():
                stopped = step
                break
        if stopped < steps:
            study.tell(replay, state=optuna.trial.TrialState.PRUNED)
        else:
            study.tell(replay, trial.user_attrs.get("targets_reached"))
            kept.append(trial.number)
        used, full = used + stopped, full + steps
    return {"env_steps_unpruned": full, "env_steps_pruned": used, "kept": kept}


RESAMPLED_REPEATS: int = 20
"""How many resampled searches the report replays per pruner (:func:`replay_resampled`)."""


def replay_resampled(
    trials: Sequence[Any],
    make_pruner: Callable[[], Any],
    size: int,
    top: Sequence[int],
    repeats: int = RESAMPLED_REPEATS,
) -> dict[str, Any]:
    """:func:`replay_pruning` on searches of ``size`` trials drawn from these trials' curves with
    replacement, in random order (draw ``k`` seeded ``k``, ``repeats`` draws): an estimate of what pruning
    saves in a search with more trials than were run. Returns the saving (unpruned / pruned env steps)
    per draw, and ``best_kept``: the share of the drawn copies of the ``top`` trials (numbers) that the
    pruner let finish."""
    import random
    from types import SimpleNamespace

    ordered = sorted(trials, key=lambda t: t.number)
    savings, best, kept = [], 0, 0
    for draw in range(repeats):
        rng = random.Random(draw)
        picked = [rng.choice(ordered) for _ in range(size)]
        replay = replay_pruning(
            [SimpleNamespace(number=i, user_attrs=t.user_attrs) for i, t in enumerate(picked)], make_pruner()
        )
        savings.append(replay["env_steps_unpruned"] / max(1, replay["env_steps_pruned"]))
        copies = [i for i, t in enumerate(picked) if t.number in top]
        best, kept = best + len(copies), kept + sum(i in replay["kept"] for i in copies)
    return {"savings": savings, "best_kept": kept / best if best else None}


def open_stages(design: StudyDesign, settings: StudySettings, url: str) -> dict[str, Any]:
    """The study's Optuna studies by stage (a search's and its confirming runs', or a list study's)."""
    stages = (SEARCH, CONFIRM) if design.is_search else (LIST,)
    return {stage: open_stage(design, settings, stage, url) for stage in stages}


def trial_errors(stages: dict[str, Any]) -> list[str]:
    """``KEY: error`` of every trial that failed with an error (surplus trials aside), by stage and trial
    number; ``stages``: :func:`open_stages`'."""
    from optuna.trial import TrialState

    return [
        f"{trial.user_attrs.get('key', trial.number)}: {trial.user_attrs['error']}"
        for study in stages.values()
        for trial in study.get_trials(deepcopy=False)
        if trial.state == TrialState.FAIL
        and "error" in trial.user_attrs
        and not trial.user_attrs.get("surplus")
    ]


def study_status(
    design: StudyDesign, settings: StudySettings, url: str, stages: dict[str, Any] | None = None
) -> dict[str, Any]:
    """How far the study is: per stage, trials finished (complete, pruned), failed with an error, and
    the planned entries (or search trials) still missing. ``stages``: :func:`open_stages`' (opened here
    when not given)."""
    from optuna.trial import TrialState

    def counts(study, planned: int) -> dict[str, int]:
        trials = [t for t in study.get_trials(deepcopy=False) if not t.user_attrs.get("surplus")]
        finished = _finished(study)
        failed = [t for t in trials if t.state == TrialState.FAIL and "error" in t.user_attrs]
        done = {t.user_attrs.get("key", t.number) for t in finished + failed}
        return {
            "finished": len(finished),
            "pruned": sum(t.state == TrialState.PRUNED for t in finished),
            "failed": len(failed),
            "missing": max(0, planned - len(done)),
        }

    stages = stages or open_stages(design, settings, url)
    if not design.is_search:
        planned = len(plan_entries(design, settings, LIST))
        return {"study": design.name, "storage": masked(url), LIST: counts(stages[LIST], planned)}
    search = stages[SEARCH]
    status = {"study": design.name, "storage": masked(url), SEARCH: counts(search, settings.trials)}
    best = best_trials(search, settings.top)
    status[CONFIRM] = counts(stages[CONFIRM], settings.top * len(settings.seeds))
    status["best"] = [{"trial": t.number, "targets_reached": t.value, "params": t.params} for t in best]
    return status


def _table(rows: Sequence[dict[str, Any]], label: str) -> list[str]:
    def pm(mean, std):
        return "–" if mean is None else f"{mean:.2f} ± {std:.2f}"

    lines = [
        f"| {label} | runs (seeds) | targets reached | success rate | env steps per run |",
        "| --- | --- | --- | --- | --- |",
    ]
    for row in rows:
        lines.append(
            f"| {row['group']} | {row['runs']} ({row['seeds']}) "
            f"| {pm(row['targets_mean'], row['targets_std'])} "
            f"| {pm(row['success_mean'], row['success_std'])} | {row['env_steps']:.3g} |"
        )
    return lines


def _figure(path: Path, curves: dict[str, dict[str, np.ndarray]], title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = [label for label in CURVE_SERIES if any(label in curve for curve in curves.values())]
    palette = distinct_colours(len(curves))
    fig, axes = plt.subplots(1, len(panels), figsize=(5.5 * len(panels), 3.6), squeeze=False)
    for ax, label in zip(axes[0], panels, strict=True):
        for index, (name, curve) in enumerate(curves.items()):
            if label in curve:
                values, x, colour = curve[label], curve["steps"] / 1e6, palette[index]
                ax.plot(x, values.mean(axis=0), label=f"{name} ({len(values)})", linewidth=1.2, color=colour)
                ax.fill_between(
                    x,
                    values.mean(0) - values.std(0),
                    values.mean(0) + values.std(0),
                    color=colour,
                    alpha=0.15,
                )
        ax.set_title(CURVE_TITLES[label], fontsize=10)
        ax.set_xlabel("env steps [1e6]")
        ax.grid(alpha=0.3)
        if label == "success":
            ax.set_ylim(-0.02, 1.02)
    axes[0, 0].legend(fontsize=7)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    write_atomic(path, figure_bytes(fig))
    plt.close(fig)


CURVE_TITLES: dict[str, str] = {
    "targets": "targets reached per 60 s episode",
    "success": "success rate (>= 2 targets, no fall)",
    "reward": "episode reward (training)",
}


def _budget_line(design: StudyDesign, settings: StudySettings) -> str:
    ours = f"{settings.budget:.3g} env steps per trial, seeds {', '.join(map(str, settings.seeds))}"
    thesis = f"{design.budget:.3g} env steps per trial, seeds {', '.join(map(str, design.seeds))}"
    if design.is_search:
        ours += f"; {settings.trials} trials, best {settings.top} confirmed for {settings.confirm_budget:.3g}"
        thesis += f"; {design.trials} trials, best {design.top} confirmed for {design.confirm_budget:.3g}"
    return f"Budget: {ours} (the thesis: {thesis})."


def _rows_csv(trials: Sequence[Any], group_of) -> bytes:
    columns = [
        "trial",
        "group",
        "seed",
        "state",
        "targets_reached",
        "success_rate",
        "env_steps",
        "wall_seconds",
    ]
    rows = [
        {
            "trial": t.number,
            "group": group_of(t),
            "seed": t.user_attrs.get("seed"),
            "state": t.state.name,
            **{key: t.user_attrs.get(key) for key in columns[4:]},
        }
        for t in trials
    ]
    return csv_bytes(columns, rows)


def write_study_report(
    design: StudyDesign,
    settings: StudySettings,
    url: str,
    out: Path,
    command: str = "",
    extra: Sequence[str] = (),
) -> dict[str, Any]:
    """Write ``NAME.md``, ``NAME.csv`` and ``NAME.png`` (and a search's ``NAME-search.csv``) into ``out``
    from the finished trials, ``extra`` (Markdown lines) closing ``NAME.md``; returns the files and the
    study's status."""
    stages = open_stages(design, settings, url)
    status = study_status(design, settings, url, stages)
    out.mkdir(parents=True, exist_ok=True)
    lines = [f"# Agent study {design.name} ({design.title})", "", _budget_line(design, settings), ""]
    if command:
        lines += ["Made by:", "", f"    {masked(command)}", ""]
    lines += [f"The thesis: {THESIS_FINDINGS.get(design.name, '')}", ""]
    written = []
    if design.is_search:
        searched = _finished(stages[SEARCH])
        write_atomic(out / f"{design.name}-search.csv", _rows_csv(searched, lambda t: f"trial{t.number}"))
        written.append(str(out / f"{design.name}-search.csv"))
        lines += _search_lines(design, settings, searched, status)
        trials = _finished(stages[CONFIRM])
        group_of = lambda t: f"trial{t.params['candidate']}"  # noqa: E731
        grid = settings.confirm_budget / 25
    else:
        trials = _finished(stages[LIST])
        group_of = lambda t: t.params["variant"]  # noqa: E731
        grid = settings.budget / 25
    missing = status[CONFIRM if design.is_search else LIST]["missing"]
    lines += [f"Runs finished: {len(trials)}; missing: {missing}.", ""]
    lines += _table(group_rows(trials, group_of), "candidate" if design.is_search else "variant")
    write_atomic(out / f"{design.name}.csv", _rows_csv(trials, group_of))
    if trials:
        _figure(
            out / f"{design.name}.png", mean_curves(trials, group_of, grid), f"{design.name} ({design.title})"
        )
        written.append(str(out / f"{design.name}.png"))
        lines += ["", f"![{design.name}]({design.name}.png)"]
    lines += ["", *extra] if extra else []
    write_atomic(out / f"{design.name}.md", "\n".join(lines) + "\n")
    return {
        "written": [str(out / f"{design.name}.md"), str(out / f"{design.name}.csv"), *written],
        "status": status,
    }


def _search_lines(design: StudyDesign, settings: StudySettings, searched, status) -> list[str]:
    """The search's part of the report: its trials, the best ones, and the pruning replay."""

    lines = [
        f"Search trials finished: {status[SEARCH]['finished']} ({status[SEARCH]['pruned']} pruned, "
        f"{status[SEARCH]['failed']} failed); missing: {status[SEARCH]['missing']}.",
        "",
        "| best trial | final targets reached | parameters |",
        "| --- | --- | --- |",
    ]
    for best in status["best"]:
        params = ", ".join(
            f"{k} {v:.3g}" if isinstance(v, float) else f"{k} {v}" for k, v in best["params"].items()
        )
        lines.append(f"| {best['trial']} | {best['targets_reached']:.2f} | {params} |")
    if settings.pruner == "none" and searched:
        lines += ["", "Pruning replayed on these unpruned trials, in trial order, for each `--pruner`:", ""]
        lines += _pruning_table(design, settings, searched, [b["trial"] for b in status["best"]])
    return [*lines, ""]


def _pruning_table(design: StudyDesign, settings: StudySettings, searched, top: list[int]) -> list[str]:
    """Each pruner replayed on the unpruned search; when the design's search is larger than the one run,
    also on searches of the design's size drawn from these trials (:func:`replay_resampled`)."""
    resampled = design.trials > len(searched)
    extra = f" {design.trials} trials drawn from these: cheaper, best kept |" if resampled else ""
    lines = [
        "| pruner | env steps | unpruned | cheaper | best kept |" + extra,
        "| --- | --- | --- | --- | --- |" + (" --- |" if resampled else ""),
    ]
    for name in ("median", "halving"):
        replay = replay_pruning(searched, pruner(name, settings.budget))
        saved = replay["env_steps_unpruned"] / max(1, replay["env_steps_pruned"])
        row = (
            f"| {name} ({pruner_rule(name, settings.budget)}) | {replay['env_steps_pruned']:.3g} | "
            f"{replay['env_steps_unpruned']:.3g} | {saved:.2f}x | "
            f"{sum(t in replay['kept'] for t in top)} of {len(top)} |"
        )
        if resampled:
            drawn = replay_resampled(searched, lambda n=name: pruner(n, settings.budget), design.trials, top)
            savings = drawn["savings"]
            row += (
                f" {statistics.mean(savings):.2f}x ({min(savings):.2f}-{max(savings):.2f}), "
                f"{drawn['best_kept']:.2f} |"
            )
        lines.append(row)
    if resampled:
        lines += [
            "",
            f"The last column replays searches of the thesis's {design.trials} trials made of these trials' "
            f"curves, drawn with replacement in {RESAMPLED_REPEATS} random orders (mean, range over the "
            "draws; best kept: the share of the drawn copies of the best trials left to finish): an "
            "estimate, since a larger search draws new settings, not copies.",
        ]
    return lines
