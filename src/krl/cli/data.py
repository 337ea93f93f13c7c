"""``krl collect``: expert data for the kernel (defaults: :class:`krl.data.collect.CollectConfig`)."""

from __future__ import annotations

import argparse
import sys

from krl.cli.common import (
    add_expert_arguments,
    add_terrain_arguments,
    default_of,
    emit,
    expert_params_from_args,
    given,
    parse_params,
    parse_vector,
)


def add_collect_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``krl collect``."""
    from krl.data.collect import EXT_HEIGHTS, MODES, CollectConfig

    def default(name: str) -> str:
        return f"(default {default_of(CollectConfig, name)})"

    parser.add_argument("--out", required=True, help="dataset directory (created, or resumed if it exists)")
    parser.add_argument("--targets", type=int, help=f"number of targets to walk to {default('targets')}")
    parser.add_argument(
        "--mode",
        choices=MODES,
        help="base: fixed settings; ext: random step/ride height per target; dyn2: reset before every target "
        + default("mode"),
    )
    parser.add_argument(
        "--ext-heights",
        choices=EXT_HEIGHTS,
        help=f"ext: redraw one height per target (the other nominal) or both {default('ext_heights')}",
    )
    parser.add_argument(
        "--targets-per-episode",
        type=int,
        help=f"targets per part file (the unit of resumption) {default('targets_per_episode')}",
    )
    parser.add_argument(
        "--target-time-limit", type=float, help=f"time allowed per target [s] {default('target_time_limit')}"
    )
    parser.add_argument("--target-distance", metavar="LOW,HIGH", help=argparse.SUPPRESS)  # for tests
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument("--json", action="store_true", help="print the summary as JSON")
    add_expert_arguments(parser)
    add_terrain_arguments(parser)


def collect_config_from_args(args: argparse.Namespace):
    """The CollectConfig of :func:`add_collect_arguments`' options (fields not given keep their defaults)."""
    from krl.data.collect import CollectConfig

    distance = None
    if args.target_distance:
        low, high = parse_vector(args.target_distance, 2, "--target-distance")
        distance = (low, high)
    return CollectConfig(
        **given(
            targets=args.targets,
            mode=args.mode,
            ext_heights=args.ext_heights,
            targets_per_episode=args.targets_per_episode,
            target_time_limit=args.target_time_limit,
            target_distance=distance,
        ),
        seed=args.seed,
        expert=expert_params_from_args(args),
        terrain=args.terrain,
        terrain_params=parse_params(args.param),
    )


def cmd_collect(args: argparse.Namespace) -> int:
    """``krl collect``: returns the exit status."""
    from krl.data.collect import collect_dataset

    config = collect_config_from_args(args)
    show = not args.quiet and sys.stderr.isatty()
    emit(collect_dataset(args.out, config, progress=show).as_dict(), args.json)
    return 0


def register(subparsers) -> None:
    """Add ``krl collect`` to the main parser's subcommands."""
    p = subparsers.add_parser("collect", help="collect expert data for the kernel (Section 4.2.6.2)")
    add_collect_arguments(p)
    p.set_defaults(func=cmd_collect)
