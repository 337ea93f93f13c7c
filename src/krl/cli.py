"""The ``krl`` command. ``krl --help`` lists the subcommands; every error is one line on stderr."""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Sequence
from typing import Any

EXIT_USAGE = 2


class CliError(Exception):
    """A user-facing error: printed as ``krl: error: <message>`` with exit status 2."""


def emit(result: dict[str, Any], as_json: bool) -> None:
    """Print a command's result: indented JSON, or one ``key: value`` line per entry (a nested mapping
    indented under its key, a list of mappings one item per line)."""
    if as_json:
        print(json.dumps(result, indent=2))
    else:
        print("\n".join(_text_lines(result, "")))


def _text_lines(result: dict[str, Any], indent: str) -> list[str]:
    lines = []
    for key, value in result.items():
        if isinstance(value, dict):
            lines += [f"{indent}{key}:", *_text_lines(value, indent + "  ")]
        elif isinstance(value, list) and value and all(isinstance(item, dict) for item in value):
            lines.append(f"{indent}{key}:")
            lines += [f"{indent}  - " + ", ".join(f"{k}: {v}" for k, v in item.items()) for item in value]
        else:
            lines.append(f"{indent}{key}: {value}")
    return lines


def _parse_params(items: Sequence[str] | None) -> dict[str, Any]:
    """``["max_height=0.04", "num_steps=6"]`` -> ``{"max_height": 0.04, "num_steps": 6}``."""
    params: dict[str, Any] = {}
    for item in items or ():
        key, sep, text = item.partition("=")
        if not sep or not key:
            raise CliError(f"--param expects KEY=VALUE, got {item!r}")
        try:
            value: Any = int(text)
        except ValueError:
            try:
                value = float(text)
            except ValueError:
                value = text
        params[key.strip()] = value
    return params


def _add_terrain_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--terrain", default="flat", help="terrain name (see `krl terrains`)")
    parser.add_argument(
        "--param", action="append", metavar="KEY=VALUE", help="terrain parameter override (repeatable)"
    )
    parser.add_argument(
        "--seed", type=int, default=0, help="seed of the run's random draws (terrain, waypoints)"
    )


def _build_sim(args: argparse.Namespace):
    from krl.sim.model import build_model
    from krl.sim.robot import A1Sim

    return A1Sim(build_model(args.terrain, _parse_params(args.param), args.seed))


def _settle(sim, seconds: float) -> None:
    from krl.robots.a1.constants import STANDING_JOINT_ANGLES
    from krl.timing import CONTROL_DT

    for _ in range(round(seconds / CONTROL_DT)):
        sim.step(STANDING_JOINT_ANGLES)


def cmd_terrains(args: argparse.Namespace) -> int:
    from krl.sim.terrains import TERRAIN_NAMES, terrain_param_defaults

    for name in TERRAIN_NAMES:
        defaults = ", ".join(f"{key}={value}" for key, value in terrain_param_defaults(name).items())
        print(f"{name:18s} {defaults}")
    return 0


def cmd_render(args: argparse.Namespace) -> int:
    from krl.sim.render import CameraView, FrameRenderer, write_png

    if args.course:
        import numpy as np

        from krl.eval.courses import load_course
        from krl.sim.robot import A1Sim

        course = load_course(args.course)
        sim = A1Sim(course.build(markers=True))
        x, y, yaw = course.starts[0]
        sim.reset(xy=(x, y), yaw=yaw)
        points = np.array([*course.waypoints, *(s[:2] for s in course.starts)])
        low, high = points.min(axis=0), points.max(axis=0)
        centre = (*((low + high) / 2), float(sim.terrain.height(*((low + high) / 2))))
        distance = 0.8 * float(np.max(high - low)) + 1.5 if args.distance is None else args.distance
        elevation = -35.0 if args.elevation is None else args.elevation
        view = CameraView(distance, args.azimuth, elevation, lookat=centre)
    else:
        sim = _build_sim(args)
        distance = 3.0 if args.distance is None else args.distance
        view = CameraView(distance, args.azimuth, -25.0 if args.elevation is None else args.elevation)
    _settle(sim, args.settle)
    with FrameRenderer(sim.model, args.width, args.height, view) as renderer:
        image = renderer.render(sim.data)
    path = write_png(image, args.out)
    print(f"wrote {path} ({args.width}x{args.height}, terrain {sim.terrain.name}, t={sim.time:.2f} s)")
    return 0


def cmd_view(args: argparse.Namespace) -> int:
    from krl.sim.render import has_display

    if not has_display():
        raise CliError(
            "`krl view` needs a display (DISPLAY/WAYLAND_DISPLAY is unset); on a headless machine use "
            "`krl render --terrain NAME --out FILE.png`"
        )
    import mujoco.viewer

    from krl.robots.a1.constants import STANDING_JOINT_ANGLES
    from krl.timing import CONTROL_DT

    sim = _build_sim(args)
    with mujoco.viewer.launch_passive(sim.model, sim.data) as viewer:
        while viewer.is_running():
            start = time.perf_counter()
            sim.step(STANDING_JOINT_ANGLES)
            viewer.sync()
            time.sleep(max(0.0, CONTROL_DT - (time.perf_counter() - start)))
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    if args.target == "sim":
        from krl.bench.sim import bench_sim

        result = bench_sim(steps=args.steps, repeats=args.repeats)
    elif args.target == "mpc":
        from krl.bench.mpc import bench_mpc

        result = bench_mpc(seconds=args.seconds)
    else:  # argparse restricts the choices
        raise CliError(f"unknown benchmark {args.target!r}")
    emit(result, args.json)
    return 0


def _parse_vector(text: str, size: int, what: str) -> list[float]:
    try:
        values = [float(part) for part in text.split(",")]
    except ValueError:
        raise CliError(f"{what} expects {size} comma-separated numbers, got {text!r}") from None
    if len(values) != size:
        raise CliError(f"{what} expects {size} comma-separated numbers, got {text!r}")
    return values


def add_expert_arguments(parser: argparse.ArgumentParser) -> None:
    """The MPC expert's settings, shared by every command that runs the expert."""
    parser.add_argument("--gait", default="trot", help="gait of Table 4.1 (walk, trot, bound)")
    parser.add_argument("--stance-duration", type=float, default=0.2, help="τ_stance [s]")
    parser.add_argument("--step-height", type=float, default=0.08, help="swing apex height [m], 0.05-0.18")
    parser.add_argument("--ride-height", type=float, default=0.25, help="base height [m], 0.18-0.28")


def expert_params_from_args(args: argparse.Namespace):
    """ExpertParams from :func:`add_expert_arguments`' options (validated by ExpertParams)."""
    from krl.control.expert import ExpertParams

    return ExpertParams(
        gait=args.gait,
        stance_duration=args.stance_duration,
        step_height=args.step_height,
        ride_height=args.ride_height,
    )


def add_run_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of every ``… run`` command: waypoints or a fixed command, video, JSON."""
    _add_terrain_arguments(parser)
    parser.add_argument(
        "--targets", type=int, default=5, help="number of random waypoints (seeded by --seed)"
    )
    parser.add_argument("--target", action="append", metavar="X,Y", help="a given waypoint (repeatable)")
    parser.add_argument("--target-time-limit", type=float, default=40.0, help="time allowed per waypoint [s]")
    parser.add_argument(
        "--command", metavar="VX,VY,WZ", help="walk at a fixed command instead of to waypoints"
    )
    parser.add_argument("--duration", type=float, default=10.0, help="with --command: run length [s]")
    parser.add_argument("--video", help="write an MP4 of the run")
    parser.add_argument("--json", action="store_true", help="print JSON")


def run_controller(args: argparse.Namespace, controller, step_hook=None) -> dict[str, Any]:
    """Run ``controller`` as :func:`add_run_arguments`' options say; returns the summary printed by ``run``.

    ``step_hook()`` is called after every control step (e.g. to collect timings).
    """
    import numpy as np

    from krl.runner import Runner, random_targets

    sim = _build_sim(args)
    recorder = None
    if args.video:
        from krl.sim.video import VideoRecorder

        recorder = VideoRecorder(sim, args.video)

    def on_step(record) -> None:
        if step_hook is not None:
            step_hook()
        if recorder is not None:
            recorder.capture()

    runner = Runner(sim, controller, on_step=on_step)
    try:
        if args.command is not None:
            command = np.array(_parse_vector(args.command, 3, "--command"))
            result = runner.hold_command(command, args.duration)
            targets = np.zeros((0, 2))
        else:
            if args.target:
                targets = np.array([_parse_vector(t, 2, "--target") for t in args.target])
            else:
                targets = random_targets(np.random.default_rng(args.seed), args.targets, sim.terrain.spawn_xy)
            result = runner.walk_to(targets, target_time_limit=args.target_time_limit)
    finally:
        if recorder is not None:
            recorder.close()
    summary: dict[str, Any] = {
        "targets": len(targets),
        "targets_reached": result.targets_reached,
        "fell": result.fell,
        "timed_out": result.timed_out,
        "sim_seconds": round(result.sim_seconds, 3),
        "wall_seconds": round(result.wall_seconds, 3),
        "real_time_factor": round(result.sim_seconds / max(result.wall_seconds, 1e-9), 2),
        "mean_velocity": [round(v, 4) for v in result.mean_velocity()],
        "terrain": sim.terrain.name,
    }
    if args.video:
        summary["video"] = str(args.video)
    return summary


def cmd_expert_run(args: argparse.Namespace) -> int:
    import numpy as np

    from krl.control.expert import MPCExpert

    expert = MPCExpert(expert_params_from_args(args))
    mpc_times: list[float] = []
    summary = run_controller(args, expert, lambda: mpc_times.append(expert.last.mpc_seconds))
    summary["mpc_ms_median"] = round(float(np.median(mpc_times)) * 1e3, 4) if mpc_times else None
    summary["mpc_failures"] = expert.mpc_failures
    emit(summary, args.json)
    return 0


def build_parser() -> argparse.ArgumentParser:
    from krl import __version__

    parser = argparse.ArgumentParser(
        prog="krl",
        description="Kernel-based residual learning for quadruped locomotion (Unitree A1, MuJoCo).",
    )
    parser.add_argument("--version", action="version", version=f"krl {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("terrains", help="list the terrains and their default parameters")
    p.set_defaults(func=cmd_terrains)

    p = sub.add_parser("render", help="render the robot standing on a terrain to a PNG (headless)")
    _add_terrain_arguments(p)
    p.add_argument("--out", required=True, help="output PNG path")
    p.add_argument("--width", type=int, default=960)
    p.add_argument("--height", type=int, default=640)
    p.add_argument("--settle", type=float, default=0.5, help="seconds of standing before the frame [s]")
    p.add_argument(
        "--course", help="render a course (name or file) from above, waypoints as red posts, robot at start 0"
    )
    p.add_argument("--distance", type=float, help="camera distance [m] (default 3; a course: fitted)")
    p.add_argument("--azimuth", type=float, default=135.0, help="camera azimuth [deg]")
    p.add_argument("--elevation", type=float, help="camera elevation [deg] (default -25; -35 for a course)")
    p.set_defaults(func=cmd_render)

    p = sub.add_parser("view", help="open MuJoCo's interactive viewer on a terrain (needs a display)")
    _add_terrain_arguments(p)
    p.set_defaults(func=cmd_view)

    p = sub.add_parser("bench", help="run a benchmark and print its figures")
    p.add_argument("target", choices=["sim", "mpc"], help="what to benchmark")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.add_argument("--steps", type=int, default=1000, help="sim: control steps per timed loop")
    p.add_argument("--repeats", type=int, default=7, help="sim: alternating timed loops per variant")
    p.add_argument("--seconds", type=float, default=20.0, help="mpc: simulated seconds of walking")
    p.set_defaults(func=cmd_bench)

    expert = sub.add_parser("expert", help="the convex-MPC expert").add_subparsers(
        dest="expert_command", required=True, metavar="EXPERT_COMMAND"
    )
    p = expert.add_parser("run", help="walk the expert to waypoints or at a fixed command")
    add_run_arguments(p)
    add_expert_arguments(p)
    p.set_defaults(func=cmd_expert_run)

    from krl.analysis import expert_plots

    p = expert.add_parser("plot", help="the expert's analysis figures (Figs. 4.8, 4.15, A.2, A.3)")
    expert_plots.add_arguments(p)
    p.set_defaults(func=expert_plots.run)

    from krl.kernel import cli as kernel_cli

    kernel_cli.register(sub)

    from krl.data import collect

    p = sub.add_parser("collect", help="collect expert data for the kernel (Section 4.2.6.2)")
    collect.add_arguments(p)
    p.set_defaults(func=collect.run)

    from krl.eval import cli as eval_cli

    p = sub.add_parser("evaluate", help="score controllers on the courses or the push sweep (resumable)")
    eval_cli.add_evaluate_arguments(p)
    p.set_defaults(func=eval_cli.run_evaluate)
    p = sub.add_parser("report", help="Tables 5.1-5.5 and the evaluation plots from krl evaluate's results")
    eval_cli.add_report_arguments(p)
    p.set_defaults(func=eval_cli.run_report)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``krl`` command; returns the exit status."""
    parser = build_parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    args = parser.parse_args(argv)
    args.argv = argv
    from krl.eval.evaluate import EvaluationError
    from krl.sim.render import RenderError
    from krl.sim.robot import SimulationUnstableError

    try:
        return args.func(args)
    except (CliError, ValueError, RenderError, SimulationUnstableError, EvaluationError, OSError) as error:
        print(f"krl: error: {error}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("krl: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
