"""The kernel as a controller: every variant drives the robot; the shipped kernels walk; CLI."""

import json

import numpy as np
import pytest

from krl.cli import main
from krl.kernel.controller import KernelController
from krl.kernel.features import VARIANTS, input_names, output_size
from krl.kernel.model import Kernel, NetworkConfig, load_kernel
from krl.kernel.registry import SHIPPED_MODELS, shipped_model_path
from krl.sim.model import build_model
from krl.sim.robot import A1Sim
from krl.task import random_targets
from krl.task.runner import Runner


def random_kernel(variant):
    rng = np.random.default_rng(0)
    n_in, n_out = len(input_names(variant)), output_size(variant)
    weights = [
        rng.normal(size=(8, n_in)) * 0.01,
        np.zeros(8),
        rng.normal(size=(n_out, 8)) * 0.01,
        np.zeros(n_out),
    ]
    # outputs centred on the standing feet, so the robot stands
    standing = A1Sim(build_model("flat")).state.foot_pos_base
    mean = standing[:1].ravel() if variant == "ind" else standing.ravel()
    return Kernel(
        variant, NetworkConfig(hidden=(8,)), weights, np.zeros(n_in), np.ones(n_in), mean, np.ones(n_out), {}
    )


@pytest.mark.parametrize("variant", VARIANTS)
def test_every_variant_produces_foot_targets(variant):
    sim = A1Sim(build_model("flat"))
    controller = KernelController(random_kernel(variant))
    state = sim.reset()
    controller.reset(state)
    for _ in range(20):
        command = controller.act(state, np.array([0.2, 0.0, 0.1]))
        state = sim.step(*command)
    assert controller.last_targets.shape == (4, 3) and np.isfinite(controller.last_targets).all()
    assert command.q_target.shape == (12,)
    assert not state.fallen


def test_heights_are_validated():
    controller = KernelController(random_kernel("ext"))
    with pytest.raises(ValueError, match="step_height"):
        controller.set_heights(0.3, 0.25)
    with pytest.raises(ValueError, match="ride_height"):
        controller.set_heights(0.1, 0.1)


@pytest.mark.parametrize("variant", [v for v in VARIANTS if v != "ext"])
def test_heights_are_refused_by_a_kernel_without_height_inputs(variant):
    for heights in ({"step_height": 0.12}, {"ride_height": 0.22}):
        with pytest.raises(ValueError, match=f"kernel-{variant} has no step or ride height input"):
            KernelController(random_kernel(variant), **heights)
    with pytest.raises(ValueError, match="no step or ride height input"):
        KernelController(random_kernel(variant)).set_heights(0.1, 0.22)


def test_cli_kernel_run_refuses_a_height_for_kernel_base(capsys):
    argv = ["kernel", "run", "--model", "base", "--step-height", "0.12", "--command", "0.3,0,0"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "kernel-base has no step or ride height input" in err and err.count("\n") == 1


@pytest.mark.parametrize("name", SHIPPED_MODELS)
def test_shipped_kernels_load_with_metadata(name):
    kernel = load_kernel(shipped_model_path(name))
    assert kernel.variant == name
    for key in ("config", "dataset_hash", "val_l1", "train_seconds", "train_targets", "inputs"):
        assert key in kernel.metadata
    # measured at training: base 5.2e-4 m (issue target 7e-4), ext 1.4e-3 m (docs/kernel.md)
    assert kernel.metadata["val_l1"] < {"base": 7e-4, "ext": 1.5e-3}[name]


def test_shipped_kernel_base_walks_to_waypoints():
    runner = Runner(A1Sim(build_model("flat")), KernelController(load_kernel(shipped_model_path("base"))))
    result = runner.walk_to(random_targets(np.random.default_rng(3), 3, distance=(1.0, 1.5)))
    assert result.targets_reached == 3 and not result.fell


def test_shipped_kernel_ext_follows_its_ride_height():
    kernel = load_kernel(shipped_model_path("ext"))
    heights = []
    for ride in (0.2, 0.27):
        sim = A1Sim(build_model("flat"))
        runner = Runner(sim, KernelController(kernel, ride_height=ride))
        result = runner.hold_command(np.array([0.2, 0.0, 0.0]), 4.0)
        assert not result.fell
        heights.append(sim.state.base_pos[2])
    assert heights[1] - heights[0] > 0.04


def test_kernel_eval_on_fresh_expert_data(capsys):
    assert main(["kernel", "eval", "--targets", "1", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["variant"] == "base" and result["rows"] > 500
    assert result["val_l1"] < 1.5e-3
    assert "fresh expert data" in result["data"]


def test_kernel_run_and_errors(tmp_path, capsys):
    assert main(["kernel", "run", "--command", "0.3,0,0", "--duration", "3", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert not result["fell"] and result["variant"] == "base" and result["gait"] == "trot"
    assert (
        main(["kernel", "run", "--gait", "walk", "--command", "0.2,0,0", "--duration", "2.5", "--json"]) == 0
    )
    assert json.loads(capsys.readouterr().out)["gait"] == "walk"
    assert main(["kernel", "run", "--gait", "gallop"]) == 2
    assert "unknown gait 'gallop'" in capsys.readouterr().err
    assert main(["kernel", "run", "--model", str(tmp_path / "missing.npz")]) == 2
    assert "not found" in capsys.readouterr().err
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"garbage")
    assert main(["kernel", "eval", "--model", str(bad)]) == 2
    assert "corrupt" in capsys.readouterr().err
