"""Held-out episodes of the training distribution: how to choose between trained agents without the courses.

The evaluation courses are unseen terrain: they measure a recipe once it is fixed and never choose a
checkpoint, a setting or a seed. What does choose is this: each policy walks fresh episodes of the very
environment it trained in (its own config: terrains, pushes, waypoints, reward, observation noise), from
environment seeds no training ever used (:data:`HELDOUT_SEED` on), with its deterministic action (the
network's mean, as in every evaluation). Environment ``k`` of the ``episodes`` is seeded ``HELDOUT_SEED +
k``, so every policy meets the same terrains, starts, waypoints and push draws.

Per episode: waypoints reached, whether it fell, its length [s] and reward per step; per policy the
training's own metrics over them (targets reached, success rate as :data:`krl.agent.callbacks.SUCCESS_TARGETS`
defines it, fall rate, reward per step); per seed group the mean and sample std of those over its seeds.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from krl.agent.callbacks import SUCCESS_TARGETS
from krl.agent.policy import check_kernel_file, load_policy
from krl.agent.process_vec_env import ProcessVecEnv
from krl.util.hashing import file_sha256
from krl.util.output import csv_bytes, json_value, write_atomic
from krl.util.timing import CONTROL_DT

HELDOUT_SEED: int = 1_000_000_000
"""Seed of the first held-out environment. Training seeds its environments ``seed + i`` and, per resumed
sitting, ``+ 7919 k`` (``krl.agent.train``): below 10^6 for any run here, so never one of these."""

METRICS: tuple[str, ...] = ("targets_reached", "success_rate", "fall_rate", "reward_per_step")
"""The per-policy measures, each a mean over its episodes."""


def heldout_episodes(
    path: Path, episodes: int, workers: int, on_episode: Callable[[], None] = lambda: None
) -> list[dict[str, Any]]:
    """Walk ``episodes`` held-out episodes with the policy file at ``path`` (``workers`` processes), one
    episode per environment; returns one dict per episode, in environment order: ``targets_reached``,
    ``fell``, ``length_s`` [s], ``reward_per_step``, ``terrain``. ``on_episode`` is called as each ends."""
    policy = load_policy(path)
    kernel = check_kernel_file(policy, None, path)
    workers = max(1, min(workers, episodes))
    per_worker = math.ceil(episodes / workers)
    venv = ProcessVecEnv(policy.config, workers, per_worker, HELDOUT_SEED, str(kernel))
    ended: list[dict[str, Any] | None] = [None] * episodes
    try:
        observations = venv.reset()
        while any(episode is None for episode in ended):
            observations, _, dones, infos = venv.step(policy.act(observations))
            for index in np.flatnonzero(dones[:episodes]):
                if ended[index] is None:
                    ended[index] = _episode(infos[index]["episode"])
                    on_episode()
    finally:
        venv.close()
    return [episode for episode in ended if episode is not None]


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
    path: Path, record_path: Path, episodes: int, workers: int, on_episode: Callable[[], None]
) -> dict[str, Any]:
    """The held-out record of one policy file: read from ``record_path`` when it holds this file (by
    SHA-256), episode count and seed, else walked and written there (atomically)."""
    identity = {"policy_sha256": file_sha256(path), "episodes": episodes, "heldout_seed": HELDOUT_SEED}
    if record_path.is_file():
        stored = json.loads(record_path.read_text())
        if all(stored.get(key) == value for key, value in identity.items()):
            for _ in range(episodes):
                on_episode()
            return stored
    walked = heldout_episodes(path, episodes, workers, on_episode)
    record = json_value(
        {"policy": str(path), **identity, "summary": summarise(walked), "episodes_walked": walked}
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


def write_tables(
    rows: list[dict[str, Any]], records: dict[str, list[tuple[int | None, dict[str, Any]]]], out: Path
) -> dict[str, str]:
    """``heldout.csv`` (the group rows) and ``heldout.md`` (them, and every seed's summary) in ``out``."""
    columns = ["label", "seeds", "episodes", *(f"{m}_{s}" for m in METRICS for s in ("mean", "std"))]
    write_atomic(out / "heldout.csv", csv_bytes(columns, rows))
    lines = [
        "# Held-out episodes of the training distribution",
        "",
        f"Each policy walks the same {rows[0]['episodes']} episodes of its own training environment, seeded "
        f"from {HELDOUT_SEED} on (never a training seed), with its deterministic action; mean ± sample std "
        f"over seeds. Success: at least {SUCCESS_TARGETS} waypoints without a fall. Reward/step is each "
        "policy's own training reward: not comparable between policies trained on different rewards.",
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
    write_atomic(out / "heldout.md", "\n".join(lines) + "\n")
    return {"csv": str(out / "heldout.csv"), "md": str(out / "heldout.md")}


def _cells(row: dict[str, Any]) -> str:
    cells = []
    for metric in METRICS:
        mean, std = row[f"{metric}_mean"], row[f"{metric}_std"]
        cells.append(f"{mean:.3g}" if math.isnan(std) else f"{mean:.3g} ± {std:.2g}")
    return " | ".join(cells)
