"""``krl demo``: the shipped agent over a thesis course beside the kernel alone and the MPC expert.

Each controller walks the course (the stairs by default) from one start; the demo writes, into its output
folder, a video of the first controller's walk (the agent's), a top-down plot of every controller's path
with the waypoints (``path.png``), and a table of the runs' metrics (``metrics.md``, ``metrics.csv``). The
runs are those of ``krl evaluate`` (:func:`krl.eval.episodes.score_walk`): same courses, same reward, same
scoring. The controllers run on worker processes (:mod:`krl.util.parallel`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from krl.util.output import csv_bytes, figure_bytes, write_atomic

DEMO_CONTROLLERS: tuple[str, ...] = ("agent", "kernel", "expert")
"""What the demo compares, in order (``krl evaluate`` specs); the first one is filmed."""

TABLE_COLUMNS: tuple[str, ...] = (
    "controller",
    "targets_reached",
    "targets",
    "success",
    "fell",
    "reward_per_step",
    "time_to_finish",
    "distance_walked",
)


@dataclass(frozen=True)
class DemoRun:
    """One controller's walk (plain data: it travels to a worker)."""

    spec: Any
    """:class:`krl.eval.controllers.ControllerSpec`."""
    course: Any
    """:class:`krl.eval.courses.Course`."""
    start: int
    filmed: bool
    """Log the walk's frames (:class:`krl.sim.video.FrameLog`) for :func:`film`."""


def run_demo_walk(run: DemoRun) -> dict[str, Any]:
    """Walk one controller over the course (in a worker); its metrics, path (x, y, z) [m] and, when
    filmed, its frames' joint positions (``qpos``)."""
    from krl.eval.episodes import score_walk
    from krl.sim.robot import A1Sim
    from krl.sim.video import FrameLog

    trace: list[np.ndarray] = []
    course = run.course
    sim = A1Sim(course.build())
    frames = FrameLog(sim) if run.filmed else None
    metrics = score_walk(
        sim,
        run.spec.build(),
        np.array(course.waypoints),
        course.starts[run.start],
        course.time_limit,
        course.d_min,
        trace=trace,
        frames=frames,
    )
    result = {"label": run.spec.driven_label, "metrics": metrics, "path": np.array(trace).tolist()}
    if frames is not None:
        result["qpos"] = frames.qpos
    return result


def film(course, result: dict[str, Any], path: str, progress: bool, say: Callable[[str], None] | None) -> str:
    """Render a filmed walk's frames into the MP4 ``path``, with a bar over the frames (and the time left);
    ``say`` first hears how many frames and seconds of walking it films. Returns ``path``."""
    from krl.sim.video import VIDEO_FPS, write_video
    from krl.util.progress import progress_bar

    frames = result["qpos"]
    if say is not None:
        say(
            f"filming {result['label']}: {len(frames)} frames ({len(frames) / VIDEO_FPS:.0f} s of walking), "
            "rendered in software; the bar shows the time left"
        )
    with progress_bar(progress, unit="frames") as bar:
        task = bar.add_task(f"filming {result['label']}", total=len(frames))
        write_video(course.build().model, frames, path, on_frame=lambda _: bar.advance(task))
    return path


def available_controllers(names: tuple[str, ...] | None = None) -> tuple[list[Any], list[str]]:
    """The specs of ``names`` (a :class:`~krl.eval.controllers.ControllerSpecError` for one that cannot be
    built), or of :data:`DEMO_CONTROLLERS` when None: those that can be built here, and one note per one
    that cannot (no shipped agent)."""
    from krl.eval.controllers import ControllerSpecError, parse_controller

    if names is not None:
        return [parse_controller(name) for name in names], []
    specs, notes = [], []
    for name in DEMO_CONTROLLERS:
        try:
            specs.append(parse_controller(name))
        except ControllerSpecError as error:
            notes.append(f"skipped {name}: {error}")
    if not specs:
        raise ValueError("the demo has no controller to run: " + "; ".join(notes))
    return specs, notes


def make_demo(
    out: str | Path,
    course: str = "stairs",
    start: int = 0,
    controllers: tuple[str, ...] | None = None,
    video: bool = True,
    workers: int = 2,
    progress: bool = True,
    say: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """Run the demo (module docstring); returns the summary printed by ``krl demo``. ``controllers``
    (``krl evaluate`` specs, the first filmed) must all build, else ValueError before anything is written;
    None runs those of :data:`DEMO_CONTROLLERS` that build here. ``say(note)`` hears each note (a skipped
    controller, no video) before the walks start, which take minutes, and what the filming, which takes
    minutes more, will render."""
    from krl.eval.courses import load_course
    from krl.util.parallel import run_jobs

    out = Path(out)
    loaded = load_course(course)
    if not 0 <= start < len(loaded.starts):
        raise ValueError(f"course {loaded.name} has starts 0-{len(loaded.starts) - 1}, not {start}")
    specs, notes = available_controllers(controllers)
    if video:
        from krl.sim.render import rendering_problem

        problem = rendering_problem()
        if problem is not None:
            video = False
            notes.append(f"no video: {problem}")
    for note in notes if say is not None else ():
        say(note)
    out.mkdir(parents=True, exist_ok=True)
    runs = [DemoRun(spec, loaded, start, video and index == 0) for index, spec in enumerate(specs)]
    results = run_jobs(run_demo_walk, runs, workers=workers, progress="walking" if progress else None)
    video_path = str(out / f"{specs[0].driven_label}-{loaded.name}.mp4")
    film_path = film(loaded, results[0], video_path, progress, say) if video else None
    rows = [_row(result) for result in results]
    write_atomic(out / "metrics.csv", csv_bytes(TABLE_COLUMNS, rows))
    write_atomic(out / "metrics.md", _markdown(loaded, start, rows, notes))
    write_atomic(out / "path.png", _path_figure(loaded, start, results))
    files = {"path": str(out / "path.png"), "metrics": str(out / "metrics.md")}
    if film_path is not None:
        files["video"] = film_path
    return {"course": loaded.name, "start": start, "runs": rows, "files": files, "notes": notes}


def _row(result: dict[str, Any]) -> dict[str, Any]:
    metrics = result["metrics"]
    return {"controller": result["label"], **{key: metrics[key] for key in TABLE_COLUMNS[1:]}}


def _markdown(course, start: int, rows: list[dict[str, Any]], notes: list[str]) -> str:
    lines = [
        f"# krl demo: course {course.name}, start {start}",
        "",
        "| " + " | ".join(TABLE_COLUMNS) + " |",
        "| " + " | ".join("---" for _ in TABLE_COLUMNS) + " |",
    ]
    for row in rows:
        cells = [f"{v:.4g}" if isinstance(v, float) else ("–" if v is None else str(v)) for v in row.values()]
        lines.append("| " + " | ".join(cells) + " |")
    lines += ["", "reward_per_step: the evaluation's reward (Table 4.8 + roll/pitch), per control step;"]
    lines += ["time_to_finish [s], distance_walked [m]."]
    lines += [f"- {note}" for note in notes]
    return "\n".join(lines) + "\n"


def _path_figure(course, start: int, results: list[dict[str, Any]]) -> bytes:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 5.2))
    waypoints = np.array(course.waypoints)
    for index, (x, y) in enumerate(waypoints):
        ax.add_patch(plt.Circle((x, y), course.d_min, color="tab:red", alpha=0.15))
        ax.annotate(str(index + 1), (x, y), ha="center", va="center", fontsize=9, color="tab:red")
    x0, y0, _ = course.starts[start]
    ax.plot([x0], [y0], marker="s", color="black", linestyle="none", label="start")
    for result in results:
        path = np.array(result["path"]).reshape(-1, 3)
        (line,) = ax.plot(path[:, 0], path[:, 1], linewidth=1.4, label=result["label"])
        if result["metrics"]["fell"] or result["metrics"]["error"]:
            ax.plot(
                path[-1, 0],
                path[-1, 1],
                marker="x",
                markersize=12,
                markeredgewidth=2.5,
                color=line.get_color(),
            )
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(f"{course.name}: paths from start {start} (x: fell), waypoints within D_min")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    fig.tight_layout()
    data = figure_bytes(fig)
    plt.close(fig)
    return data
