"""`krl kernel figures` (:mod:`krl.analysis.kernel`): the metrics on hand-made inputs, a --quick run of every
figure, argument errors."""

import argparse
import csv
import json

import numpy as np
import pytest
from PIL import Image

from krl.analysis.common import fit_rows, velocity_sweep
from krl.analysis.kernel.context import FR, RL, FigureError
from krl.analysis.kernel.driver import make_kernel_figures
from krl.analysis.kernel.metrics import (
    fold_cycle,
    height_metrics,
    l1_per_axis,
    stance_lift_metrics,
    sweep_metrics,
    symmetry_metrics,
)
from krl.analysis.kernel.recording import cycle_inputs
from krl.analysis.kernel.symmetry import SYMMETRY_SPEEDS
from krl.cli import kernel as kernel_cli
from krl.kernel.features import input_names, output_size
from krl.kernel.model import Kernel, NetworkConfig
from krl.kernel.registry import shipped_model_path

HAS_EXT = shipped_model_path("ext").is_file()


def fake_kernel_file(tmp_path, variant):
    """A small random kernel of ``variant`` saved to a file (its outputs near a standing foot)."""
    rng = np.random.default_rng(1)
    n_in, n_out = len(input_names(variant)), output_size(variant)
    weights = [rng.normal(size=(8, n_in)), np.zeros(8), rng.normal(size=(n_out, 8)) * 0.01, np.zeros(n_out)]
    mean = np.tile([0.18, -0.13, -0.23], n_out // 3)
    kernel = Kernel(
        variant, NetworkConfig(hidden=(8,)), weights, np.zeros(n_in), np.ones(n_in), mean, np.ones(n_out), {}
    )
    return kernel.save(tmp_path / f"kernel-{variant}.npz")


# --- metrics ----------------------------------------------------------------------------------------------


def test_l1_per_axis():
    label = np.zeros((10, 4, 3))
    prediction = label + np.array([0.001, -0.002, 0.004])
    l1 = l1_per_axis(prediction, label)
    assert l1 == pytest.approx({"x": 0.001, "y": 0.002, "z": 0.004, "mean": 0.007 / 3})
    with pytest.raises(ValueError, match="shape"):
        l1_per_axis(np.zeros((3, 2)), np.zeros((3, 2)))


def test_symmetry_metrics_on_symmetric_identical_and_offset_trajectories():
    t = np.linspace(0, 1, 50, endpoint=False)
    wave = 0.003 * np.sin(2 * np.pi * t)
    fr = np.stack([0.18 + 0.02 * np.cos(2 * np.pi * t), -0.13 + wave, -0.23 + 0.01 * t], 1)
    rl = np.stack([fr[:, 0] - 0.36, 0.13 - wave, fr[:, 2]], 1)  # the mirror image: y inverse
    m = symmetry_metrics(fr, rl)
    assert m["y_asym"] == pytest.approx(0, abs=1e-12) and m["y_asym_rel"] == pytest.approx(0, abs=1e-9)
    assert m["y_corr"] == pytest.approx(-1) and m["y_offset_sum"] == pytest.approx(0, abs=1e-12)
    assert m["x_mismatch"] == pytest.approx(0, abs=1e-12) and m["z_mismatch"] == pytest.approx(0, abs=1e-12)
    assert m["y_rms_fr"] == pytest.approx(0.003 / np.sqrt(2))
    same = rl.copy()
    same[:, 1] = 0.14 + wave  # RL's y moves with FR's: fully asymmetric, and 1 cm wider
    m = symmetry_metrics(fr, same)
    assert m["y_asym_rel"] == pytest.approx(2) and m["y_corr"] == pytest.approx(1)
    assert m["y_asym"] == pytest.approx(2 * 0.003 / np.sqrt(2)) and m["y_offset_sum"] == pytest.approx(0.01)
    with pytest.raises(ValueError):
        symmetry_metrics(fr, rl[:5])


def test_fold_cycle_averages_by_phase():
    phase = np.tile((np.arange(20) + 0.5) / 20, 7)
    values = np.sin(2 * np.pi * phase)[:, None] * np.array([1.0, 2.0])
    centres, means = fold_cycle(phase, values, bins=10)
    assert centres == pytest.approx((np.arange(10) + 0.5) / 10)
    expected = [
        (np.sin(2 * np.pi * (2 * j + 0.5) / 20) + np.sin(2 * np.pi * (2 * j + 1.5) / 20)) / 2
        for j in range(10)
    ]
    assert means[:, 0] == pytest.approx(expected) and means[:, 1] == pytest.approx(2 * np.array(expected))
    centres, means = fold_cycle(np.array([0.05, 1.0]), np.array([1.0, 3.0]), bins=4)
    assert means[0] == 1.0 and means[3] == 3.0 and np.isnan(means[1]) and np.isnan(means[2])


def test_stance_lift_metrics():
    stance = np.array([True] * 6 + [False] * 4)
    label = np.array([-0.23] * 6 + [-0.20, -0.15, -0.15, -0.22])
    prediction = label.copy()
    prediction[:2] += 0.05  # lifts in stance: 2 of 6
    prediction[7] = -0.23  # stays down where the foot should be up: 1 of the 3 "really up" samples
    m = stance_lift_metrics(prediction, label, stance)
    assert m["phantom_lift_fraction"] == pytest.approx(2 / 6)
    assert m["missed_swing_fraction"] == pytest.approx(1 / 3)
    assert m["stance_z_l1"] == pytest.approx(0.1 / 6) and m["swing_z_l1"] == pytest.approx(0.08 / 4)


def test_height_and_sweep_metrics():
    stance = np.array([False, False, True, True, True])
    z = np.array([-0.15, -0.20, -0.23, -0.23, -0.22])
    m = height_metrics(z, stance, step_height=0.08, ride_height=0.25)
    assert m["stance_z"] == pytest.approx(-0.23) and m["apex_z"] == pytest.approx(-0.15)
    assert m["clearance"] == pytest.approx(0.08) and m["clearance_expected"] == 0.08
    assert m["stance_z_expected"] == pytest.approx(-0.23) and m["apex_z_expected"] == pytest.approx(-0.15)
    feet = np.stack([[0.1, 0.2, 0.3], [-0.1, -0.1, -0.1], z[:3]], 1)  # (3 samples, 3 axes)
    s = sweep_metrics(feet)
    assert s["x_ptp"] == pytest.approx(0.2) and s["y_mean"] == pytest.approx(-0.1)
    assert (s["z_min"], s["z_max"]) == pytest.approx((-0.23, -0.15))


def test_cycle_inputs_sample_one_trot_cycle_by_fr_phase():
    c = cycle_inputs("trot", 0.2, points=40)
    assert c["phase"][0] == pytest.approx(1 / 40) and c["phase"][-1] == 1.0
    assert c["phases"][:, FR] == pytest.approx(c["phase"])
    assert c["phases"][:, RL] == pytest.approx(c["phase"])  # the trot's diagonal pair
    assert c["step_duration"] == pytest.approx(0.2 / 0.6) and c["time"].max() < c["step_duration"]
    assert c["stance"].sum() == 24  # r_swing 0.4
    assert np.all((c["normalised"] > 1) == (c["phases"] <= 0.4))


def test_velocity_sweep_is_the_expert_figures_sweep():
    points = velocity_sweep()
    counts = {axis: sum(1 for a, _, _ in points if a == axis) for axis in ("vx", "vy", "wz")}
    assert counts == {"vx": 11, "vy": 7, "wz": 11}
    assert [v for a, v, _ in points if a == "vy"] == pytest.approx([-0.3, -0.2, -0.1, 0.0, 0.1, 0.2, 0.3])
    for axis, value, command in points:
        assert command[("vx", "vy", "wz").index(axis)] == value and sum(map(abs, command)) == abs(value)
    assert [v for a, v, _ in velocity_sweep(quick=True) if a == "wz"] == [-0.5, 0.0, 0.5]


def test_fit_rows_fits_one_key_of_the_rows_against_another():
    rows = [{"value": v, "x_ptp": 0.2 * v + 0.01, "y_ptp": 0.0} for v in (0.0, 0.5, 1.0)]
    fit = fit_rows(rows, "value", "x_ptp")
    assert (fit["slope"], fit["offset"], fit["points"]) == pytest.approx((0.2, 0.01, 3))
    assert np.isnan(fit_rows(rows[:1], "value", "x_ptp")["slope"])


# --- quick runs ---------------------------------------------------------------------------------------------


def check_outputs(summary, name, tmp_path):
    figure = summary["figures"][name]
    with Image.open(figure["png"]) as image:
        width, height = image.size
    assert 800 <= width <= 1000 and 400 <= height <= 700
    table = json.loads((tmp_path / f"{name}.json").read_text())
    assert table["figure"] == name and table["thesis_figure"].startswith("Fig. 4.")
    with open(tmp_path / f"{name}.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert rows
    assert not list(tmp_path.glob(".*.tmp"))
    return table, rows


def test_quick_trajectories(tmp_path):
    summary = make_kernel_figures("trajectories", tmp_path, quick=True, workers=1, progress=False)
    table, rows = check_outputs(summary, "trajectories", tmp_path)
    assert table["steps"] > 100 and not table["fell"]
    assert table["l1_fr"]["mean"] < 0.005  # the shipped kernel imitates its expert to millimetres
    assert {"label_x", "kernel_z", "vx_cmd"} <= set(rows[0])


def test_quick_command_sweep_and_the_cli(tmp_path, capsys):
    parser = argparse.ArgumentParser()
    kernel_cli.add_figures_arguments(parser)
    args = parser.parse_args(["command-sweep", "--out", str(tmp_path), "--quick", "--workers", "1"])
    assert kernel_cli.run_figures(args) == 0
    assert "command-sweep (Fig. 4.10)" in capsys.readouterr().out
    table = json.loads((tmp_path / "command-sweep.json").read_text())
    assert {r["command"] for r in table["conditions"]} == {"vx", "vy", "wz"}
    assert table["training_range"]["vy"] == [-0.3, 0.3]
    inside = {(r["command"], r["value"]): r["in_training_range"] for r in table["conditions"]}
    assert inside[("vx", 0.5)] and not inside[("vx", 1.0)] and not inside[("wz", -1.0)]


def test_quick_symmetry(tmp_path):
    summary = make_kernel_figures("symmetry", tmp_path, quick=True, workers=1, progress=False)
    table, _ = check_outputs(summary, "symmetry", tmp_path)
    sources = {(r["source"], r["vx"]) for r in table["conditions"]}
    assert sources == {(s, v) for s in ("kernel-base", "MPC expert") for v in SYMMETRY_SPEEDS}
    assert all(r["y_asym"] is not None for r in table["conditions"])


def test_quick_walk_gait_with_a_kernel_ind(tmp_path):
    ind = fake_kernel_file(tmp_path, "ind")
    out = tmp_path / "out"
    summary = make_kernel_figures("walk-gait", out, ind_model=ind, quick=True, workers=1, progress=False)
    table, rows = check_outputs(summary, "walk-gait", out)
    assert set(table["results"]) == {"kernel-base", "kernel-ind"} and table["kernel_ind"]
    assert table["gait"]["swing_ratio"] == 0.25 and "ind_z" in rows[0]


def test_quick_velocity(tmp_path):
    summary = make_kernel_figures("velocity", tmp_path, quick=True, workers=1, progress=False)
    table, rows = check_outputs(summary, "velocity", tmp_path)
    assert len(rows) == 9 and set(table["fits"]) == {"vx", "vy", "wz"}
    if table["expert_source"] is not None:  # the committed expert numbers sit beside the kernel's
        assert all(r["expert_mean"] != "" for r in rows)


@pytest.mark.parametrize("shipped", [False, True])
def test_quick_heights(tmp_path, shipped):
    if shipped and not HAS_EXT:
        pytest.skip("no shipped kernel-ext")
    ext = "ext" if shipped else fake_kernel_file(tmp_path, "ext")
    out = tmp_path / "out"
    summary = make_kernel_figures("heights", out, ext_model=ext, quick=True, workers=1, progress=False)
    _, rows = check_outputs(summary, "heights", out)
    assert {(r["sweep"], float(r["step_height"]), float(r["ride_height"])) for r in rows} == {
        ("step_height", 0.05, 0.25),
        ("step_height", 0.18, 0.25),
        ("ride_height", 0.08, 0.18),
        ("ride_height", 0.08, 0.28),
    }


# --- errors -------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("which", "kwargs", "match"),
    [
        ("nope", {}, "unknown figure 'nope'; choose from trajectories"),
        ("trajectories", {"model": "/no/such/kernel.npz"}, "--model: kernel file not found"),
        ("heights", {"ext_model": "/no/such/ext.npz"}, "--ext-model: kernel file not found"),
        ("heights", {"ext_model": "base"}, "is a kernel-base, this figure needs a kernel-ext"),
        ("walk-gait", {"ind_model": "/no/ind.npz"}, "--ind-model: kernel file not found"),
        ("velocity", {"expert_json": "/no/velocity.json"}, "expert velocity table not found"),
        ("symmetry", {"workers": 0}, "--workers must be"),
        ("symmetry", {"seed": -1}, "--seed must be"),
    ],
)
def test_errors_are_clear_and_write_nothing(tmp_path, which, kwargs, match):
    out = tmp_path / "out"
    with pytest.raises(ValueError, match=match):
        make_kernel_figures(which, out, progress=False, **kwargs)
    assert not out.exists()


def test_out_must_not_be_a_file(tmp_path):
    path = tmp_path / "file"
    path.write_text("x")
    with pytest.raises(FigureError, match="not a folder"):
        make_kernel_figures("command-sweep", path, progress=False)
