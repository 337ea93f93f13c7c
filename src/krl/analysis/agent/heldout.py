"""Held-out episodes of the training distribution: how to choose between trained agents without the courses.

The evaluation courses are unseen terrain: they measure a recipe once it is fixed and never choose a
checkpoint, a setting or a seed. What does choose is this: each policy walks fresh episodes of the very
environment it trained in (its own config: terrains, pushes, waypoints, reward, observation noise), from
environment seeds no training ever used (:data:`HELDOUT_SEED` on), with its deterministic action (the
network's mean, as in every evaluation). Environment ``k`` of the ``episodes`` is seeded ``HELDOUT_SEED +
k``, so every policy meets the same terrains, starts, waypoints and push draws. Episodes are walked
:data:`HELDOUT_BATCH` at a time (each batch's environments built together), at most :data:`MAX_EPISODES`.

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

from krl.agent.action import DRIVE_PARTS, SATURATED, ActionPart, action_parts
from krl.agent.callbacks import SUCCESS_TARGETS
from krl.agent.config import AgentConfig, EnvConfig
from krl.agent.policy import RECIPE_FIELDS, check_kernel_file, load_policy
from krl.agent.process_vec_env import ProcessVecEnv
from krl.analysis.agent.heldout_request import HELDOUT_BATCH, MAX_EPISODES
from krl.kernel.model import load_kernel
from krl.util.hashing import file_sha256
from krl.util.output import json_value, write_atomic
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
    episode per environment, in batches of :data:`HELDOUT_BATCH`, in the policy's own training environment
    or in ``env``. Returns one dict per episode, in environment order (``targets_reached``, ``fell``,
    ``length_s`` [s], ``reward_per_step``, ``terrain``), and the policy's :func:`drive_usage` over every step
    of them (empty for a policy that drives nothing). ``on_episode`` is called as each episode ends.

    Raises:
        ValueError: ``episodes`` is not in [1, :data:`MAX_EPISODES`].
    """
    if not 1 <= episodes <= MAX_EPISODES:
        raise ValueError(f"held-out episodes must be 1 to at most {MAX_EPISODES}, got {episodes}")
    policy = load_policy(path)
    kernel = check_kernel_file(policy, None, path)
    parts = action_parts(policy.config.residual, load_kernel(kernel))
    config = policy.config if env is None else dataclasses.replace(policy.config, env=env)
    walk = _BatchWalk(policy, config, str(kernel), parts, on_episode)
    walked: list[dict[str, Any]] = []
    for first in range(0, episodes, HELDOUT_BATCH):
        walked += walk(first, min(HELDOUT_BATCH, episodes - first), workers)
    driven = tuple(part for part in parts if part.name in DRIVE_PARTS)
    usage = drive_usage(driven, np.concatenate(walk.asked)) if driven else {}
    return walked, usage


class _BatchWalk:
    """Walks batches of held-out episodes of one policy, keeping what its drives asked for (the driven
    parts' columns of its actions, every step of every unfinished episode) in :attr:`asked`."""

    def __init__(self, policy, config: AgentConfig, kernel: str, parts, on_episode: Callable[[], None]):
        self.policy, self.config, self.kernel, self.on_episode = policy, config, kernel, on_episode
        starts = np.cumsum([0, *(part.size for part in parts)])
        self.columns = [
            column
            for part, start in zip(parts, starts, strict=False)
            if part.name in DRIVE_PARTS
            for column in range(start, start + part.size)
        ]
        self.asked: list[np.ndarray] = []

    def __call__(self, first: int, episodes: int, workers: int) -> list[dict[str, Any]]:
        """Episodes ``first`` to ``first + episodes - 1`` (environment ``k`` seeded ``HELDOUT_SEED + k``),
        on ``workers`` processes (at most one per episode)."""
        workers = max(1, min(workers, episodes))
        per_worker = math.ceil(episodes / workers)
        # the kernel and the policy row by row: an episode's outcome does not depend on the batch it is in
        venv = ProcessVecEnv(
            self.config, workers, per_worker, HELDOUT_SEED + first, self.kernel, rowwise=True
        )
        ended: list[dict[str, Any] | None] = [None] * episodes
        try:
            observations = venv.reset()
            while any(episode is None for episode in ended):
                actions = self.policy.act(observations, rowwise=True)
                if self.columns:
                    running = [index for index in range(episodes) if ended[index] is None]
                    self.asked.append(actions[running][:, self.columns])
                observations, _, dones, infos = venv.step(actions)
                for index in np.flatnonzero(dones[:episodes]):
                    if ended[index] is None:
                        ended[index] = _episode(infos[index]["episode"])
                        self.on_episode()
        finally:
            venv.close()
        return [episode for episode in ended if episode is not None]


DRIVE_STATISTICS: tuple[str, ...] = ("mean", "p5", "p95", "at_low", "at_high")
"""What :func:`drive_usage` measures of each driven number, in table order."""


def drive_usage(parts: tuple[ActionPart, ...], actions: np.ndarray) -> dict[str, dict[str, float]]:
    """How a policy used each driven number, from its actions over every step walked (before the drive
    filter: what the policy asked for). Per number of each drive part (``heights.step_height``,
    ``clock_rate.rate``, …: the part's name and :attr:`krl.agent.action.ActionPart.labels`): the mean and
    the 5th and 95th percentiles of its value in the part's unit, and the fractions of steps at its low and
    its high bound (:data:`krl.agent.action.SATURATED`).

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
