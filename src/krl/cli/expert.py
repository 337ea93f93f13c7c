"""``krl expert run`` and ``krl expert plot``: the convex-MPC expert."""

from __future__ import annotations

import argparse
from typing import Any

from krl.cli.common import (
    add_expert_arguments,
    add_run_arguments,
    default_of,
    emit,
    expert_params_from_args,
    given,
    print_json_summary,
    process_count,
    run_controller,
)


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


def add_plot_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``krl expert plot`` (defaults: :func:`krl.analysis.expert.driver.make_figures`)."""
    from krl.analysis.common import DEFAULT_DURATION, QUICK_DURATION
    from krl.analysis.expert.driver import make_figures
    from krl.analysis.expert.plan import CHOICES, DEFAULT_TARGETS, QUICK_TARGETS

    parser.add_argument("which", metavar="WHICH", help=f"figure to make: {', '.join(CHOICES)}")
    parser.add_argument(
        "--out", required=True, metavar="DIR", help="output folder (PNG, JSON, CSV per figure)"
    )
    parser.add_argument(
        "--seed",
        type=int,
        help=f"seed of the random waypoints and terrain (default {default_of(make_figures, 'seed')})",
    )
    parser.add_argument(
        "--targets",
        type=int,
        help=f"random waypoints per CoM condition (default {DEFAULT_TARGETS}; {QUICK_TARGETS} with --quick)",
    )
    parser.add_argument(
        "--duration",
        type=float,
        help=f"velocity sweep: seconds each command is held (default {DEFAULT_DURATION:g}; "
        f"{QUICK_DURATION:g} with --quick)",
    )
    parser.add_argument(
        "--workers", type=process_count, help="worker processes (default: number of CPUs; 1 = in-process)"
    )
    parser.add_argument("--quick", action="store_true", help="tiny runs (tests): 1 short waypoint, 3 s holds")
    parser.add_argument("--json", action="store_true", help="print a JSON summary instead of text")


def _plot_text_summary(summary: dict[str, Any]) -> str:
    lines = []
    for name, figure in summary["figures"].items():
        table = figure["table"]
        lines.append(f"{name} ({table['thesis_figure']}): {figure['png']}, {figure['json']}, {figure['csv']}")
        if name == "velocity":
            for axis, fit in table["fits"].items():
                lines.append(
                    f"  {axis}: slope {fit['slope']}, offset {fit['offset']}, rmse {fit['rmse']}, "
                    f"max |cross| {fit['max_abs_cross']}"
                )
        else:
            for row in table["conditions"]:
                std = [row[k] for k in ("com_std_x", "com_std_y", "com_std_z")]
                mm = "/".join("nan" if v is None else f"{1e3 * v:.2f}" for v in std)
                tilt = "/".join(
                    "nan" if row[k] is None else f"{row[k]:.2f}" for k in ("roll_std_deg", "pitch_std_deg")
                )
                lines.append(
                    f"  {row['label']}: com_std x/y/z {mm} mm, roll/pitch std {tilt} deg, "
                    f"reached {row['targets_reached']}, fell {row['fell']}"
                )
    lines.append(
        f"{summary['conditions_run']} conditions, {summary['workers']} workers, {summary['wall_seconds']} s"
    )
    return "\n".join(lines)


def cmd_expert_plot(args: argparse.Namespace) -> int:
    """``krl expert plot``: make the figure(s); print a summary (text or ``--json``)."""
    from krl.analysis.expert.driver import make_figures

    summary = make_figures(
        args.which,
        args.out,
        **given(seed=args.seed, targets=args.targets, duration=args.duration, workers=args.workers),
        quick=args.quick,
    )
    if args.json:
        print_json_summary(summary, lambda table: {"summary": table.get("fits") or table["conditions"]})
    else:
        print(_plot_text_summary(summary))
    return 0


def register(subparsers) -> None:
    """Add ``krl expert run|plot`` to the main parser's subcommands."""
    expert = subparsers.add_parser("expert", help="the convex-MPC expert").add_subparsers(
        dest="expert_command", required=True, metavar="EXPERT_COMMAND"
    )
    p = expert.add_parser("run", help="walk the expert to waypoints or at a fixed command")
    add_run_arguments(p)
    add_expert_arguments(p)
    p.set_defaults(func=cmd_expert_run)

    p = expert.add_parser("plot", help="the expert's analysis figures (Figs. 4.8, 4.15, A.2, A.3)")
    add_plot_arguments(p)
    p.set_defaults(func=cmd_expert_plot)
