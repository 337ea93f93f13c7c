"""``krl agent run|info|curves`` and ``krl evaluate --controller agent:PATH`` end to end (smoke-sized)."""

from __future__ import annotations

import json
from dataclasses import replace

import pytest
from agent_fakes import make_policy
from eval_fakes import short_flat

from krl.agent.config import AgentConfig
from krl.agent.policy import load_policy, one_policy
from krl.cli import main


def test_agent_run_and_info_with_a_policy_file(tmp_path, capsys):
    path = make_policy(AgentConfig()).save(tmp_path / "agent-zero.npz")
    assert main(["agent", "run", "--policy", str(path), "--target", "1.0,0.0", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["targets_reached"] == 1 and not summary["fell"]
    assert main(["agent", "info", "--policy", str(path), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert [row["name"] for row in info["observation"]][:2] == ["base_lin_vel", "base_ang_vel"]
    assert info["observation"][-1] == {"name": "foot_contact", "slice": "50:54", "unit": "1"}
    assert info["policy"] == str(path)


def test_a_shipped_policy_is_named_the_same_on_every_machine(capsys):
    assert main(["agent", "info", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["policy"] == "krl/agent/policies/agent-rp/seed150.npz"


@pytest.mark.parametrize(
    "name, file",
    [
        ("rp", "agent-rp/seed150.npz"),
        ("rp@215", "agent-rp/seed215.npz"),
        ("base", "agent-base/seed150.npz"),
        ("base@215", "agent-base/seed215.npz"),
    ],
)
def test_each_shipped_agent_was_trained_with_its_own_reward(name, file, capsys):
    assert main(["agent", "info", "--policy", name, "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["policy"] == f"krl/agent/policies/{file}"
    assert info["reward"] == name.partition("@")[0] and info["kernel"] == "base"
    assert info["training"]["env_steps"] >= 20_000_000


def shipped_gait_agent_info(name: str, seed: int, capsys) -> dict:
    """``krl agent info --json`` of a shipped gait-driving agent's seed, after checking what every one of
    them shares: its file, the thesis's reward, kernel-ext, its seed and a budget of 2e7 env steps."""
    assert main(["agent", "info", "--policy", f"{name}@{seed}", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["policy"] == f"krl/agent/policies/agent-{name}/seed{seed}.npz"
    assert (info["reward"], info["kernel"], info["training"]["seed"]) == ("rp", "ext", seed)
    assert info["training"]["env_steps"] >= 20_000_000
    return info


@pytest.mark.parametrize("seed", [150, 215, 345, 556])
def test_shipped_agent_gait_drives_the_gait_of_kernel_ext(seed, capsys):
    """agent-gait (docs/agent-gait.md): the thesis's reward, on kernel-ext, residuals and three drives."""
    info = shipped_gait_agent_info("gait", seed, capsys)
    assert [(part["name"], part["slice"]) for part in info["action"]] == [
        ("residual", "0:12"),
        ("steer", "12:15"),
        ("heights", "15:17"),
        ("clock_rate", "17:18"),
    ]


@pytest.mark.parametrize("seed", [150, 215, 345, 556])
def test_shipped_agent_gait_ground_is_agent_gaits_recipe_on_pyramids_and_stronger_pushes(seed, capsys):
    """agent-gait-ground (docs/agent-gait.md): agent-gait's config but for its ground and training pushes."""
    shipped_gait_agent_info("gait-ground", seed, capsys)
    gait, ground = (load_policy(one_policy(f"{name}@{seed}")[1]).config for name in ("gait", "gait-ground"))
    fields = ("heightfield_probability", "pyramids_probability", "pyramids_step_height", "push_magnitude")
    assert [getattr(ground.env, name) for name in fields] == [0.5, 0.25, (0.04, 0.08), (100.0, 600.0)]
    as_gait = {name: getattr(gait.env, name) for name in fields}
    assert replace(ground, env=replace(ground.env, **as_gait)) == gait


@pytest.mark.parametrize("seed", [150, 215, 345, 556])
def test_shipped_agent_robust_is_agent_gait_grounds_recipe_with_mirror_loss_and_curriculum(seed, capsys):
    """agent-robust (docs/agent-robust.md): agent-gait-ground's config, symmetric and with a curriculum."""
    assert main(["agent", "info", "--policy", f"robust@{seed}", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["policy"] == f"krl/agent/policies/agent-robust/seed{seed}.npz"
    assert (info["reward"], info["kernel"], info["training"]["seed"]) == ("rp", "ext", seed)
    assert info["training"]["env_steps"] >= 20_000_000
    ground, robust = (
        load_policy(one_policy(f"{name}@{seed}")[1]).config for name in ("gait-ground", "robust")
    )
    assert (robust.ppo.symmetry, robust.env.push_curriculum) == ("loss", True)
    as_ground = replace(
        robust, env=replace(robust.env, push_curriculum=False), ppo=replace(robust.ppo, symmetry="none")
    )
    assert as_ground == ground


def test_the_faithful_agent_acts_with_residuals_only(capsys):
    assert main(["agent", "info", "--json"]) == 0
    (part,) = json.loads(capsys.readouterr().out)["action"]
    assert (part["name"], part["at_plus_1"]) == ("residual", [0.08] * 12)


def test_agent_errors_are_one_line(tmp_path, capsys):
    (tmp_path / "bad.npz").write_text("not a policy")
    assert main(["agent", "run", "--policy", str(tmp_path / "bad.npz"), "--targets", "1"]) == 2
    error = capsys.readouterr().err
    assert error == f"krl: error: {tmp_path / 'bad.npz'} is not a krl policy (.npz) file\n"
    (tmp_path / "cfg.json").write_text('{"observation": {"features": ["joint_pos", "nonsense"]}}')
    assert (
        main(["agent", "train", "--out", str(tmp_path / "run"), "--config", str(tmp_path / "cfg.json")]) == 2
    )
    error = capsys.readouterr().err
    assert "unknown observation feature 'nonsense'" in error and error.count("\n") == 1
    assert not (tmp_path / "run").exists()


def test_evaluate_scores_an_agent_on_a_course(tmp_path, capsys):
    path = make_policy(AgentConfig()).save(tmp_path / "agent-zero.npz")
    course, out = short_flat(tmp_path), tmp_path / "eval"
    args = ["evaluate", "--controller", f"agent:{path}", "--course", str(course), "--workers", "1"]
    assert main([*args, "--out", str(out), "--quiet", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    flat = summary["controllers"]["agent-zero"]["short-flat"]
    assert flat["runs"] == 4 and flat["fall_rate"] == 0.0
