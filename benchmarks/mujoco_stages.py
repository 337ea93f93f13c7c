"""Where MuJoCo's own time goes inside the residual environment, from MuJoCo's built-in profiler timers.

    python benchmarks/mujoco_stages.py [--robots 16] [--warmup 200] [--steps 400]

A ``ResidualVecEnv`` of ``--robots`` robots (default config, seed 0, BLAS on one thread) driven by the shipped
agent-rp, so the robots walk as they do late in training, takes ``--warmup`` control steps, then ``--steps``
more over which each robot's ``MjData.timer`` durations are summed. Prints JSON: the wall time per robot-step
of the whole env step (policy included) [µs], each MuJoCo stage's time per robot-step [µs] (a control step is
5 physics steps; stages nest: ``step`` ⊃ ``forward`` ⊃ ``position`` ⊃ ``pos_collision`` ⊃ ``col_narrow``),
and the mean number of contacts and constraint rows. benchmarks/README.md records the figures.
"""

import argparse
import json
import time

import mujoco
import numpy as np
from threadpoolctl import threadpool_limits

from krl.agent.config import AgentConfig
from krl.agent.env import ResidualVecEnv
from krl.agent.policy import load_policy, shipped_policy_dir

STAGES = [name for name in dir(mujoco.mjtTimer) if name.startswith("mjTIMER_")]


def _timers(datas) -> dict[str, float]:
    """Each stage's time summed over ``datas`` [s] (MuJoCo's timers count seconds)."""
    return {
        name: sum(data.timer[int(getattr(mujoco.mjtTimer, name))].duration for data in datas)
        for name in STAGES
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", type=int, default=16)
    parser.add_argument("--warmup", type=int, default=200)
    parser.add_argument("--steps", type=int, default=400)
    args = parser.parse_args()
    with threadpool_limits(1):
        env = ResidualVecEnv(AgentConfig(num_envs=args.robots), args.robots, seed=0)
        policy = load_policy(shipped_policy_dir() / "agent-rp.npz")
        observations = env.reset()
        for _ in range(args.warmup):
            env.step_async(policy.act(observations))
            observations = env.step_wait()[0]
        datas = [env.batch.sims.data(index) for index in range(args.robots)]
        before = _timers(datas)
        contacts, rows, wall = [], [], 0.0
        for _ in range(args.steps):
            start = time.perf_counter()
            env.step_async(policy.act(observations))
            observations = env.step_wait()[0]
            wall += time.perf_counter() - start  # the env step alone, not the counting below
            contacts.append(np.mean([data.ncon for data in datas]))
            rows.append(np.mean([data.nefc for data in datas]))
    robot_steps = args.steps * args.robots
    after = _timers(datas)
    stages = {
        name.removeprefix("mjTIMER_").lower(): round(1e6 * (after[name] - before[name]) / robot_steps, 1)
        for name in STAGES
        if after[name] - before[name] >= 0.05e-6 * robot_steps
    }
    print(
        json.dumps(
            {
                "robots": args.robots,
                "steps": args.steps,
                "env_step_us_per_robot_step": round(1e6 * wall / robot_steps, 1),
                "mujoco_us_per_robot_step": dict(sorted(stages.items(), key=lambda item: -item[1])),
                "contacts": float(np.mean(contacts)),
                "constraint_rows": float(np.mean(rows)),
            },
            indent=2,
        )
    )


if __name__ == "__main__":
    main()
