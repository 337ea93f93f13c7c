"""``krl bench agent``: the residual environment's and PPO training's throughput against bare MuJoCo.

Measured in one run, on the training height field:

* ``bare_steps_per_s``: one ``MjData`` stepped by ``mj_step(nstep=5)`` (one 200 Hz control step) with
  constant controls holding the standing pose: the floor of a control step on one core.
* ``env_steps_per_s``: a :class:`krl.agent.env.ResidualVecEnv` of ``num_envs`` robots in this process
  (one core) with random actions: everything in the step (kernel, filter, IK, PD and physics, state
  readout, waypoint task, pushes, reward, observation, automatic resets).
* ``env_ratio`` = env / bare (target >= 0.5; >= 0.45 for an agent that observes the height scan).
* ``scan_us_per_robot`` (an agent that observes the height scan): what the scan of the configured grid
  costs per robot and control step (:meth:`krl.sim.batch.SimBatch.terrain_heights` and the values, for
  ``num_envs`` robots at once) on each training tile and on the moving props: the fixed ground is the
  terrain's own height function (a height field's triangles, the boxes' tops), a prop's boxes a slab test
  at their pose; no ray is cast (a Python loop of ``mj_ray`` over 187 points costs a few hundred µs).
* ``policy_us_per_step``: NumPy inference of a policy of the default shape, per robot, in a batch of
  ``num_envs`` and alone.
* ``train_steps_per_s``: PPO training (:func:`krl.agent.train.train`, every core, workers of ``num_envs``
  robots, the default PPO settings with a shorter rollout) over ``train_steps`` env steps in three
  rollouts: the rate of the second and third, each collection and PPO update included, as a long
  training runs (the workers' start and the first rollout are left out), the update on
  ``update_threads`` PyTorch threads (1, as ``krl agent train`` by default; its results depend on it).
  ``train_ratio`` = train / (cores × bare) (target >= 0.3).

The agent is the thesis's agent-rp (:class:`krl.agent.config.AgentConfig`'s defaults) unless a config is
given (a gait-driving variant's run folder's ``config.json``, say): its action size, observation, kernel,
terrains and PPO settings are what the environment and the training measure run.
"""

from __future__ import annotations

import csv
import os
import statistics
import tempfile
import time
import warnings
from dataclasses import replace

import mujoco
import numpy as np
from threadpoolctl import threadpool_limits

from krl.agent.config import AgentConfig
from krl.bench.sim import bare_seconds
from krl.sim.model import build_model

ENV_TARGET_RATIO = 0.5
SCAN_ENV_TARGET_RATIO = 0.45
SCAN_TERRAINS: tuple[str, ...] = ("heightfield", "pyramids", "pits", "slope", "tabletop", "seesaw")
"""The terrains the scan's cost is measured on: the training tiles and the moving props."""
TRAIN_TARGET_RATIO = 0.3


def _env_rate(config, num_envs: int, steps: int) -> float:
    from krl.agent.env import ResidualVecEnv

    env = ResidualVecEnv(config, num_envs, seed=0)
    env.reset()
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, (steps, num_envs, *env.action_space.shape))
    start = time.perf_counter()
    for k in range(steps):
        env.step_async(actions[k])
        env.step_wait()
    return steps * num_envs / (time.perf_counter() - start)


def _policy_times(config, num_envs: int, repeats: int = 200) -> tuple[float, float]:
    from krl.agent.observation import observation_size
    from krl.agent.policy import Policy

    size = observation_size(config.observation.features, config.observation.scan)
    widths = [size, *config.ppo.shared, *config.ppo.actor, config.residual.action_size]
    rng = np.random.default_rng(0)
    layers = [
        (rng.standard_normal((widths[i + 1], widths[i])) * 0.1, np.zeros(widths[i + 1]))
        for i in range(len(widths) - 1)
    ]
    policy = Policy(config, layers, np.zeros(size), np.ones(size), 10.0, 1e-8, {})
    batch, single = rng.standard_normal((num_envs, size)), rng.standard_normal((1, size))
    times = []
    for observation in (batch, single):
        start = time.perf_counter()
        for _ in range(repeats):
            policy.act(observation)
        times.append((time.perf_counter() - start) / repeats / len(observation) * 1e6)
    return times[0], times[1]


def _scan_times(config, num_envs: int, repeats: int = 100) -> dict[str, float]:
    """µs per robot of one scan of ``num_envs`` robots standing on each of :data:`SCAN_TERRAINS`."""
    from krl.agent.sensing import Sensing
    from krl.sim.batch import SimBatch

    sensing = Sensing(config.observation)
    times = {}
    for name in SCAN_TERRAINS:
        sims = SimBatch([build_model(name, seed=0)] * num_envs)
        sensing.scan_values(sims.terrain_heights(sensing.points), sims.states)  # first reads: page faults
        start = time.perf_counter()
        for _ in range(repeats):
            sensing.scan_values(sims.terrain_heights(sensing.points), sims.states)
        times[name] = round((time.perf_counter() - start) / repeats / num_envs * 1e6, 1)
    return times


def bench_agent(
    num_envs: int | None = None,
    steps: int = 300,
    repeats: int = 3,
    train_steps: int = 72_000,
    config: AgentConfig | None = None,
    update_threads: int = 1,
) -> dict:
    """Run the measurements (module docstring); medians of ``repeats`` alternating loops. ``num_envs``:
    robots per process (default: the config's, :data:`krl.agent.config.DEFAULT_NUM_ENVS` for agent-rp);
    ``update_threads``: PyTorch threads of the training's PPO update."""
    from krl.agent.train import train

    config = config or AgentConfig()
    num_envs = num_envs or config.num_envs
    config = replace(config, num_envs=num_envs)
    bare, env = [], []
    with threadpool_limits(1):
        for _ in range(repeats):
            bare.append(steps * 4 / bare_seconds(build_model("heightfield", seed=0), steps * 4))
            env.append(_env_rate(config, num_envs, steps))
        batched_us, single_us = _policy_times(config, num_envs)
        scans = any(name.startswith("height_scan") for name in config.observation.all_features)
        scan_us = _scan_times(config, num_envs) if scans else None
    bare_rate, env_rate = statistics.median(bare), statistics.median(env)
    cores = os.cpu_count() or 1
    rollout = max(config.ppo.batch_size, train_steps // 3)
    train_config = replace(
        config,
        workers=cores,
        total_steps=3 * rollout,
        checkpoint_every=3 * rollout,
        ppo=replace(
            config.ppo,
            rollout_steps=rollout,
            lr_decay_horizon=float(3 * rollout),
            lr_decay_stop=float(3 * rollout),
        ),
    )
    with tempfile.TemporaryDirectory() as folder, warnings.catch_warnings():
        # SB3 warns when a rollout is not a whole number of minibatches; the figures stand either way
        warnings.filterwarnings("ignore", "You have specified a mini-batch size", UserWarning)
        run = os.path.join(folder, "run")
        train(run, train_config, seed=0, progress=False, log=lambda _: None, update_threads=update_threads)
        with open(os.path.join(run, "progress.csv"), newline="") as log:
            logged = list(csv.DictReader(log))  # one row per rollout
        rows = [(float(r["time/total_timesteps"]), float(r["time/wall_seconds"])) for r in logged]
    (first_steps, first_wall), (last_steps, last_wall) = rows[0], rows[-1]
    train_rate = (last_steps - first_steps) / (last_wall - first_wall)
    env_target = SCAN_ENV_TARGET_RATIO if scans else ENV_TARGET_RATIO
    result = {
        "benchmark": "agent",
        "terrain": "heightfield",
        "num_envs": num_envs,
        "action_size": config.residual.action_size,
        "bare_steps_per_s": round(bare_rate, 1),
        "env_steps_per_s": round(env_rate, 1),
        "env_ratio": round(env_rate / bare_rate, 3),
        "env_target_ratio": env_target,
        "policy_us_per_step": {"batched": round(batched_us, 2), "single": round(single_us, 2)},
        "cores": cores,
        "train_steps": int(last_steps),
        "train_steps_per_s": round(train_rate, 1),
        "update_threads": update_threads,
        "train_ratio": round(train_rate / (cores * bare_rate), 3),
        "train_target_ratio": TRAIN_TARGET_RATIO,
        "meets_targets": env_rate / bare_rate >= env_target
        and train_rate / (cores * bare_rate) >= TRAIN_TARGET_RATIO,
        "mujoco": mujoco.__version__,
    }
    if scan_us is not None:
        result["scan_points"] = config.observation.scan.size
        result["scan_us_per_robot"] = scan_us
    return result
