"""The push curriculum (krl.agent.curriculum): its schedule, the env's push verdicts, resumption."""

from __future__ import annotations

import csv
import json
from dataclasses import replace

import numpy as np
import pytest

from krl.agent.config import AgentConfigError, EnvConfig
from krl.agent.curriculum import next_ceiling
from krl.agent.env import ResidualEnvBatch
from krl.agent.train import train

CURRICULUM = EnvConfig(push_magnitude=(100.0, 600.0), push_curriculum=True)


def test_the_ceiling_rises_on_survival_falls_on_falls_and_keeps_its_bounds():
    assert next_ceiling(CURRICULUM, 600.0, 0.95) == 650.0
    assert next_ceiling(CURRICULUM, 700.0, 0.8) == 700.0  # between lower and raise: stays
    assert next_ceiling(CURRICULUM, 700.0, 0.5) == 650.0
    assert next_ceiling(CURRICULUM, 600.0, 0.1) == 600.0  # never below push_magnitude's high
    assert next_ceiling(CURRICULUM, 900.0, 1.0) == 900.0  # nor above push_curriculum_max
    assert next_ceiling(CURRICULUM, 750.0, None) == 750.0  # no push judged: no evidence


def test_a_curriculum_past_the_largest_measured_push_is_refused_in_one_line():
    with pytest.raises(AgentConfigError, match=r"push_curriculum_max must be in \[.* 600, 900\] N") as error:
        EnvConfig(push_magnitude=(100.0, 600.0), push_curriculum=True, push_curriculum_max=1500.0)
    assert "\n" not in str(error.value)
    with pytest.raises(AgentConfigError, match="push_curriculum_max"):
        EnvConfig(push_magnitude=(100.0, 600.0), push_curriculum=True, push_curriculum_max=500.0)
    EnvConfig(push_magnitude=(100.0, 1200.0))  # no curriculum: its maximum is not asked about


def test_a_top_share_outside_zero_to_one_is_refused_in_one_line_and_reaches_the_pushes(small_config):
    for bad in (1.5, -0.2, True, "half"):
        with pytest.raises(AgentConfigError, match="push_top_share must be in") as error:
            EnvConfig(push_top_share=bad)
        assert "\n" not in str(error.value)
    env = replace(small_config.env, push_top_share=0.75)
    assert ResidualEnvBatch(replace(small_config, env=env), 1).pushes.top_share == 0.75
    assert ResidualEnvBatch(small_config, 1).pushes.top_share is None


def test_the_env_judges_every_push_and_draws_up_to_the_ceiling_it_is_given(small_config):
    env = replace(small_config.env, push_interval=(0.05, 0.1), push_magnitude=(100.0, 200.0))
    batch = ResidualEnvBatch(replace(small_config, env=env), 2)
    batch.reset([0, 1])
    verdicts = []
    for step in range(400):
        if step == 200:
            batch.set_push_ceiling(800.0)
        *_, terminated, truncated, infos = batch.step(np.zeros((2, 12)))
        verdicts += [info["push_survived"] for info in infos if "push_survived" in info]
        ended = np.flatnonzero(terminated | truncated)
        if len(ended):
            batch.reset(ended)
    assert len(verdicts) > 10
    magnitudes = [push.magnitude for schedule in batch.push_schedules for push in schedule.pushes]
    assert max(magnitudes) > 200.0 and max(magnitudes) <= 800.0
    assert min(magnitudes) >= 100.0


def test_a_resumed_run_continues_its_curriculum(tmp_path, small_config):
    env = replace(
        small_config.env,
        push_interval=(0.02, 0.05),
        push_magnitude=(50.0, 100.0),
        push_curriculum=True,
        push_curriculum_max=900.0,
        push_curriculum_lower=0.0,
        push_curriculum_raise=0.0,  # every rollout with a judged push raises the ceiling
    )
    config = replace(small_config, env=env)
    out = tmp_path / "run"
    quiet = {"progress": False, "log": lambda _: None}
    train(out, config, seed=2, total_steps=512, **quiet)
    state = json.loads((out / "checkpoints" / "00000000512" / "state.json").read_text())
    assert state["push_ceiling"] == 200.0  # 100 N, raised after each of the two rollouts
    train(out, total_steps=768, **quiet)
    rows = list(csv.DictReader((out / "progress.csv").open()))
    assert [float(row["curriculum/push_ceiling"]) for row in rows] == [200.0]  # continued, not restarted
    assert float(rows[0]["curriculum/pushes"]) > 0
    saved = json.loads((out / "checkpoints" / "00000000768" / "state.json").read_text())
    assert saved["push_ceiling"] == 250.0
