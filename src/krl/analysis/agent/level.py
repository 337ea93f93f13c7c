"""Fig. 4.22 (``krl agent study level-base``): does an agent keep its trunk level on slopes?

The thesis added agent-rp's roll and pitch term because agent-base "does not maintain a level base when on
a slope, causing the robot to lose balance and take extreme actions to regain its center of mass". Each
policy walks the sinusoid course and the slope course from their first start, exactly as ``krl evaluate``
walks them (:func:`krl.analysis.agent.trace.trace_course_run`); the figure draws the trunk's roll and pitch
against time, and the table gives their RMS and largest magnitudes with the run's outcome.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from krl.analysis.agent.trace import trace_course_run
from krl.eval.courses import Course
from krl.util.output import csv_bytes, figure_bytes, write_atomic

LEVEL_COURSES: tuple[str, ...] = ("sinusoid", "slope")
"""The courses of the comparison: the sinusoid's 0.2 rad inclines and the slope's 0.15 rad ramps."""

COLUMNS: tuple[str, ...] = (
    "policy",
    "course",
    "roll_rms",
    "pitch_rms",
    "roll_max",
    "pitch_max",
    "targets_reached",
    "targets",
    "fell",
)


def level_runs(policies: dict[str, Path], courses: list[Course]) -> list[dict[str, Any]]:
    """Each policy over each course from its first start: ``{"policy", "course", "time", "roll", "pitch",
    "metrics"}`` (roll and pitch [rad], shape (T,))."""
    runs = []
    for label, path in policies.items():
        for course in courses:
            trace, metrics = trace_course_run(path, course, 0)
            rpy = trace["rpy"]
            runs.append(
                {
                    "policy": label,
                    "course": course.name,
                    "time": trace["time"],
                    "roll": rpy[:, 0],
                    "pitch": rpy[:, 1],
                    "metrics": metrics,
                }
            )
    return runs


def level_table(runs: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per run: RMS and largest |roll| and |pitch| [rad], waypoints reached, fall."""
    rows = []
    for run in runs:
        roll, pitch = np.abs(run["roll"]), np.abs(run["pitch"])
        rows.append(
            {
                "policy": run["policy"],
                "course": run["course"],
                "roll_rms": round(float(np.sqrt(np.mean(roll**2))), 4),
                "pitch_rms": round(float(np.sqrt(np.mean(pitch**2))), 4),
                "roll_max": round(float(roll.max()), 4),
                "pitch_max": round(float(pitch.max()), 4),
                "targets_reached": run["metrics"]["targets_reached"],
                "targets": run["metrics"]["targets"],
                "fell": run["metrics"]["fell"],
            }
        )
    return rows


def write_level_report(runs: list[dict[str, Any]], out: Path, command: str = "") -> list[str]:
    """``level-base.png`` (roll and pitch against time, one row per course), ``level-base.csv`` and
    ``level-base.md`` in ``out``; returns their paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    courses = list(dict.fromkeys(run["course"] for run in runs))
    fig, axes = plt.subplots(len(courses), 2, figsize=(11, 3.0 * len(courses)), squeeze=False)
    for row, course in enumerate(courses):
        for run in (r for r in runs if r["course"] == course):
            for column, angle in enumerate(("roll", "pitch")):
                axes[row, column].plot(run["time"], run[angle], linewidth=0.9, label=run["policy"])
        for column, angle in enumerate(("roll", "pitch")):
            axes[row, column].set_title(f"{course}: trunk {angle}", fontsize=10)
            axes[row, column].set_ylabel("[rad]")
            axes[row, column].grid(alpha=0.3)
    for axis in axes[-1]:
        axis.set_xlabel("time [s]")
    axes[0, 0].legend(fontsize=8)
    fig.tight_layout()
    out.mkdir(parents=True, exist_ok=True)
    write_atomic(out / "level-base.png", figure_bytes(fig))
    plt.close(fig)
    rows = level_table(runs)
    write_atomic(out / "level-base.csv", csv_bytes(COLUMNS, rows))
    lines = ["# Agent study level-base (Fig. 4.22)", ""]
    if command:
        lines += ["Made by:", "", f"    {command}", ""]
    lines += [
        "Trunk roll and pitch while walking each course from its first start; RMS and largest magnitude",
        "[rad]. The thesis: agent-base tilts on slopes and loses balance; the roll and pitch term (agent-rp)",
        "keeps it level.",
        "",
        "| policy | course | roll RMS | pitch RMS | largest roll | largest pitch | targets | fell |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for r in rows:
        angles = " | ".join(f"{r[key]:.3f}" for key in ("roll_rms", "pitch_rms", "roll_max", "pitch_max"))
        outcome = f"{r['targets_reached']}/{r['targets']} | {'yes' if r['fell'] else 'no'}"
        lines.append(f"| {r['policy']} | {r['course']} | {angles} | {outcome} |")
    lines += ["", "![roll and pitch against time](level-base.png)", ""]
    write_atomic(out / "level-base.md", "\n".join(lines))
    return [str(out / name) for name in ("level-base.md", "level-base.csv", "level-base.png")]
