"""`krl expert plot` (:mod:`krl.analysis.expert`): the CoM metric on hand-made trajectories, the line fit,
quick runs of every figure, argument errors."""

import argparse
import csv
import json
import math

import numpy as np
import pytest

from krl.analysis.common import fit_line
from krl.analysis.expert.driver import PlotError, make_figures
from krl.analysis.expert.metrics import (
    com_deviation,
    com_metrics,
    detrend_kernel,
    detrend_window_steps,
    gait_cycle,
    moving_average_kernel,
)
from krl.analysis.expert.plan import FIGURES, THESIS_FIGURE
from krl.cli import expert as expert_cli
from krl.util.timing import CONTROL_DT


def test_nominal_heights_are_the_expert_defaults():
    from krl.control.expert import NOMINAL_RIDE_HEIGHT, NOMINAL_STEP_HEIGHT, ExpertParams

    params = ExpertParams()
    assert (NOMINAL_RIDE_HEIGHT, NOMINAL_STEP_HEIGHT) == (params.ride_height, params.step_height)


# --- metric -------------------------------------------------------------------------------------------


@pytest.mark.parametrize(("stance", "steps"), [(0.3, 200), (0.25, 250), (0.2, 200)])
def test_detrend_window_is_whole_gait_cycles_of_at_least_one_second(stance, steps):
    cycle = gait_cycle(stance)
    assert cycle == pytest.approx(stance / 0.6)  # trot: r_swing = 0.4
    window = detrend_window_steps(cycle)
    assert window == steps
    cycles = window * CONTROL_DT / cycle
    assert cycles == pytest.approx(round(cycles)) and window * CONTROL_DT >= 1.0 - 1e-9


@pytest.mark.parametrize("window", [7, 8, 200])
def test_kernels(window):
    average = moving_average_kernel(window)
    assert average.sum() == pytest.approx(1.0) and np.allclose(average, average[::-1])
    high_pass = detrend_kernel(window)
    t = np.arange(len(high_pass), dtype=float) - len(high_pass) // 2
    for power in range(4):  # polynomials up to degree 3 are removed exactly
        assert abs(high_pass @ (t**power)) < 1e-9 * max(1.0, np.abs(t**power).max())
    # a sinusoid with a whole number of periods in the window passes unchanged
    n = np.arange(3 * len(high_pass))
    wave = np.sin(2 * np.pi * 2 * n / window + 0.4)
    out = np.convolve(wave, high_pass, mode="valid")
    assert np.allclose(out, wave[len(high_pass) // 2 : len(high_pass) // 2 + len(out)], atol=1e-9)


def _straight_walk(seconds=20.0, heading=0.5, lateral=0.004, vertical=0.002, cycle=1 / 3):
    """CoM walking along a line at 30° with a speed ramp, a lateral sway at the gait frequency and a
    vertical bounce at twice it; trunk yaw = the line's heading."""
    t = np.arange(0.0, seconds, CONTROL_DT)
    s = 0.2 * t + 0.01 * t**2  # speed ramp: the path is a quadratic in t
    forward = np.array([np.cos(heading), np.sin(heading), 0.0])
    left = np.array([-np.sin(heading), np.cos(heading), 0.0])
    sway = lateral * np.sin(2 * np.pi * t / cycle)
    bounce = vertical * np.cos(4 * np.pi * t / cycle)
    com = s[:, None] * forward + sway[:, None] * left
    com[:, 2] = 0.24 + bounce
    return t, com, np.full(len(t), heading)


def test_com_deviation_recovers_known_sway_on_a_straight_line():
    _, com, yaw = _straight_walk()
    window = detrend_window_steps(1 / 3)
    deviation, where = com_deviation(com, yaw, window)
    assert len(deviation) == len(com) - 2 * window and where.start == window
    std = deviation.std(axis=0)
    assert std[0] == pytest.approx(0.0, abs=1e-9)  # the walk (with its speed ramp) is gone
    assert std[1] == pytest.approx(0.004 / math.sqrt(2), rel=1e-3)  # lateral sway: amplitude / √2
    assert std[2] == pytest.approx(0.002 / math.sqrt(2), rel=1e-3)  # bounce


def test_com_deviation_on_a_turn_is_in_the_heading_frame():
    # walking a circle of radius 1 m at 0.5 m/s (yaw rate 0.5 rad/s) with a forward surge of 3 mm
    t = np.arange(0.0, 30.0, CONTROL_DT)
    yaw = 0.5 * t
    surge = 0.003 * np.sin(2 * np.pi * t / 0.5)
    com = np.stack(
        (np.sin(yaw) + surge * np.cos(yaw), 1 - np.cos(yaw) + surge * np.sin(yaw), np.full_like(t, 0.24)), 1
    )
    metrics = com_metrics(com, np.stack((0 * t, 0 * t, yaw), 1), detrend_window_steps(0.5))
    assert metrics["com_std_x"] == pytest.approx(0.003 / math.sqrt(2), rel=0.02)
    assert metrics["com_std_y"] < 2e-4  # the turn's curvature leaves (almost) nothing
    assert metrics["com_std_z"] == pytest.approx(0.0, abs=1e-9)


def test_com_metrics_tilt_skip_and_short_runs():
    t, com, yaw = _straight_walk(seconds=10.0)
    roll = np.radians(2.0) * np.sin(2 * np.pi * t / 0.5)
    rpy = np.stack((roll, np.zeros_like(t), yaw), 1)
    metrics = com_metrics(com, rpy, 200, skip=200)
    assert metrics["roll_std_deg"] == pytest.approx(2.0 / math.sqrt(2), rel=1e-2)
    assert metrics["pitch_std_deg"] == 0.0
    assert metrics["com_height_mean"] == pytest.approx(0.24, abs=1e-4)
    assert metrics["samples"] == len(t) - 200 - 2 * 200
    assert metrics["com_std"] == pytest.approx(
        math.sqrt(metrics["com_std_x"] ** 2 + metrics["com_std_y"] ** 2 + metrics["com_std_z"] ** 2)
    )
    short = com_metrics(com[:300], rpy[:300], 200)
    assert math.isnan(short["com_std_y"]) and short["samples"] == 0
    assert math.isfinite(short["roll_std_deg"])
    with pytest.raises(ValueError, match="com must be"):
        com_deviation(com[:, :2], yaw, 200)


def test_fit_line():
    x = np.linspace(-0.5, 0.5, 11)
    fit = fit_line(x, 0.9 * x - 0.02)
    assert fit["slope"] == pytest.approx(0.9) and fit["offset"] == pytest.approx(-0.02)
    assert fit["rmse"] == pytest.approx(0.0, abs=1e-12) and fit["points"] == 11
    y = 0.9 * x - 0.02
    y[3] = np.nan  # ignored
    assert fit_line(x, y)["points"] == 10
    assert math.isnan(fit_line([0.1], [0.1])["slope"])


# --- quick runs -----------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def quick_all(tmp_path_factory):
    out = tmp_path_factory.mktemp("expert")
    summary = make_figures("all", out, seed=0, quick=True, workers=2, progress=False)
    return out, summary


COM_KEYS = {"com_std_x", "com_std_y", "com_std_z", "com_std", "roll_std_deg", "pitch_std_deg", "fell"}


def test_quick_all_writes_every_figure(quick_all):
    from PIL import Image

    out, summary = quick_all
    assert set(summary["figures"]) == set(FIGURES)
    assert summary["conditions_run"] == 3 + 3 + 4 + 7  # stance 0.2 / ride 0.25 shared; one zero command
    for name in FIGURES:
        png, table, rows = out / f"{name}.png", out / f"{name}.json", out / f"{name}.csv"
        with Image.open(png) as image:
            assert image.width == 900 and image.height >= 300
            low, high = image.convert("L").getextrema()
            assert high - low > 100  # not blank
        data = json.loads(table.read_text())
        assert data["figure"] == name and data["thesis_figure"] == THESIS_FIGURE[name]
        with rows.open() as handle:
            assert len(list(csv.DictReader(handle))) == len(data["conditions"])
    assert not [p for p in out.iterdir() if p.name.startswith(".")]  # no temp files left


def test_quick_com_tables(quick_all):
    out, _ = quick_all
    expected = {
        "com-variance": ("stance_duration", [0.3, 0.25, 0.2]),
        "ride-height": ("ride_height", [0.18, 0.21, 0.25, 0.28]),
        "step-height": ("step_height", [0.05, 0.09, 0.13, 0.18]),
    }
    for name, (key, values) in expected.items():
        data = json.loads((out / f"{name}.json").read_text())
        assert [row[key] for row in data["conditions"]] == values
        assert len(data["waypoints"]) == 1 and "(I - M)^2" in data["metric"]
        for row in data["conditions"]:
            assert COM_KEYS <= set(row)
            assert not row["fell"] and row["targets_reached"] == 1
            assert 0 < row["com_std_z"] < 0.05  # finite, millimetres
    # ride 0.25 m at stance 0.2 s is the same run in all three figures
    rows = {
        name: json.loads((out / f"{name}.json").read_text())["conditions"]
        for name in ("com-variance", "ride-height")
    }
    assert rows["com-variance"][2]["com_std"] == rows["ride-height"][2]["com_std"]


def test_quick_velocity_table(quick_all):
    out, _ = quick_all
    data = json.loads((out / "velocity.json").read_text())
    commanded = {
        axis: [r["commanded"] for r in data["conditions"] if r["axis"] == axis] for axis in "vx vy wz".split()
    }
    assert commanded == {"vx": [-0.5, 0.0, 0.5], "vy": [-0.3, 0.0, 0.3], "wz": [-0.5, 0.0, 0.5]}
    for axis, fit in data["fits"].items():
        assert set(fit) >= {"slope", "offset", "rmse", "max_abs_cross"}
        assert 0.8 < fit["slope"] < 1.2, axis  # the expert tracks its commands
    assert all(not r["fell"] and r["vx_std"] is not None for r in data["conditions"])


def test_cli_run_in_process_matches_the_pool(quick_all, tmp_path, capsys):
    parser = argparse.ArgumentParser()
    expert_cli.add_plot_arguments(parser)
    args = parser.parse_args(["com-variance", "--out", str(tmp_path), "--quick", "--workers", "1", "--json"])
    assert expert_cli.cmd_expert_plot(args) == 0
    printed = json.loads(capsys.readouterr().out)
    assert set(printed["figures"]) == {"com-variance"}
    here = json.loads((tmp_path / "com-variance.json").read_text())
    pooled = json.loads((quick_all[0] / "com-variance.json").read_text())
    assert here == pooled  # deterministic: the worker count does not matter


# --- errors ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"which": "rocking"}, "unknown figure 'rocking'"),
        ({"duration": -1.0}, "--duration must be"),
        ({"duration": 2.0}, "--duration must be"),
        ({"targets": 0}, "--targets must be"),
        ({"workers": 0}, "--workers must be"),
        ({"seed": -3}, "--seed must be"),
    ],
)
def test_bad_arguments_raise_before_anything_is_written(tmp_path, kwargs, message):
    out = tmp_path / "never"
    arguments = {"which": "velocity", "out": out, "quick": True, **kwargs}
    with pytest.raises(PlotError, match=message):
        make_figures(**arguments)
    assert not out.exists()


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["expert", "plot", "rocking", "--out", "OUT"], "unknown figure"),
        (["expert", "plot", "velocity", "--out", "OUT", "--duration", "-1"], "--duration must be"),
    ],
)
def test_cli_errors_are_one_line(tmp_path, capsys, argv, message):
    from krl.cli import main

    out = tmp_path / "out"
    assert main([str(out) if a == "OUT" else a for a in argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("krl: error:") and message in err and err.count("\n") == 1
    assert not out.exists()
