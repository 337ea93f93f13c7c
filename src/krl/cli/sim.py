"""``krl terrains``, ``krl render``, ``krl view`` and ``krl bench``: the simulator on its own."""

from __future__ import annotations

import argparse

from krl.cli.common import CliError, add_terrain_arguments, build_sim, default_of, emit, given, parse_ints


def _settle(sim, seconds: float) -> None:
    from krl.robots.a1.constants import STANDING_JOINT_ANGLES
    from krl.util.timing import CONTROL_DT

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
        sim = build_sim(args)
        distance = 3.0 if args.distance is None else args.distance
        view = CameraView(distance, args.azimuth, -25.0 if args.elevation is None else args.elevation)
    _settle(sim, args.settle)
    with FrameRenderer(sim.model, args.width, args.height, view) as renderer:
        image = renderer.render(sim.data)
    path = write_png(image, args.out)
    print(f"wrote {path} ({args.width}x{args.height}, terrain {sim.terrain.name}, t={sim.time:.2f} s)")
    return 0


def cmd_view(args: argparse.Namespace) -> int:
    from krl.apps.viewer import window_problem

    if args.duration is not None and not args.duration > 0:
        raise CliError(f"--duration must be > 0 s, got {args.duration:g}")
    problem = window_problem()
    if problem is not None:
        raise CliError(problem)
    from krl.apps.viewer import LiveSession, StandingController, run_viewer
    from krl.eval.controllers import parse_controller
    from krl.sim.robot import A1Sim

    controller = parse_controller(args.controller).build() if args.controller else StandingController()
    if args.course:
        from krl.eval.courses import load_course

        course = load_course(args.course)
        sim = A1Sim(course.build(markers=True))
        session = LiveSession(sim, controller, course.waypoints, course.starts[0], course.d_min)
    else:
        session = LiveSession(build_sim(args), controller)
    run_viewer(session, args.duration)
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    if args.target == "sim":
        from krl.bench.sim import bench_sim

        result = bench_sim(**given(steps=args.steps, repeats=args.repeats))
    elif args.target == "terrains":
        from krl.bench.terrains import bench_terrains

        try:
            result = bench_terrains(**given(terrains=args.terrain, steps=args.steps, repeats=args.repeats))
        except ValueError as error:
            raise CliError(str(error)) from None
    elif args.target == "mpc":
        from krl.bench.mpc import bench_mpc

        result = bench_mpc(**given(seconds=args.seconds))
    elif args.target == "evaluate":
        from krl.bench.evaluate import bench_evaluate

        seeds = None if args.seeds is None else tuple(parse_ints(args.seeds, "--seeds"))
        options = given(controller=args.controller, courses=args.course, seeds=seeds, repeats=args.repeats)
        result = bench_evaluate(**options, **given(push_attempts=args.push_attempts))
    elif args.target == "agent":
        from krl.bench.agent import bench_agent

        options = given(num_envs=args.num_envs, steps=args.steps, repeats=args.repeats)
        if args.config:
            from krl.agent.config import AgentConfig

            options["config"] = AgentConfig.load(args.config)
        if args.update_threads is not None and args.update_threads < 1:
            raise CliError(f"--update-threads must be at least 1, got {args.update_threads}")
        result = bench_agent(
            **options, **given(train_steps=args.train_steps, update_threads=args.update_threads)
        )
    else:  # argparse restricts the choices
        raise CliError(f"unknown benchmark {args.target!r}")
    emit(result, args.json)
    return 0


def register(subparsers) -> None:
    """Add ``krl terrains``, ``render``, ``view`` and ``bench`` to the main parser's subcommands."""
    p = subparsers.add_parser("terrains", help="list the terrains and their default parameters")
    p.set_defaults(func=cmd_terrains)
    _add_render(subparsers)
    _add_view(subparsers)
    _add_bench(subparsers)


def _add_render(subparsers) -> None:
    """``krl render``."""
    p = subparsers.add_parser("render", help="render the robot standing on a terrain to a PNG (headless)")
    add_terrain_arguments(p)
    p.add_argument("--out", required=True, help="output PNG path")
    p.add_argument("--width", type=int, default=960, help="image width [px]")
    p.add_argument("--height", type=int, default=640, help="image height [px]")
    p.add_argument("--settle", type=float, default=0.5, help="seconds of standing before the frame [s]")
    p.add_argument(
        "--course", help="render a course (name or file) from above, waypoints as red posts, robot at start 0"
    )
    p.add_argument("--distance", type=float, help="camera distance [m] (default 3; a course: fitted)")
    p.add_argument("--azimuth", type=float, default=135.0, help="camera azimuth [deg]")
    p.add_argument("--elevation", type=float, help="camera elevation [deg] (default -25; -35 for a course)")
    p.set_defaults(func=cmd_render)


def _add_view(subparsers) -> None:
    """``krl view``."""
    p = subparsers.add_parser(
        "view", help="a controller walking live in MuJoCo's viewer, keyboard-steered (needs a display)"
    )
    p.add_argument("--controller", help="expert, kernel, agent, ... as in krl evaluate (default: stand)")
    p.add_argument("--course", help="a course (name or file): its waypoints steer, from its first start")
    p.add_argument(
        "--duration", type=float, help="close the window after this many simulated seconds (default: never)"
    )
    add_terrain_arguments(p)
    p.set_defaults(func=cmd_view)


def _add_bench(subparsers) -> None:
    """``krl bench`` (defaults: the benchmark functions' own)."""
    from krl.bench.agent import bench_agent
    from krl.bench.evaluate import bench_evaluate
    from krl.bench.mpc import bench_mpc
    from krl.bench.sim import bench_sim
    from krl.bench.terrains import bench_terrains

    p = subparsers.add_parser("bench", help="run a benchmark and print its figures")
    p.add_argument(
        "target", choices=["sim", "terrains", "mpc", "agent", "evaluate"], help="what to benchmark"
    )
    p.add_argument("--json", action="store_true", help="print JSON")
    p.add_argument(
        "--steps",
        type=int,
        help=f"sim, agent: control steps per timed loop (default {default_of(bench_sim, 'steps')} for sim, "
        f"{default_of(bench_agent, 'steps')} for agent); terrains: physics steps per timed loop (default "
        f"{default_of(bench_terrains, 'steps')})",
    )
    p.add_argument(
        "--repeats",
        type=int,
        help=f"sim: alternating timed loops per variant (default {default_of(bench_sim, 'repeats')}); "
        f"terrains: builds and timed loops per terrain (default {default_of(bench_terrains, 'repeats')}); "
        f"evaluate: timed evaluations (default {default_of(bench_evaluate, 'repeats')})",
    )
    p.add_argument(
        "--terrain",
        action="append",
        help="terrains: a terrain to measure (repeat; default: every terrain), beside flat ground",
    )
    p.add_argument(
        "--seconds",
        type=float,
        help=f"mpc: simulated seconds of walking (default {default_of(bench_mpc, 'seconds'):g})",
    )
    _add_bench_agent_arguments(p)
    p.add_argument(
        "--controller",
        help="evaluate: the controller, as krl evaluate spells it "
        f"(default {default_of(bench_evaluate, 'controller')})",
    )
    p.add_argument(
        "--course",
        action="append",
        help="evaluate: a course to walk (repeat; default "
        f"{', '.join(default_of(bench_evaluate, 'courses'))})",
    )
    p.add_argument(
        "--seeds",
        help=f"evaluate: training seeds of a seed group (default {default_of(bench_evaluate, 'seeds')[0]})",
    )
    p.add_argument(
        "--push-attempts",
        type=int,
        help="evaluate: push sweep attempts per force, on every core "
        f"(default {default_of(bench_evaluate, 'push_attempts')})",
    )
    p.set_defaults(func=cmd_bench)


def _add_bench_agent_arguments(p) -> None:
    """``krl bench agent``'s own options."""
    from krl.agent.config import DEFAULT_NUM_ENVS
    from krl.bench.agent import bench_agent

    p.add_argument(
        "--num-envs",
        type=int,
        help="agent: robots per environment process "
        f"(default: the config's, {DEFAULT_NUM_ENVS} for agent-rp)",
    )
    p.add_argument(
        "--train-steps",
        type=int,
        help="agent: env steps of the PPO training measurement "
        f"(default {default_of(bench_agent, 'train_steps')})",
    )
    p.add_argument(
        "--update-threads",
        type=int,
        help="agent: PyTorch threads of the training's PPO update (default 1, as krl agent train's; "
        "another count changes a training's last bits)",
    )
    p.add_argument(
        "--config",
        help="agent: an agent config file (.json or .toml, such as a run folder's config.json; "
        "default: the thesis's agent-rp)",
    )
