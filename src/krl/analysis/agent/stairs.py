"""Why agents fall on the stairs course: where each run went, and how it followed its commands.

For every policy and start of the stairs course, :func:`stairs_diagnosis` traces the run exactly as
``krl evaluate`` walks it (:func:`krl.analysis.agent.trace.trace_course_run`) and measures:

* where it fell: the trunk's position on the last step, and whether the feet were past the stairs' side
  (|y| beyond the half-width) above the flights or the landing;
* how far out it swung on the landing: the largest |y| of the trunk and of any foot while over the landing;
* how it followed the commands over its first 15 s (the walk up the first flight and the first turns on
  the landing): the realised forward speed minus the commanded one (heading frame) [m/s], and the realised
  yaw rate's mean magnitude over the commanded one's.

:func:`stairs_figure` draws the runs from above over the stairs' outline with the course's commanded paths
(an ideal follower, exactly and through a 0.3 s lag: :meth:`krl.eval.courses.Course.commanded_path`), and
the two measures of command following against the swing on the landing; :func:`gait_figure` draws, for the
same runs, what the kernel was asked for over time (the step and ride heights and the gait clock's rate: a
gait-driving agent's choices, else the nominal ones) under the ground the trunk was over, and measures them
over the flights and the landing.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from krl.analysis.agent.trace import trace_course_run
from krl.eval.courses import Course
from krl.util.timing import CONTROL_DT

TRACKING_WINDOW: tuple[float, float] = (1.0, 15.0)
"""The stretch of each run whose command following is measured [s]: after the 1 s ramp, up the first
flight and through the first turns on the landing (where the failing runs fall, from 14 s on)."""

SMOOTHING: float = 0.2
"""Moving-average window of the realised velocities [s] (a trot's step is 0.2-0.3 s)."""

LAGS: tuple[float, ...] = (0.0, 0.3)
"""Tracking lags of the commanded paths drawn [s]."""


def stairs_geometry(course: Course) -> dict[str, float]:
    """The stairs' outline from the course's terrain landmarks and parameters [m]: first riser, landing
    start and end, end of the far flight (x), half-width (|y|), landing height (z)."""
    terrain = course.build().terrain
    marks, params = terrain.landmarks, terrain.params
    return {
        "first_riser": marks["first_riser"][0],
        "landing_start": marks["landing_start"][0],
        "landing_end": marks["landing_end"][0],
        "stairs_end": marks["stairs_end"][0],
        "half_width": 0.5 * params["width"],
        "landing_height": params["num_steps"] * params["step_height"],
    }


def _smooth(values: np.ndarray) -> np.ndarray:
    window = np.ones(round(SMOOTHING / CONTROL_DT)) / round(SMOOTHING / CONTROL_DT)
    return np.convolve(values, window, mode="same")


def command_following(trace: dict[str, np.ndarray]) -> dict[str, float]:
    """Forward-speed error (realised - commanded, heading frame) [m/s] and the yaw-rate gain (mean |realised|
    over mean |commanded|) over :data:`TRACKING_WINDOW` of a trace; NaN where the run ended before the window
    (both) or no yaw rate was commanded in it (the gain)."""
    yaw = np.unwrap(trace["rpy"][:, 2])
    velocity = np.gradient(trace["base_pos"][:, :2], CONTROL_DT, axis=0)
    forward = _smooth(np.cos(yaw) * velocity[:, 0] + np.sin(yaw) * velocity[:, 1])
    yaw_rate = _smooth(np.gradient(yaw, CONTROL_DT))
    low, high = (round(t / CONTROL_DT) for t in TRACKING_WINDOW)
    window = slice(low, min(high, len(yaw)))
    if window.start >= window.stop:
        return {"forward_speed_error": math.nan, "yaw_rate_gain": math.nan}
    command = trace["command"][window]
    commanded = float(np.mean(np.abs(command[:, 2])))
    return {
        "forward_speed_error": float(np.mean(forward[window] - command[:, 0])),
        "yaw_rate_gain": float(np.mean(np.abs(yaw_rate[window]))) / commanded if commanded > 0 else math.nan,
    }


def run_summary(trace: dict[str, np.ndarray], metrics: dict[str, Any], geometry: dict[str, float]) -> dict:
    """One run's row: outcome, fall position, swing on the landing and command following."""
    base, feet = trace["base_pos"], trace["foot_pos"]
    on_landing = (base[:, 0] > geometry["landing_start"]) & (base[:, 0] < geometry["landing_end"])
    feet_on_landing = (feet[..., 0] > geometry["landing_start"]) & (feet[..., 0] < geometry["landing_end"])
    over_stairs = (feet[-1, :, 0] > geometry["first_riser"]) & (feet[-1, :, 0] < geometry["stairs_end"])
    past_side = bool(np.any(over_stairs & (np.abs(feet[-1, :, 1]) > geometry["half_width"])))
    return {
        "targets_reached": metrics["targets_reached"],
        "success": metrics["success"],
        "fell": metrics["fell"],
        "fall_xy": [round(float(v), 3) for v in base[-1, :2]] if metrics["fell"] else None,
        "fell_past_the_side": past_side if metrics["fell"] else None,
        "landing_max_abs_y_base": float(np.abs(base[on_landing, 1]).max()) if on_landing.any() else None,
        "landing_max_abs_y_feet": float(np.abs(feet[..., 1][feet_on_landing]).max())
        if feet_on_landing.any()
        else None,
        **command_following(trace),
    }


GAIT_INPUTS: dict[str, int] = {"step_height": 3, "ride_height": 4, "clock_rate": 5}
"""The kernel's gait inputs a run's figure draws: column in a trace's ``gait_inputs`` (units: m, m, 1)."""


def gait_on_stairs(trace: dict[str, np.ndarray], geometry: dict[str, float]) -> dict[str, Any]:
    """Time series and means of a run's gait inputs (:data:`GAIT_INPUTS`) while its trunk is over the stairs.

    Returns ``time`` [s] (T,), ``ground`` (the mean terrain height under the four feet [m], (T,)), each
    input's series (T,), and ``NAME_on_stairs``: its mean over the steps whose trunk x lies between the
    first riser and the far flight's end (NaN if none).
    """
    x = trace["base_pos"][:, 0]
    over = (x > geometry["first_riser"]) & (x < geometry["stairs_end"])
    series: dict[str, Any] = {"time": trace["time"], "ground": trace["ground"].mean(axis=1)}
    for name, column in GAIT_INPUTS.items():
        values = trace["gait_inputs"][:, column]
        series[name] = values
        series[f"{name}_on_stairs"] = float(values[over].mean()) if over.any() else math.nan
    return series


def stairs_diagnosis(policies: dict[str, str | Path], course: Course) -> dict[str, list[dict]]:
    """``{label: [row per start]}`` (:func:`run_summary`, the base path ``xy`` and :func:`gait_on_stairs`'s
    ``gait``) for each policy file."""
    geometry = stairs_geometry(course)
    results: dict[str, list[dict]] = {}
    for label, path in policies.items():
        rows = []
        for start in range(len(course.starts)):
            trace, metrics = trace_course_run(path, course, start)
            gait = gait_on_stairs(trace, geometry)
            rows.append(
                {
                    "start": start,
                    **run_summary(trace, metrics, geometry),
                    **{f"{name}_on_stairs": gait[f"{name}_on_stairs"] for name in GAIT_INPUTS},
                    "xy": trace["base_pos"][:, :2],
                    "gait": gait,
                }
            )
        results[label] = rows
    return results


CSV_COLUMNS: tuple[str, ...] = (
    "policy",
    "start",
    "targets_reached",
    "success",
    "fell",
    "fall_xy",
    "fell_past_the_side",
    "landing_max_abs_y_base",
    "landing_max_abs_y_feet",
    "forward_speed_error",
    "yaw_rate_gain",
    *(f"{name}_on_stairs" for name in GAIT_INPUTS),
)
"""Columns of ``stairs-diagnosis.csv``: one row per run."""


def stairs_figure(results: dict[str, list[dict]], course: Course, out_dir: str | Path) -> dict[str, Any]:
    """Draw and write ``stairs-diagnosis.png``/``.json``/``.csv`` and ``stairs-gait.png``
    (:func:`gait_figure`) in ``out_dir`` (:func:`stairs_diagnosis`'s results); returns the paths
    (``gait_png`` the second figure's) and the table."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from krl.analysis.common import write_figure

    geometry = stairs_geometry(course)
    fig, axes = plt.subplots(1, 3, figsize=(13, 4.2), gridspec_kw={"width_ratios": [2.2, 1, 1]})
    colours = dict(zip(results, plt.rcParams["axes.prop_cycle"].by_key()["color"], strict=False))
    _draw_paths(axes[0], results, course, geometry, colours)
    for ax, key, label in (
        (axes[1], "forward_speed_error", "forward speed − commanded [m/s]"),
        (axes[2], "yaw_rate_gain", "mean |yaw rate| / mean |commanded|"),
    ):
        _draw_following(ax, results, key, label, geometry, colours)
    fig.tight_layout()
    rows = [{"policy": label, **row} for label, runs in results.items() for row in runs]
    table = {
        "course": course.name,
        "geometry": geometry,
        "runs": [{key: row.get(key) for key in CSV_COLUMNS} for row in rows],
    }
    written = write_figure(Path(out_dir), "stairs-diagnosis", fig, table, CSV_COLUMNS, rows)
    plt.close(fig)
    written["gait_png"] = gait_figure(results, geometry, colours, Path(out_dir))
    return written


def gait_figure(results, geometry: dict[str, float], colours: dict[str, str], out_dir: Path) -> str:
    """Draw ``stairs-gait.png`` in ``out_dir``: per run (a line each, the policy's colour, x where it fell)
    the ground under the feet, then each of :data:`GAIT_INPUTS` over time. Returns its path."""
    import matplotlib.pyplot as plt

    from krl.util.output import figure_bytes, write_atomic

    units = {"ground": "ground under the feet [m]", "step_height": "step height [m]"}
    units |= {"ride_height": "ride height [m]", "clock_rate": "gait clock rate"}
    fig, axes = plt.subplots(len(units), 1, figsize=(9, 8), sharex=True)
    for ax, (name, label) in zip(axes, units.items(), strict=True):
        for policy, runs in results.items():
            for i, run in enumerate(runs):
                gait = run["gait"]
                ax.plot(
                    gait["time"], gait[name], color=colours[policy], lw=0.8, label=policy if i == 0 else None
                )
                if run["fell"]:
                    ax.plot(gait["time"][-1], gait[name][-1], "x", color=colours[policy], ms=8, mew=2)
        ax.set_ylabel(label, fontsize=8)
        ax.grid(alpha=0.3)
    axes[0].axhline(geometry["landing_height"], color="k", lw=0.8, ls="--")
    axes[0].legend(fontsize=7, loc="upper right")
    axes[0].set_title("what the kernel was asked for on the stairs (nominal unless the agent drives it)")
    axes[-1].set_xlabel("time [s]")
    fig.tight_layout()
    path = out_dir / "stairs-gait.png"
    write_atomic(path, figure_bytes(fig))
    plt.close(fig)
    return str(path)


def _draw_paths(ax, results, course: Course, geometry: dict[str, float], colours: dict[str, str]) -> None:
    """Top view: the stairs' outline, every run's trunk path (x where it fell) and the commanded paths."""
    from matplotlib.patches import Rectangle

    half = geometry["half_width"]
    spans = (
        ("first_riser", "landing_start", "0.85"),
        ("landing_start", "landing_end", "0.7"),
        ("landing_end", "stairs_end", "0.85"),
    )
    for start, end, shade in spans:
        ax.add_patch(
            Rectangle((geometry[start], -half), geometry[end] - geometry[start], 2 * half, color=shade)
        )
    for label, runs in results.items():
        for i, run in enumerate(runs):
            ax.plot(*run["xy"].T, color=colours[label], lw=0.8, label=label if i == 0 else None)
            if run["fell"]:
                ax.plot(*run["xy"][-1], "x", color=colours[label], ms=9, mew=2)
    for lag, style in zip(LAGS, ("--", ":"), strict=True):
        path = course.commanded_path(0, lag)
        ax.plot(path[:, 0], path[:, 1], "k", ls=style, lw=1, label=f"commanded, start 0, lag {lag:g} s")
    ax.plot(*np.array(course.waypoints).T, "o", color="red", ms=5, label="waypoints")
    ax.set(xlabel="x [m]", ylabel="y [m]", aspect="equal", title="stairs course from above (landing dark)")
    ax.legend(fontsize=6, loc="lower left")


def _draw_following(ax, results, key: str, label: str, geometry, colours: dict[str, str]) -> None:
    """One measure of command following (x) against the largest |y| of a foot on the landing (y)."""
    for name, runs in results.items():
        for run in runs:
            if run["landing_max_abs_y_feet"] is not None:
                marker = "x" if run["fell"] else "o"
                ax.plot(run[key], run["landing_max_abs_y_feet"], marker, color=colours[name], ms=7)
    ax.axhline(geometry["half_width"], color="k", lw=1, ls="--")
    ax.text(ax.get_xlim()[0], geometry["half_width"], " side of the landing", fontsize=7, va="bottom")
    ax.set(xlabel=label, ylabel="largest |y| of a foot over the landing [m]", title="first 15 s (x: fell)")
    ax.grid(alpha=0.3)
