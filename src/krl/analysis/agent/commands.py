"""The alternative study's question (``krl agent study alternative --report``): does the reward pay a
command-giving agent for standing still?

The thesis explains the failed runs of its alternative architecture (4.2.8.4: the policy gives the kernel
its velocity command) by "the emphasis on the CoM in the reward function" making zero commands, "where the
robot is most stable", a good strategy. We measure it: fixed policies drive the alternative's environment
(the study's terrain and reward, :data:`FIXED_POLICIES`) through the same action path a trained one would,
and we compare each reward term per step and the targets reached. If ``zero`` earns at least ``follow``'s
reward, the explanation holds: the reward cannot tell a standing robot from a walking one; if ``follow``
earns clearly more, failing runs are stuck in a local optimum rather than led there by the reward.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from krl.agent.config import AgentConfig
from krl.agent.env import ResidualEnvBatch
from krl.agent.residual import ResidualController
from krl.util.output import csv_bytes, write_atomic

FIXED_POLICIES: dict[str, tuple[str, float]] = {
    "follow": ("gives the kernel the task's command", 1.0),
    "half": ("gives the kernel half the task's command", 0.5),
    "zero": ("gives the kernel zero commands (the robot trots in place)", 0.0),
}
"""The fixed command policies: (what it does, the fraction of the task's command it passes on)."""


def command_action(controller: ResidualController, fraction: float) -> np.ndarray:
    """The actions of a command-giving agent that passes on ``fraction`` of the task's command of the
    prepared step (clipped to the kernel's command ranges). Shape: (N, D)."""
    if [p.name for p in controller.parts] != ["command"]:
        raise ValueError("the fixed command policies need an action of the command part alone")
    return controller.parts[0].action(fraction * controller.command)


def fixed_command_runs(
    config: AgentConfig, num_envs: int = 4, seed: int = 0, policies: dict[str, float] | None = None
) -> list[dict[str, Any]]:
    """Each fixed policy for one full episode in each of ``num_envs`` environments (seeds ``seed`` ...):
    ``{"policy", "steps", "reward_per_step", "terms_per_step": {term: value}, "targets_reached",
    "falls"}``, per-step values averaged over every step of every episode."""
    policies = policies or {name: fraction for name, (_, fraction) in FIXED_POLICIES.items()}
    return [
        {"policy": name, **_episodes(config, num_envs, seed, lambda c, f=fraction: command_action(c, f))}
        for name, fraction in policies.items()
    ]


def _episodes(
    config: AgentConfig, num_envs: int, seed: int, act: Callable[[ResidualController], np.ndarray]
) -> dict[str, Any]:
    batch = ResidualEnvBatch(config, num_envs)
    for index in range(num_envs):
        batch.seed(index, seed + index)
    batch.reset(np.arange(num_envs))
    running = np.ones(num_envs, dtype=bool)
    ended: list[dict[str, Any]] = [{} for _ in range(num_envs)]
    while running.any():
        _, _, terminated, truncated, infos = batch.step(act(batch.controller))
        for index in np.flatnonzero((terminated | truncated) & running):
            ended[index] = infos[index]["episode"]
            running[index] = False
    steps = sum(e["l"] for e in ended)
    terms = sorted({name for e in ended for name in e["terms"]})
    return {
        "steps": steps,
        "reward_per_step": sum(e["r"] for e in ended) / steps,
        "terms_per_step": {t: sum(e["terms"].get(t, 0.0) for e in ended) / steps for t in terms},
        "targets_reached": float(np.mean([e["targets_reached"] for e in ended])),
        "falls": sum(e["fell"] for e in ended),
    }


def write_fixed_command_table(runs: list[dict[str, Any]], out: Path, command: str) -> list[str]:
    """Write ``alternative-fixed.csv`` into ``out``; returns the Markdown section for the study report."""
    terms = sorted({t for run in runs for t in run["terms_per_step"]})
    columns = ["policy", "episodes_steps", "reward_per_step", *terms, "targets_reached", "falls"]
    rows = [
        {
            "policy": r["policy"],
            "episodes_steps": r["steps"],
            "reward_per_step": r["reward_per_step"],
            **r["terms_per_step"],
            "targets_reached": r["targets_reached"],
            "falls": r["falls"],
        }
        for r in runs
    ]
    write_atomic(out / "alternative-fixed.csv", csv_bytes(columns, rows))
    lines = [
        "## Does the reward pay for zero commands? (fixed command policies)",
        "",
        "Made by:",
        "",
        f"    {command}",
        "",
        "| policy | what | reward / step | " + " | ".join(terms) + " | targets / episode | falls |",
        "| --- | --- | --- | " + " | ".join("---" for _ in terms) + " | --- | --- |",
    ]
    for r in runs:
        what = FIXED_POLICIES.get(r["policy"], ("", 0.0))[0]
        values = " | ".join(f"{r['terms_per_step'].get(t, 0.0):.5f}" for t in terms)
        lines.append(
            f"| {r['policy']} | {what} | {r['reward_per_step']:.5f} | {values} | "
            f"{r['targets_reached']:.2f} | {r['falls']} |"
        )
    return [*lines, ""]


def alternative_measurement(design, settings, out: Path, command: str) -> list[str]:
    """The alternative study's report sections (:data:`krl.agent.studies.jobs.MeasuredSections`): the fixed
    command policies' rewards, the thesis's explanation of its failed runs, measured; nothing for another
    study."""
    from krl.agent.studies.runner import trial_config

    if design.name != "alternative":
        return []
    (commands,) = [v for v in design.variants if v.name == "commands"]
    config = trial_config(design, settings, commands.overrides, settings.budget)
    out.mkdir(parents=True, exist_ok=True)
    return write_fixed_command_table(fixed_command_runs(config), out, command)
