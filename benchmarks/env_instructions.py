"""Instructions per robot-step of the residual environment, for comparing code versions on a noisy machine.

Run under callgrind, which counts instructions whatever else the machine is doing::

    valgrind --tool=callgrind --instr-atstart=no --callgrind-out-file=OUT \
        python benchmarks/env_instructions.py
    callgrind_annotate OUT | head -40

A ``ResidualVecEnv`` of ``--robots`` robots (default config or ``--config FILE``'s, seed 0, uniform random
actions of seed 0, BLAS on one thread) takes ``--warmup`` steps uncounted, then ``--steps`` steps with
callgrind's collection switched on (``callgrind_control -i on``); divide the total by robots × steps.
benchmarks/README.md records the figures.
"""

import argparse
import os
import subprocess
from dataclasses import replace

import numpy as np
from threadpoolctl import threadpool_limits

from krl.agent.config import AgentConfig
from krl.agent.env import ResidualVecEnv


def _collect(on: bool) -> None:
    subprocess.run(
        ["callgrind_control", "-i", "on" if on else "off", str(os.getpid())],
        check=True,
        stdout=subprocess.DEVNULL,
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", type=int, default=16)
    parser.add_argument("--warmup", type=int, default=20)
    parser.add_argument("--steps", type=int, default=40)
    parser.add_argument("--config", help="agent config file (krl agent train --config); default the thesis's")
    args = parser.parse_args()
    config = AgentConfig.load(args.config) if args.config else AgentConfig()
    config = replace(config, num_envs=args.robots)
    with threadpool_limits(1):
        env = ResidualVecEnv(config, args.robots, seed=0)
        env.reset()
        width = env.action_space.shape[0]
        actions = np.random.default_rng(0).uniform(-1, 1, (args.warmup + args.steps, args.robots, width))
        for step, action in enumerate(actions):
            if step == args.warmup:
                _collect(True)
            env.step_async(action)
            env.step_wait()
        _collect(False)
    robot_steps = args.steps * args.robots
    print(f"counted {args.steps} steps of {args.robots} robots: divide callgrind's total by {robot_steps}")


if __name__ == "__main__":
    main()
