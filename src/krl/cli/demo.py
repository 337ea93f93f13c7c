"""``krl demo``: the shipped agent, the kernel and the expert (or the controllers given) on a thesis course
(video, path, metrics)."""

from __future__ import annotations

import argparse
import sys

from krl.cli.common import default_of, emit, given, process_count


def run_demo(args: argparse.Namespace) -> int:
    from krl.apps.demo import make_demo

    summary = make_demo(
        args.out,
        **given(
            course=args.course,
            start=args.start,
            workers=args.workers,
            controllers=tuple(args.controller) if args.controller else None,
        ),
        video=not args.no_video,
        progress=not args.quiet,
        say=None if args.json else lambda note: print(f"krl demo: {note}", file=sys.stderr, flush=True),
    )
    if args.json:
        emit(summary, True)
        return 0
    for row in summary["runs"]:
        outcome = "success" if row["success"] else ("fell" if row["fell"] else "stopped")
        print(f"{row['controller']:>18}: {row['targets_reached']}/{row['targets']} waypoints, {outcome}")
    for kind, path in summary["files"].items():
        print(f"{kind}: {path}")
    return 0


def register(subparsers) -> None:
    from krl.apps.demo import DEMO_CONTROLLERS, make_demo

    p = subparsers.add_parser(
        "demo", help="the shipped agent, the kernel and the expert on a thesis course: video, path, metrics"
    )
    p.add_argument("--out", default="demo", help="output folder (default demo/)")
    p.add_argument(
        "--controller",
        action="append",
        metavar="SPEC",
        help="a controller as krl evaluate names it (agent:gait, kernel:ext, ...); repeat; the first is "
        f"filmed (default: {', '.join(DEMO_CONTROLLERS)})",
    )
    p.add_argument("--course", help=f"course name or file (default {default_of(make_demo, 'course')})")
    p.add_argument("--start", type=int, help=f"start pose index (default {default_of(make_demo, 'start')})")
    p.add_argument(
        "--workers", type=process_count, help=f"processes (default {default_of(make_demo, 'workers')})"
    )
    p.add_argument("--no-video", action="store_true", help="skip the video")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=run_demo)
