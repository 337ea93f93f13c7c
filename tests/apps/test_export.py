"""``krl export``: onnxruntime runs the exported kernel and policy as krl's NumPy inference does."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import onnxruntime
from agent_fakes import make_policy

from krl.agent.config import AgentConfig
from krl.cli import main
from krl.kernel.registry import load_model


def _run(path: Path, name: str, x: np.ndarray) -> np.ndarray:
    session = onnxruntime.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    return session.run(None, {name: x.astype(np.float32)})[0]


def test_exported_kernel_and_policy_match_numpy_inference(tmp_path, capsys):
    policy = make_policy(AgentConfig(), scale=0.3, seed=1)
    rng = np.random.default_rng(0)
    policy.obs_mean = rng.standard_normal(policy.observation_size)
    policy.obs_var = rng.uniform(0.5, 2.0, policy.observation_size)
    path = policy.save(tmp_path / "agent-x.npz")
    assert main(["export", "--out", str(tmp_path / "onnx"), "--policy", str(path), "--json"]) == 0
    files = json.loads(capsys.readouterr().out)
    kernel = load_model("base")
    features = np.column_stack((rng.uniform(-0.5, 0.5, (64, 3)), rng.uniform(0, 2, (64, 4))))
    np.testing.assert_allclose(
        _run(files["kernel"], "features", features), kernel.predict(features), atol=1e-5, rtol=1e-5
    )
    observation = rng.standard_normal((64, policy.observation_size)) * 3
    np.testing.assert_allclose(
        _run(files["policy"], "observation", observation), policy.act(observation), atol=1e-5
    )
    contract = json.loads(Path(files["contract"]).read_text())
    assert contract["policy"]["observation"][0] == {
        "name": "base_lin_vel",
        "start": 0,
        "stop": 3,
        "unit": "m/s",
    }
    assert contract["policy"]["action"]["filter_alpha"] == 0.1
    assert contract["kernel"]["source"]["sha256"] == contract["policy"]["kernel_sha256"]
    assert contract["joint_order"][:3] == ["FR_abduction", "FR_hip", "FR_knee"]


def test_a_gait_driving_policy_exports_its_action_parts(tmp_path, capsys):
    config = AgentConfig.from_json(
        {
            "residual": {"kernel": "ext", "drive_heights": True, "drive_rhythm": True},
            "observation": {"features": ["base_lin_vel", "command", "heights", "clock_rate"]},
        }
    )
    policy = make_policy(config, scale=0.3, seed=2)
    path = policy.save(tmp_path / "agent-gait.npz")
    assert main(["export", "--out", str(tmp_path / "onnx"), "--policy", str(path), "--json"]) == 0
    files = json.loads(capsys.readouterr().out)
    observation = np.random.default_rng(0).standard_normal((8, policy.observation_size))
    actions = _run(files["policy"], "observation", observation)
    assert actions.shape == (8, 15)
    np.testing.assert_allclose(actions, policy.act(observation), atol=1e-5)
    action = json.loads(Path(files["contract"]).read_text())["policy"]["action"]
    assert action["size"] == 15
    parts = {part["name"]: part for part in action["parts"]}
    assert [(p["start"], p["stop"]) for p in action["parts"]] == [(0, 12), (12, 14), (14, 15)]
    assert parts["heights"]["at_minus_1"] == [0.05, 0.18] and parts["heights"]["at_plus_1"] == [0.18, 0.28]
    assert parts["clock_rate"]["at_0"] == [1.0] and parts["clock_rate"]["filter_alpha"] == 0.05
    assert parts["residual"]["at_plus_1"] == [0.08] * 12 and "drive_filter" in action
    assert parts["heights"]["labels"] == ["step_height", "ride_height"]
    assert parts["clock_rate"]["labels"] == ["rate"]
    assert parts["residual"]["labels"][:4] == ["FR.x", "FR.y", "FR.z", "FL.x"]


def test_the_ext_kernel_alone(tmp_path, capsys):
    assert main(["export", "--out", str(tmp_path), "--kernel", "ext", "--json"]) == 0
    files = json.loads(capsys.readouterr().out)
    kernel = load_model("ext")
    features = np.random.default_rng(1).uniform(0, 0.3, (16, kernel.input_size))
    np.testing.assert_allclose(
        _run(files["kernel"], "features", features), kernel.predict(features), atol=1e-5, rtol=1e-5
    )
    assert "policy" not in files


def test_export_takes_an_agent_as_krl_evaluate_spells_it(tmp_path, capsys):
    out = tmp_path / "onnx"
    assert main(["export", "--out", str(out), "--policy", "agent:gait-ground@215", "--json"]) == 0
    capsys.readouterr()
    policy = json.loads((out / "contract.json").read_text())["policy"]
    assert (policy["seed_group"], policy["seed"], policy["source"]["file"]) == (
        "gait-ground",
        215,
        "seed215.npz",
    )


def test_shipped_names_resolve_for_the_policy_and_its_kernel(tmp_path, capsys):
    from krl.kernel.registry import shipped_model_path
    from krl.util.hashing import file_sha256

    out = tmp_path / "onnx"
    assert main(["export", "--out", str(out), "--policy", "rp", "--kernel", "base", "--json"]) == 0
    files = json.loads(capsys.readouterr().out)
    contract = json.loads(Path(files["contract"]).read_text())
    assert contract["kernel"]["source"]["sha256"] == file_sha256(shipped_model_path("base"))
    for role in ("kernel", "policy"):  # each file the contract lists is hashed as it was written
        assert contract[role]["sha256"] == file_sha256(out / contract[role]["file"])
    assert (contract["policy"]["seed_group"], contract["policy"]["seed"]) == ("rp", 150)
    assert contract["policy"]["action"]["size"] == 12
    before = {path.name: path.read_bytes() for path in out.iterdir()}
    assert main(["export", "--out", str(out), "--policy", "rp", "--kernel", "ext"]) == 2
    err = capsys.readouterr().err
    assert "not the kernel this policy corrects" in err and err.count("\n") == 1
    assert {path.name: path.read_bytes() for path in out.iterdir()} == before


def test_a_kernel_only_export_never_leaves_an_unlisted_policy_beside_it(tmp_path, capsys):
    """A policy.onnx of an earlier export is refused, not kept unlisted in contract.json nor deleted."""
    policy = make_policy(AgentConfig(), scale=0.3, seed=1).save(tmp_path / "agent-x.npz")
    out = tmp_path / "onnx"
    assert main(["export", "--out", str(out), "--policy", str(policy)]) == 0
    capsys.readouterr()
    before = {path.name: path.read_bytes() for path in out.iterdir()}
    assert main(["export", "--out", str(out), "--kernel", "ext"]) == 2
    err = capsys.readouterr().err
    assert f"{out / 'policy.onnx'}" in err and "kernel-only" in err and err.count("\n") == 1
    assert {path.name: path.read_bytes() for path in out.iterdir()} == before
    (out / "policy.onnx").unlink()
    assert main(["export", "--out", str(out), "--kernel", "ext", "--json"]) == 0
    contract = json.loads((out / "contract.json").read_text())
    assert "policy" not in contract
    assert sorted(path.name for path in out.iterdir()) == ["contract.json", "kernel.onnx"]


def test_without_the_export_extra_the_error_is_one_line(tmp_path, monkeypatch, capsys):
    import builtins

    from krl.cli import main

    real_import = builtins.__import__

    def no_onnx(name, *args, **kwargs):
        if name == "onnx" or name.startswith("onnx."):
            raise ImportError("No module named 'onnx'")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_onnx)
    assert main(["export", "--out", str(tmp_path / "onnx")]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "pip install" in error
