"""Held-out episodes of the training distribution: how to choose between trained agents without the courses.

The evaluation courses are unseen terrain: they measure a recipe once it is fixed and never choose a
checkpoint, a setting or a seed. What does choose is this: each policy walks fresh episodes of the very
environment it trained in (its own config: terrains, pushes, waypoints, reward, observation noise), from
environment seeds no training ever used (:data:`HELDOUT_SEED` on), with its deterministic action (the
network's mean, as in every evaluation). Environment ``k`` of the ``episodes`` is seeded ``HELDOUT_SEED +
k``, so every policy meets the same terrains, starts, waypoints and push draws.

To compare recipes trained on different grounds, every policy can walk the episodes of one given
environment instead (``env``: a config's :class:`krl.agent.config.EnvConfig`; its terrains, pushes,
waypoints and reward), still from the held-out seeds.

Per episode: waypoints reached, whether it fell, its length [s] and reward per step; per policy the
training's own metrics over them (targets reached, success rate as :data:`krl.agent.callbacks.SUCCESS_TARGETS`
defines it, fall rate, reward per step); per seed group the mean and sample std of those over its seeds.
A policy that drives the gait (:mod:`krl.agent.action`) also gets how it used each driven number over
every step of its episodes (:func:`drive_usage`): where its values lay and how often the policy asked for
a bound, the sign that the bound, not the policy, limits what the drive can do.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from krl.agent.action import DRIVE_PARTS, ActionPart, action_parts
from krl.agent.callbacks import SUCCESS_TARGETS
from krl.agent.config import AgentConfig, EnvConfig
from krl.agent.policy import RECIPE_FIELDS, check_kernel_file, load_policy
from krl.agent.process_vec_env import ProcessVecEnv
from krl.kernel.model import load_kernel
from krl.util.hashing import file_sha256
from krl.util.output import csv_bytes, json_value, write_atomic
from krl.util.timing import CONTROL_DT

HELDOUT_SEED: int = 1_000_000_000
"""Seed of the first held-out environment. Training seeds its environments ``seed + i`` and, per resumed
sitting, ``+ 7919 k`` (``krl.agent.train``): below 10^6 for any run here, so never one of these."""

METRICS: tuple[str, ...] = ("targets_reached", "success_rate", "fall_rate", "reward_per_step")
"""The per-policy measures, each a mean over its episodes."""


def heldout_episodes(
    path: Path,
    episodes: int,
    workers: int,
    on_episode: Callable[[], None] = lambda: None,
    env: EnvConfig | None = None,
) -> tuple[list[dict[str, Any]], dict[str, dict[str, float]]]:
    """Walk ``episodes`` held-out episodes with the policy file at ``path`` (``workers`` processes), one
    episode per environment, in the policy's own training environment or in ``env``. Returns one dict per
    episode, in environment order (``targets_reached``, ``fell``, ``length_s`` [s], ``reward_per_step``,
    ``terrain``), and the policy's :func:`drive_usage` over every step of them (empty for a policy that
    drives nothing). ``on_episode`` is called as each episode ends."""
    policy = load_policy(path)
    kernel = check_kernel_file(policy, None, path)
    parts = action_parts(policy.config.residual, load_kernel(kernel))
    drives = any(part.name in DRIVE_PARTS for part in parts)
    workers = max(1, min(workers, episodes))
    per_worker = math.ceil(episodes / workers)
    config = policy.config if env is None else dataclasses.replace(policy.config, env=env)
    venv = ProcessVecEnv(config, workers, per_worker, HELDOUT_SEED, str(kernel))
    ended: list[dict[str, Any] | None] = [None] * episodes
    asked: list[np.ndarray] = []
    try:
        observations = venv.reset()
        while any(episode is None for episode in ended):
            actions = policy.act(observations)
            if drives:
                asked.append(actions[[index for index in range(episodes) if ended[index] is None]])
            observations, _, dones, infos = venv.step(actions)
            for index in np.flatnonzero(dones[:episodes]):
                if ended[index] is None:
                    ended[index] = _episode(infos[index]["episode"])
                    on_episode()
    finally:
        venv.close()
    usage = drive_usage(parts, np.concatenate(asked)) if drives else {}
    return [episode for episode in ended if episode is not None], usage


SATURATED: float = 0.99
"""An action number at or beyond ±this asks for its bound (actions are clipped to ±1)."""

DRIVE_STATISTICS: tuple[str, ...] = ("mean", "p5", "p95", "at_low", "at_high")
"""What :func:`drive_usage` measures of each driven number, in table order."""


def drive_usage(parts: tuple[ActionPart, ...], actions: np.ndarray) -> dict[str, dict[str, float]]:
    """How a policy used each driven number, from its actions over every step walked (before the drive
    filter: what the policy asked for). Per number of each drive part (``heights.step_height``,
    ``clock_rate.rate``, …: the part's name and :attr:`krl.agent.action.ActionPart.labels`): the mean and
    the 5th and 95th percentiles of its value in the part's unit, and the fractions of steps at its low and
    its high bound (:data:`SATURATED`).

    Args:
        parts: the action's parts, in order (:func:`krl.agent.action.action_parts`).
        actions: the policy's actions. Shape: (steps, action size).
    """
    usage: dict[str, dict[str, float]] = {}
    start = 0
    for part in parts:
        numbers = np.clip(actions[:, start : start + part.size], -1.0, 1.0)
        start += part.size
        if part.name not in DRIVE_PARTS:
            continue
        values = part.value(numbers)
        for column, label in enumerate(part.labels):
            usage[f"{part.name}.{label}"] = {
                "mean": float(np.mean(values[:, column])),
                "p5": float(np.percentile(values[:, column], 5)),
                "p95": float(np.percentile(values[:, column], 95)),
                "at_low": float(np.mean(numbers[:, column] <= -SATURATED)),
                "at_high": float(np.mean(numbers[:, column] >= SATURATED)),
            }
    return usage


def _episode(info: dict[str, Any]) -> dict[str, Any]:
    return {
        "targets_reached": int(info["targets_reached"]),
        "fell": bool(info["fell"]),
        "length_s": info["l"] * CONTROL_DT,
        "reward_per_step": info["r"] / max(info["l"], 1),
        "terrain": info["terrain"],
    }


def summarise(episodes: list[dict[str, Any]]) -> dict[str, float]:
    """The training's metrics over ``episodes``: means of waypoints reached, success (at least
    ``SUCCESS_TARGETS`` waypoints, no fall), fall, and reward per step."""
    return {
        "targets_reached": float(np.mean([e["targets_reached"] for e in episodes])),
        "success_rate": float(
            np.mean([e["targets_reached"] >= SUCCESS_TARGETS and not e["fell"] for e in episodes])
        ),
        "fall_rate": float(np.mean([e["fell"] for e in episodes])),
        "reward_per_step": float(np.mean([e["reward_per_step"] for e in episodes])),
    }


def policy_record(
    path: Path,
    record_path: Path,
    episodes: int,
    workers: int,
    on_episode: Callable[[], None],
    env: EnvConfig | None = None,
) -> dict[str, Any]:
    """The held-out record of one policy file: read from ``record_path`` when it holds this file (by
    SHA-256), episode count, seed and environment (``env``, None: the policy's own), else walked and
    written there (atomically)."""
    identity = {"policy_sha256": file_sha256(path), "episodes": episodes, "heldout_seed": HELDOUT_SEED}
    if env is not None:  # absent for the policy's own environment, as in records made before the option
        identity["env"] = json.loads(json.dumps(AgentConfig(env=env).to_json()["env"]))
    if record_path.is_file():
        stored = json.loads(record_path.read_text())
        if all(stored.get(key) == identity.get(key) for key in {*identity, "env"}):
            for _ in range(episodes):
                on_episode()
            return stored
    walked, usage = heldout_episodes(path, episodes, workers, on_episode, env)
    record = json_value(
        {
            "policy": str(path),
            **identity,
            "summary": summarise(walked),
            "drive_usage": usage,
            "episodes_walked": walked,
        }
    )
    write_atomic(record_path, json.dumps(record, indent=1) + "\n")
    return record  # as stored (rounded), so that a rerun reading it reports the same


def group_rows(records: dict[str, list[tuple[int | None, dict[str, Any]]]]) -> list[dict[str, Any]]:
    """One row per label: its seeds, episodes per seed, and per metric the mean and sample std over the
    seeds' summaries (std empty for one seed)."""
    rows = []
    for label, members in records.items():
        row: dict[str, Any] = {
            "label": label,
            "seeds": " ".join("-" if seed is None else str(seed) for seed, _ in members),
            "episodes": members[0][1]["episodes"],
        }
        for metric in METRICS:
            values = [record["summary"][metric] for _, record in members]
            row[f"{metric}_mean"] = float(np.mean(values))
            row[f"{metric}_std"] = float(np.std(values, ddof=1)) if len(values) > 1 else float("nan")
        rows.append(row)
    return rows


def check_candidates(labels: list[str], candidates: list[str]) -> None:
    """Raise ``ValueError`` unless ``candidates`` are distinct labels among ``labels``."""
    for label in candidates:
        if label not in labels:
            raise ValueError(f"--choose {label!r} is no --policy label (labels: {', '.join(labels)})")
    if len(set(candidates)) != len(candidates):
        raise ValueError(f"--choose names a label twice: {','.join(candidates)}")


def choose(rows: list[dict[str, Any]], candidates: list[str]) -> dict[str, Any]:
    """Choose one of ``candidates`` (labels of ``rows``, :func:`group_rows`) by their held-out episodes:
    the highest mean success rate wins; candidates within one episode of it (``1 / episodes``, a
    seed's rate moved by one episode) count as tied, and of those the most targets reached wins (then
    the first given). Returns ``chosen``, ``tied`` (in the order given), ``best_success_rate`` and
    ``tolerance``.

    Raises:
        ValueError: from :func:`check_candidates`.
    """
    by_label = {row["label"]: row for row in rows}
    check_candidates(list(by_label), candidates)
    tolerance = 1.0 / max(by_label[label]["episodes"] for label in candidates)
    best = max(by_label[label]["success_rate_mean"] for label in candidates)
    tied = [
        label
        for label in candidates
        if by_label[label]["success_rate_mean"] >= best - tolerance - 1e-12  # rates are k / episodes
    ]
    chosen = max(tied, key=lambda label: (by_label[label]["targets_reached_mean"], -tied.index(label)))
    return {"chosen": chosen, "tied": tied, "best_success_rate": best, "tolerance": tolerance}


def against_baseline(
    rows: list[dict[str, Any]], chosen: str, baseline: str, must_beat: bool
) -> dict[str, Any]:
    """How ``chosen`` stands against ``baseline`` (labels of ``rows``, :func:`group_rows`) on those episodes:
    ``margin``, its mean success rate minus the baseline's; ``tolerance``, one episode (``1 / episodes``);
    ``holds``: the margin exceeds the tolerance where ``must_beat`` (better here), else it is not below
    minus the tolerance (no worse here)."""
    by_label = {row["label"]: row for row in rows}
    margin = by_label[chosen]["success_rate_mean"] - by_label[baseline]["success_rate_mean"]
    tolerance = 1.0 / max(by_label[label]["episodes"] for label in (chosen, baseline))
    # rates are k / episodes: a margin of exactly one episode must compare as one episode
    holds = margin > tolerance + 1e-12 if must_beat else margin >= -tolerance - 1e-12
    return {"margin": margin, "tolerance": tolerance, "must_beat": must_beat, "holds": bool(holds)}


def write_choice(choice: dict[str, Any], files: list[tuple[int | None, Path]], out: Path) -> dict[str, str]:
    """Write the chosen recipe: ``choice.json`` (:func:`choose`'s answer and the chosen group's policy
    files) and ``chosen-config.json``, the config its first policy was trained with, for
    ``krl agent train --config`` to train more seeds of it.

    Raises:
        ValueError: the chosen policies differ in a recipe setting (:data:`krl.agent.policy.RECIPE_FIELDS`;
            a seed group is refused earlier for it).
    """
    configs = [load_policy(path).config.to_json() for _, path in files]
    recipes = [{key: config[key] for key in RECIPE_FIELDS} for config in configs]
    if any(recipe != recipes[0] for recipe in recipes[1:]):
        raise ValueError(f"the policies of {choice['chosen']!r} were trained with different recipes")
    config_path = out / "chosen-config.json"
    write_atomic(config_path, json.dumps(configs[0], indent=1) + "\n")
    record = {**choice, "policies": [str(path) for _, path in files], "config": str(config_path)}
    write_atomic(out / "choice.json", json.dumps(json_value(record), indent=1) + "\n")
    return {"choice": str(out / "choice.json"), "chosen_config": str(config_path)}


def write_verdict(choice: dict[str, Any], out: Path) -> str:
    """Write ``choice.json`` for a choice that does not stand against its baseline (:func:`against_baseline`):
    nothing to train from, so a ``chosen-config.json`` an earlier run of the command left in ``out`` goes.
    Returns the path written."""
    (out / "chosen-config.json").unlink(missing_ok=True)
    write_atomic(out / "choice.json", json.dumps(json_value(choice), indent=1) + "\n")
    return str(out / "choice.json")


def write_tables(
    rows: list[dict[str, Any]],
    records: dict[str, list[tuple[int | None, dict[str, Any]]]],
    out: Path,
    choice: dict[str, Any] | None = None,
    ground: str | None = None,
) -> dict[str, str]:
    """``heldout.csv`` (the group rows) and ``heldout.md`` (them, every seed's summary and ``choice``,
    :func:`choose`'s answer, when given) in ``out``; ``ground`` names the config file whose environment
    every policy walked (None: each its own)."""
    columns = ["label", "seeds", "episodes", *(f"{m}_{s}" for m in METRICS for s in ("mean", "std"))]
    write_atomic(out / "heldout.csv", csv_bytes(columns, rows))
    where, reward = (
        (
            "its own training environment",
            "each policy's own training reward: not comparable between policies trained on different rewards",
        )
        if ground is None
        else (f"the environment of `{ground}`", "that environment's reward")
    )
    lines = [
        "# Held-out episodes of the training distribution",
        "",
        f"Each policy walks the same {rows[0]['episodes']} episodes of {where}, seeded from {HELDOUT_SEED} "
        "on (never a training seed), with its deterministic action; mean ± sample std over seeds. Success: "
        f"at least {SUCCESS_TARGETS} waypoints without a fall. Reward/step is {reward}.",
        "",
        "| policy | seeds | targets reached | success rate | fall rate | reward/step |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    lines += [f"| {row['label']} | {row['seeds']} | {_cells(row)} |" for row in rows]
    lines += [
        "",
        "By seed:",
        "",
        "| policy | seed | targets reached | success rate | fall rate | reward/step |",
    ]
    lines += ["| --- | --- | --- | --- | --- | --- |"]
    for label, members in records.items():
        for seed, record in members:
            summary = record["summary"]
            cells = " | ".join(f"{summary[m]:.3g}" for m in METRICS)
            lines.append(f"| {label} | {'-' if seed is None else seed} | {cells} |")
    written = {"csv": str(out / "heldout.csv"), "md": str(out / "heldout.md")}
    drives = drive_rows(records)
    if drives:
        write_atomic(out / "heldout-drives.csv", csv_bytes(list(drives[0]), drives))
        written["drives_csv"] = str(out / "heldout-drives.csv")
        lines += ["", *_drive_lines(drives)]
    if choice is not None:
        lines += ["", *_choice_lines(choice)]
    write_atomic(out / "heldout.md", "\n".join(lines) + "\n")
    return written


def drive_rows(records: dict[str, list[tuple[int | None, dict[str, Any]]]]) -> list[dict[str, Any]]:
    """One row per label and driven number (:func:`drive_usage`), each statistic the mean over the
    label's seeds; none for labels that drive nothing (or records written before drives were counted)."""
    rows = []
    for label, members in records.items():
        usages = [record.get("drive_usage") or {} for _, record in members]
        for drive in usages[0]:
            row: dict[str, Any] = {"label": label, "drive": drive}
            for statistic in DRIVE_STATISTICS:
                row[statistic] = float(np.mean([usage[drive][statistic] for usage in usages]))
            rows.append(row)
    return rows


def _drive_lines(rows: list[dict[str, Any]]) -> list[str]:
    lines = [
        "How the gait-driving policies used their drives: what each asked for (before the drive filter) "
        f"over every step of the held-out episodes, mean over seeds; at a bound: the share of steps whose "
        f"action was at ±{SATURATED} or beyond.",
        "",
        "| policy | drive | mean | 5 % | 95 % | at low bound | at high bound |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    for row in rows:
        cells = " | ".join(f"{row[s]:.3g}" for s in DRIVE_STATISTICS)
        lines.append(f"| {row['label']} | {row['drive']} | {cells} |")
    return lines


def _choice_lines(choice: dict[str, Any]) -> list[str]:
    others = [label for label in choice["tied"] if label != choice["chosen"]]
    tie = (
        f"tied within {choice['tolerance']:.3g} with {', '.join(others)}; the most targets reached wins"
        if others
        else "no other candidate within one episode of it"
    )
    lines = [
        f"Chosen: **{choice['chosen']}**, the highest held-out success rate "
        f"({choice['best_success_rate']:.3g}) of the candidates, {tie} "
        "(`krl.analysis.agent.heldout.choose`).",
    ]
    baseline = choice.get("baseline")
    if baseline:
        for where, check in baseline["checks"].items():
            need = "better than" if check["must_beat"] else "no worse than"
            verdict = "holds" if check["holds"] else "does not hold"
            lines.append(
                f"- {need} {baseline['label']} on {where}: success {check['margin']:+.3g} against it, "
                f"one episode {check['tolerance']:.3g}: {verdict}."
            )
        lines.append(
            f"The choice **{'stands' if baseline['stands'] else 'does not stand'}** against "
            f"{baseline['label']} (`krl.analysis.agent.heldout.against_baseline`)."
        )
    return lines


def _cells(row: dict[str, Any]) -> str:
    cells = []
    for metric in METRICS:
        mean, std = row[f"{metric}_mean"], row[f"{metric}_std"]
        cells.append(f"{mean:.3g}" if math.isnan(std) else f"{mean:.3g} ± {std:.2g}")
    return " | ".join(cells)
