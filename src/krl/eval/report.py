"""``krl report``: the thesis's Tables 5.1-5.5 and the evaluation plots from stored ``krl evaluate`` results.

Reads each controller's records in ``RESULTS/<controller>/`` (:func:`krl.eval.records.read_runs`: its
Parquet parts, or the older layout's JSON files) and writes, into ``OUT``: ``evaluation.md`` (every table, the
thesis's numbers beside ours, the commands that made the results), one CSV per table, ``courses.png``
(success and fall rate per course and controller) and, from ``krl.eval.sweep_report``, the push sweep's
(``push.png``: success rate against push magnitude; ``push-direction.csv``) and the friction sweep's
(``friction.png``: success rate against ground friction) sections.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from krl.eval.courses import THESIS_COURSES
from krl.eval.evaluate import FRICTION_DIR, PUSH_DIR, STAIR_DIR
from krl.eval.records import labels_in, read_runs
from krl.eval.summaries import summarise_course, summarise_course_by_seed
from krl.eval.sweep_report import write_sweep_sections
from krl.eval.tables import controller_table, rows_csv
from krl.util.output import distinct_colours, figure_bytes, write_atomic
from krl.util.thesis import THESIS_NAMES

TABLE_NUMBERS = {"tabletop": "5.1", "seesaw": "5.2", "stairs": "5.3", "sinusoid": "5.4"}

# Tables 5.1-5.4: reward/step (mean, std), targets (mean, std), success rate, fall rate
THESIS_COURSES_RESULTS: dict[str, dict[str, tuple[float, float, float, float, float, float]]] = {
    "tabletop": {
        "MPC (τ_stance=0.3)": (0.013, 0.072, 0.25, 0.5, 0.0, 1.0),
        "MPC (τ_stance=0.2)": (0.016, 0.11, 2.5, 2.89, 0.5, 0.5),
        "Kernel": (0.065, 0.0085, 2.25, 1.5, 0.0, 1.0),
        "Agent-base": (0.091, 0.0076, 4.5, 1.1, 0.8125, 0.1875),
        "Agent-rp": (0.097, 0.001, 5.0, 0.0, 1.0, 0.0),
    },
    "seesaw": {
        "MPC (τ_stance=0.3)": (0.041, 0.0722, 0.0, 0.0, 0.0, 1.0),
        "MPC (τ_stance=0.2)": (0.065, 0.018, 0.0, 0.0, 0.0, 1.0),
        "Kernel": (0.043, 0.00245, 0.0, 0.0, 0.0, 1.0),
        "Agent-base": (0.087, 0.0024, 5.0, 0.0, 1.0, 0.0),
        "Agent-rp": (0.091, 0.0006, 5.0, 0.0, 1.0, 0.0),
    },
    "stairs": {
        "MPC (τ_stance=0.3)": (0.067, 0.00098, 0.0, 0.0, 0.0, 1.0),
        "MPC (τ_stance=0.2)": (0.073, 0.0022, 0.0, 0.0, 0.0, 1.0),
        "Kernel": (0.047, 0.0019, 0.0, 0.0, 0.0, 0.0),
        "Agent-base": (0.078, 0.0046, 2.25, 1.8, 0.25, 0.75),
        "Agent-rp": (0.089, 0.0024, 4.75, 1.0, 0.9375, 0.0625),
    },
    "sinusoid": {
        "MPC (τ_stance=0.3)": (0.07, 0.0078, 0.5, 1.0, 0.0, 1.0),
        "MPC (τ_stance=0.2)": (0.082, 0.0057, 3.0, 1.83, 0.25, 0.75),
        "Kernel": (0.042, 0.0021, 0.0, 0.0, 0.0, 0.0),
        "Agent-base": (0.081, 0.006, 3.87, 1.4, 0.5, 0.5),
        "Agent-rp": (0.089, 0.0026, 4.75, 1.0, 0.9375, 0.0625),
    },
}


def collect(
    results: Path, controllers: Sequence[str] | None = None
) -> dict[str, dict[str, list[dict[str, Any]]]]:
    """``{controller: {course or "push": [records]}}`` from a results directory."""
    if not results.is_dir():
        raise FileNotFoundError(f"no results directory {str(results)!r} (run `krl evaluate` first)")
    found: dict[str, dict[str, list[dict[str, Any]]]] = {}
    for label in controllers or labels_in(results):
        directory = results / label
        if not directory.is_dir():
            raise FileNotFoundError(f"no results for controller {label!r} in {str(results)!r}")
        groups: dict[str, list[dict[str, Any]]] = {}
        for run, stored in read_runs(directory, label).items():
            groups.setdefault(run.partition("/")[0], []).append(stored.record)
        found[label] = groups
    return found


def _fmt(value: float | None, digits: int = 3) -> str:
    if value is None:
        return "–"
    return f"{value:.{digits}g}"


def _pm(mean: float, std: float) -> str:
    return f"{_fmt(mean)} ± {_fmt(std, 2)}"


def course_rows(found: dict[str, dict[str, list[dict[str, Any]]]], course: str) -> list[dict[str, Any]]:
    """One row per controller with results on ``course``, then the thesis's rows."""
    rows = []
    for label, groups in found.items():
        if course in groups:
            summary = summarise_course(groups[course])
            rows.append({"source": "krl", "controller": label, **summary})
    for name, values in THESIS_COURSES_RESULTS.get(course, {}).items():
        reward, reward_std, targets, targets_std, success, fall = values
        rows.append(
            {
                "source": "thesis",
                "controller": name,
                "runs": 16 if name.startswith("Agent") else 4,
                "targets": 5,
                "reward_per_step_mean": reward,
                "reward_per_step_std": reward_std,
                "targets_reached_mean": targets,
                "targets_reached_std": targets_std,
                "success_rate": success,
                "fall_rate": fall,
            }
        )
    return rows


def _course_markdown(course: str, rows: list[dict[str, Any]]) -> str:
    number = TABLE_NUMBERS.get(course)
    title = f"Table {number}: {course}" if number else f"Course: {course}"
    lines = [
        f"### {title}",
        "",
        "| source | controller | runs | reward/step | targets reached | success rate | fall rate |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    for row in rows:
        name = row["controller"]
        if row["source"] == "krl" and name in THESIS_NAMES:
            name = f"{name} ({THESIS_NAMES[name]})"
        lines.append(
            f"| {row['source']} | {name} | {row['runs']} | "
            f"{_pm(row['reward_per_step_mean'], row['reward_per_step_std'])} | "
            f"{_pm(row['targets_reached_mean'], row['targets_reached_std'])} of {row['targets']} | "
            f"{row['success_rate']:.2f} | {row['fall_rate']:.2f} |"
        )
    return "\n".join(lines) + "\n"


def seed_rows(found: dict[str, dict[str, list[dict[str, Any]]]], course: str) -> list[dict[str, Any]]:
    """One row per (seed group, training seed) with results on ``course``: the spread behind a group's row."""
    return [
        {"controller": label, **row}
        for label, groups in found.items()
        for row in summarise_course_by_seed(groups.get(course, []))
    ]


def _seed_markdown(rows: list[dict[str, Any]]) -> str:
    """Each seed group's runs by training seed: successes of runs, falls, mean waypoints reached."""
    seeds = sorted({row["seed"] for row in rows})

    def cell(r: dict[str, Any]) -> str:
        runs = r["runs"]
        successes, falls = round(r["success_rate"] * runs), round(r["fall_rate"] * runs)
        return f"{successes}/{runs}, {falls} fell, {r['targets_reached_mean']:.2f}"

    lines = [
        "By training seed (successes of runs, falls, mean waypoints reached):",
        "",
        *controller_table(rows, "seed", seeds, [f"seed {seed}" for seed in seeds], cell),
    ]
    return "\n".join(lines) + "\n"


def _plot_courses(path: Path, tables: dict[str, list[dict[str, Any]]]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    courses = list(tables)
    labels = sorted({row["controller"] for rows in tables.values() for row in rows if row["source"] == "krl"})
    colours = distinct_colours(len(labels))
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), sharey=True)
    width = 0.8 / max(len(labels), 1)
    x = np.arange(len(courses))
    for axis, key, title in ((axes[0], "success_rate", "success rate"), (axes[1], "fall_rate", "fall rate")):
        for index, label in enumerate(labels):
            values = [
                next((r[key] for r in tables[c] if r["source"] == "krl" and r["controller"] == label), np.nan)
                for c in courses
            ]
            offset = (index - (len(labels) - 1) / 2) * width
            axis.bar(x + offset, values, width, label=label, color=colours[index])
            for position in (x + offset)[np.isnan(values)]:  # not run, which a bar of 0 would hide
                axis.text(position, 0.01, "not run", rotation=90, ha="center", va="bottom", fontsize=6)
        axis.set_xticks(x, courses, rotation=30, ha="right")
        axis.set_title(title)
        axis.set_ylim(0, 1.05)
    axes[1].legend(fontsize=8, loc="upper right")
    fig.tight_layout()
    write_atomic(path, figure_bytes(fig))
    plt.close(fig)


def write_report(results: Path, out: Path, controllers: Sequence[str] | None, command: str) -> dict[str, Any]:
    """Write the tables and plots; returns what was written and the summary rows."""
    found = collect(results, controllers)
    course_names = [c for c in THESIS_COURSES if any(c in g for g in found.values())]
    sweeps = {PUSH_DIR, FRICTION_DIR, STAIR_DIR}
    course_names += sorted({c for g in found.values() for c in g} - set(THESIS_COURSES) - sweeps)
    tables = {course: course_rows(found, course) for course in course_names}
    if not tables and not any(sweeps & set(groups) for groups in found.values()):
        raise FileNotFoundError(f"no evaluation results in {str(results)!r}")
    written = []
    parts = [
        "# Evaluation results\n",
        "Made by:\n",
        f"    {command}\n",
        "from the results of:\n",
    ]
    commands: dict[str, None] = {}  # one line per command, though several controllers ran in it
    for label in found:
        commands_file = results / label / "commands.txt"
        if commands_file.exists():
            commands.update(dict.fromkeys(commands_file.read_text().splitlines()))
    parts += [f"    {line}" for line in commands]
    parts.append("")
    parts.append(
        "Reward/step: the final reward (Table 4.8 plus the roll/pitch term, `krl.task.reward`) summed over "
        "the run and divided by its control steps; mean ± sample std over runs. Targets reached: of the "
        "course's 5. Success: every waypoint reached; fall: the robot fell (or the run ended in an error).\n"
    )
    for course, rows in tables.items():
        parts.append(_course_markdown(course, rows))
        path = out / f"course-{course}.csv"
        write_atomic(path, rows_csv(rows))
        written.append(str(path))
        by_seed = seed_rows(found, course)
        if by_seed:
            parts.append(_seed_markdown(by_seed))
            path = out / f"course-{course}-seeds.csv"
            write_atomic(path, rows_csv(by_seed))
            written.append(str(path))
    sweep_parts, sweep_written, pushes, frictions, stairs = write_sweep_sections(found, out)
    parts += sweep_parts
    written += sweep_written
    if tables:
        _plot_courses(out / "courses.png", tables)
        written.append(str(out / "courses.png"))
        parts.append("![success and fall rate per course](courses.png)\n")
    markdown = out / "evaluation.md"
    write_atomic(markdown, "\n".join(parts))
    written.insert(0, str(markdown))
    ours = [r for r in pushes if r["source"] == "krl"]
    return {"written": written, "courses": tables, "push": ours, "friction": frictions, "stair_sweep": stairs}
