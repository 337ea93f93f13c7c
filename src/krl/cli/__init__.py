"""The ``krl`` command. ``krl --help`` lists the subcommands; every error is one line on stderr.

One module per command group registers its subcommands (``register(subparsers)``): :mod:`krl.cli.sim`
(terrains, render, view, bench), :mod:`krl.cli.expert` (expert run, expert plot), :mod:`krl.cli.data`
(collect), :mod:`krl.cli.kernel` (kernel …), :mod:`krl.cli.agent` (agent …, with :mod:`krl.cli.study` for
agent study), :mod:`krl.cli.eval` (evaluate, report), :mod:`krl.cli.analyze` (analyze …),
:mod:`krl.cli.demo`, :mod:`krl.cli.export` and :mod:`krl.cli.reproduce`; what they share is in
:mod:`krl.cli.common`. This package is the only place argparse lives (``tests/cli/test_structure.py``).

krl's packages, bottom first; each imports only itself and the packages listed before it
(``tests/test_imports.py`` holds the order and checks it):

- :mod:`krl.util`: rates and periods, atomic output, progress bars, the process pool, hashes, the thesis's
  protocol constants;
- :mod:`krl.robots`: the A1 model (MJCF) and its constants;
- :mod:`krl.sim`: MuJoCo: terrains, the robot, pushes, the batch of simulators, rendering;
- :mod:`krl.control`: kinematics, gait, commands, filters, swing, the MPC expert;
- :mod:`krl.task`: the waypoint task, the reward (as data), the runner that walks a controller through it;
- :mod:`krl.data`: expert datasets: columns, schema, writer, reader, collection;
- :mod:`krl.kernel`: features, MLP, training, tuning, studies, the kernel as a controller, shipped kernels;
- :mod:`krl.agent`: the residual agent: action path, environments, PPO training, policy files;
- :mod:`krl.envs`: Gymnasium registration (``krl/A1-v0``, ``krl/A1Residual-v0``);
- :mod:`krl.eval`: courses, controllers, metrics, push sweep, reports;
- :mod:`krl.analysis`: figures;
- :mod:`krl.bench`: throughput benchmarks;
- :mod:`krl.apps`: the demo, the viewer, ONNX export, the reproduction plan;
- :mod:`krl.cli`: this command.
"""

from __future__ import annotations

import sys
import warnings
from collections.abc import Sequence

from krl.cli import agent, analyze, data, demo, expert, export, kernel, reproduce, sim
from krl.cli import eval as evaluation
from krl.cli.common import CliError, Parser, interrupted_status

EXIT_USAGE = 2


def build_parser() -> Parser:
    from krl import __version__

    parser = Parser(
        prog="krl",
        description="Kernel-based residual learning for quadruped locomotion (Unitree A1, MuJoCo).",
    )
    parser.add_argument("--version", action="version", version=f"krl {__version__}")
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    sim.register(subparsers)
    expert.register(subparsers)
    kernel.register(subparsers)
    data.register(subparsers)
    evaluation.register(subparsers)
    agent.register(subparsers)
    analyze.register(subparsers)
    demo.register(subparsers)
    export.register(subparsers)
    reproduce.register(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``krl`` command; returns the exit status."""
    # GLFW (MuJoCo's rendering backend when no other is chosen) reports a failure to start as Python
    # warnings, several lines before the one-line error that says what to install
    warnings.filterwarnings("ignore", module="glfw")
    from krl.sim.render import RenderError, import_mujoco

    try:
        import_mujoco()  # before anything that imports it, so a backend that cannot load is one line
    except RenderError as error:
        print(f"krl: error: {error}", file=sys.stderr)
        return EXIT_USAGE
    parser = build_parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    args = parser.parse_args(argv)
    args.argv = argv
    from krl.eval.evaluate import EvaluationError
    from krl.sim.robot import SimulationUnstableError

    try:
        return args.func(args)
    except (CliError, ValueError, RenderError, SimulationUnstableError, EvaluationError, OSError) as error:
        print(f"krl: error: {error}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt as stop:
        print("krl: interrupted", file=sys.stderr)
        return interrupted_status(stop)


__all__ = ["CliError", "build_parser", "main"]
