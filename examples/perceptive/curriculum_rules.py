"""The terrain curriculum's two demotion rules side by side (docs/agent-perceptive.md, "The curriculum's
amendment"): agent-robust's seed 150 walks the blind-curriculum environment (16 robots, the same seed under
both rules), and every sixth of the way the robots' levels, the ended episodes, those a push ended and their
mean waypoints are printed.

    python examples/perceptive/curriculum_rules.py amended 24000
    python examples/perceptive/curriculum_rules.py first 24000

``first``: the rule as first registered, where a fall a push caused demotes too.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import krl.agent.env as env_module
from krl.agent.config import AgentConfig
from krl.agent.env import ResidualVecEnv
from krl.agent.policy import load_policy

ROOT = Path(__file__).resolve().parents[2]


def main(rule: str, steps: int) -> None:
    if rule not in ("amended", "first"):
        raise SystemExit(f"rule must be 'amended' or 'first', not {rule!r}")
    if rule == "first":
        amended = env_module.next_level
        env_module.next_level = lambda curriculum, level, targets, pushed_off, rng: amended(
            curriculum, level, targets, False, rng
        )
    config = AgentConfig.load(ROOT / "examples/perceptive/blind-curriculum.json")
    policy = load_policy(ROOT / "src/krl/agent/policies/agent-robust/seed150.npz")
    env = ResidualVecEnv(config, 16, seed=7)
    observations = env.reset()
    episodes = pushed_off = 0
    targets: list[int] = []
    for step in range(steps):
        observations, _, dones, infos = env.step(policy.act(observations))
        for index in np.flatnonzero(dones):
            episodes += 1
            targets.append(infos[index]["episode"]["targets_reached"])
            pushed_off += infos[index].get("push_survived") is False
        if (step + 1) % max(steps // 6, 1) == 0:
            levels = sorted(int(level) for level in env.terrain_levels())
            mean = round(float(np.mean(targets)), 2) if targets else None
            print(
                f"{rule} step {step + 1}: levels {levels} (mean {np.mean(levels):.2f}), episodes {episodes}, "
                f"pushed off {pushed_off}, waypoints an episode {mean}",
                flush=True,
            )


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]))
