"""``krl analyze``: readings beyond ``krl report``, printed as Markdown: ``push-sweep`` (a push sweep's
records: the headroom and the success by face struck, :mod:`krl.analysis.push_sweep`) and ``mirror`` (how
symmetric the A1 and its kernel are, :mod:`krl.analysis.agent.mirror`)."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from krl.cli.common import CliError, add_field_option, default_of, given, parse_ints, parse_vector


def run_push_sweep(args: argparse.Namespace) -> int:
    from krl.analysis.push_faces import parse_band
    from krl.analysis.push_sweep import push_sweep_markdown
    from krl.util.output import write_atomic

    bands = None if args.band is None else [parse_band(text) for text in args.band]
    seeds = None if args.seeds is None else parse_ints(args.seeds, "--seeds")
    text = push_sweep_markdown(Path(args.results), args.controller, **given(bands=bands, seeds=seeds))
    if args.out is None:
        sys.stdout.write(text)
    else:
        write_atomic(Path(args.out), text)
    return 0


def _add_push_sweep(group) -> None:
    """``krl analyze push-sweep`` (defaults: :func:`krl.analysis.push_sweep.push_sweep_markdown`)."""
    from krl.analysis.push_sweep import push_sweep_markdown

    p = group.add_parser(
        "push-sweep",
        help="a push sweep's records beyond krl report: which pushes some controller seed survives "
        "(headroom), and the success by the face of the trunk struck",
    )
    p.add_argument("results", help="a krl evaluate --out folder with push-sweep records")
    p.add_argument(
        "--controller",
        action="append",
        metavar="LABEL",
        help="a controller label; repeat (default: every one)",
    )
    bands = ", ".join(f"{low:g}:{high:g}" for low, high in default_of(push_sweep_markdown, "bands"))
    p.add_argument(
        "--band",
        action="append",
        help=f"a force band LOW:HIGH [N] of the faces table; repeat (default {bands})",
    )
    p.add_argument("--seeds", help="SEED,SEED,...: read these training seeds' records only (default all)")
    p.add_argument("--out", help="write the tables here instead of printing them")
    p.set_defaults(func=run_push_sweep)


def run_mirror(args: argparse.Namespace) -> int:
    from krl.analysis.agent.mirror import mirror_markdown
    from krl.util.timing import CONTROL_DT

    if args.duration is not None and not (math.isfinite(args.duration) and args.duration >= CONTROL_DT):
        raise CliError(f"--duration must be a finite length of at least one control step ({CONTROL_DT} s)")
    commands = None if args.command is None else [parse_vector(c, 3, "--command") for c in args.command]
    sys.stdout.write(mirror_markdown(**given(kernels=args.kernel, commands=commands, duration=args.duration)))
    return 0


def _add_mirror(group) -> None:
    """``krl analyze mirror`` (defaults: :func:`krl.analysis.agent.mirror.mirror_markdown`)."""
    from krl.analysis.agent.mirror import mirror_markdown

    p = group.add_parser(
        "mirror",
        help="how symmetric the A1 and its kernel are: the model's asymmetries, and each kernel walking a "
        "command beside its mirror (docs/agent-robust.md)",
    )
    kernels = " and ".join(default_of(mirror_markdown, "kernels"))
    p.add_argument(
        "--kernel", action="append", help=f"a shipped kernel or kernel file; repeat (default {kernels})"
    )
    commands = "; ".join(",".join(f"{v:g}" for v in c) for c in default_of(mirror_markdown, "commands"))
    p.add_argument(
        "--command",
        action="append",
        metavar="VX,VY,WZ",
        help=f"a command walked beside its mirror [m/s, m/s, rad/s]; repeat (default {commands})",
    )
    add_field_option(p, "--duration", mirror_markdown, type=float, help="length of each walk [s]")
    p.set_defaults(func=run_mirror)


def register(subparsers) -> None:
    """Add ``krl analyze`` and its subcommands to the main parser's subcommands."""
    group = subparsers.add_parser("analyze", help="readings beyond krl report, as Markdown").add_subparsers(
        dest="analyze_command", required=True, metavar="ANALYZE_COMMAND"
    )
    _add_push_sweep(group)
    _add_mirror(group)
