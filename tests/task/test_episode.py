"""The one episode loop: what training steps and what evaluation scores are the same steps."""

from dataclasses import replace

import numpy as np
import pytest
from agent_fakes import make_policy

from krl.agent.config import AgentConfig
from krl.agent.controller import AgentController
from krl.control.commands import CommandParams
from krl.envs.residual import A1ResidualEnv
from krl.robots.a1.constants import STANDING_JOINT_ANGLES
from krl.sim.backend import make_backend
from krl.sim.batch import SimBatch
from krl.sim.model import build_model
from krl.sim.pushes import OnePush, Push
from krl.sim.robot import A1Sim
from krl.task.episode import EpisodeBatch
from krl.task.reward import EVALUATION_REWARD
from krl.task.runner import HoldTask, Runner

STEPS = 300


class _Enough(Exception):
    """Stops a walk after the steps a test compares."""


def test_an_agent_makes_the_same_steps_in_the_training_environment_and_in_an_evaluation_walk(monkeypatch):
    config = AgentConfig()
    config = replace(config, env=replace(config.env, pushes=False))
    policy = make_policy(config, scale=0.05, seed=1)
    built, resets = [], []
    monkeypatch.setattr("krl.agent.env.build_model", lambda *a: built.append(build_model(*a)) or built[-1])
    reset = SimBatch.reset
    monkeypatch.setattr(SimBatch, "reset", lambda self, *a, **k: resets.append(k) or reset(self, *a, **k))
    env = A1ResidualEnv(config)
    observation, _ = env.reset(seed=7)
    targets = env.batch.episodes.tasks[0].targets
    trained = []
    for _ in range(STEPS):
        observation, _, terminated, truncated, info = env.step(policy.act(observation[None])[0])
        trained.append(info["reward_terms"])
        assert not (terminated or truncated)

    walked = []

    def on_task_step(record, step):
        walked.append({name: float(values[0]) for name, values in step.terms.items()})
        if len(walked) == STEPS:
            raise _Enough

    start = (*built[0].terrain.spawn_xy, resets[-1]["yaw"])
    runner = Runner(A1Sim(built[0]), AgentController(policy), CommandParams(d_min=config.env.d_min))
    assert config.env.reward == EVALUATION_REWARD
    with pytest.raises(_Enough):
        runner.walk_to(targets, None, start_pose=start, time_limit=60.0, on_task_step=on_task_step)
    assert walked == trained  # every reward term of every step, bit for bit


def test_each_robot_of_a_batch_ends_its_own_episode():
    sims = make_backend([build_model("flat")] * 2)
    episodes = EpisodeBatch(sims, EVALUATION_REWARD)
    topple = Push(0.02, np.array([0.0, 900.0, 100.0]), np.zeros(3), duration=0.2, mode="continuous")
    episodes.start(
        [0, 1], [HoldTask(np.zeros(3), 200, 1), HoldTask(np.zeros(3), 200, 1)], [None, OnePush(topple)]
    )
    q = np.tile(STANDING_JOINT_ANGLES, (2, 1))
    first = episodes.step(q)
    assert first.pushes[0] is None and first.pushes[1] is topple
    ends = []
    for k in range(1, 200):
        step = episodes.step(q)
        ends += [(k, index, bool(step.fell[index])) for index in np.flatnonzero(step.ended)]
    (fall_step, fallen, fell), (hold_end, standing, standing_fell) = ends
    assert (fallen, fell, standing, standing_fell, hold_end) == (1, True, 0, False, 199)
    assert 4 <= fall_step < 199 and not episodes.active.any()


def test_a_walk_whose_every_waypoint_is_within_reach_at_the_start_takes_no_step():
    from krl.kernel.controller import KernelController
    from krl.kernel.registry import load_model

    sim = A1Sim(build_model("flat"))
    runner = Runner(sim, KernelController(load_model("base")))
    result = runner.walk_to([[0.2, 0.0], [0.0, 0.3]], start_pose=(0.0, 0.0, 0.0))
    assert result.targets_reached == 2 and sim.step_count == 0 and not result.fell
