"""krl bench agent measures the agent it is given: a gait-driving config's action size reaches the
environment, the policy and the training measurement."""

from __future__ import annotations

import json
from dataclasses import replace

from krl.agent.config import AgentConfig, ResidualConfig
from krl.cli import main


def test_bench_agent_runs_a_given_config(tmp_path, capsys):
    config = AgentConfig(num_envs=3)
    gait = replace(
        config,
        residual=ResidualConfig(kernel="ext", drive_heights=True, drive_rhythm=True),
        ppo=replace(config.ppo, batch_size=64, n_epochs=1),  # three rollouts of 64 steps, not of 4000
    )
    path = tmp_path / "gait.json"
    path.write_text(json.dumps(gait.to_json()))
    small = ["--steps", "10", "--repeats", "1", "--train-steps", "1"]
    assert main(["bench", "agent", "--config", str(path), *small, "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert (result["num_envs"], result["action_size"]) == (3, 15)  # the config's robots and action
    assert result["env_steps_per_s"] > 0 and result["train_steps"] > 0
    assert result["update_threads"] == 1
    assert main(["bench", "agent", "--config", str(tmp_path / "missing.json"), *small]) == 2
    assert "missing.json" in capsys.readouterr().err
    assert main(["bench", "agent", "--config", str(path), *small, "--update-threads", "0"]) == 2
    assert "--update-threads must be at least 1, got 0" in capsys.readouterr().err


def test_bench_agent_measures_the_scan_of_an_agent_that_observes_it(tmp_path, capsys):
    config = AgentConfig(num_envs=2)
    observation = replace(
        config.observation,
        features=(*config.observation.features, "height_scan"),
        critic_features=("height_scan_clean", "push_force"),
    )
    scanning = replace(config, observation=observation, ppo=replace(config.ppo, batch_size=64, n_epochs=1))
    path = tmp_path / "scan.json"
    path.write_text(json.dumps(scanning.to_json()))
    small = ["--steps", "10", "--repeats", "1", "--train-steps", "1"]
    assert main(["bench", "agent", "--config", str(path), *small, "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["scan_points"] == 187 and result["env_target_ratio"] == 0.45
    assert set(result["scan_us_per_robot"]) == {
        "heightfield",
        "pyramids",
        "pits",
        "slope",
        "tabletop",
        "seesaw",
    }
    assert all(us > 0 for us in result["scan_us_per_robot"].values())
