"""What the ``krl`` command groups share: the output printer, value parsers, option groups and the run loop
of every ``… run`` command.

Options that set a dataclass field default to ``None``; a command passes on only the options given
(:func:`given`), so the dataclass is the one home of each default and help texts read it from there
(:func:`default_of`); the same holds for a domain function's keyword defaults.
"""

from __future__ import annotations

import argparse
import dataclasses
import inspect
import json
import math
import re
import signal
import sys
import textwrap
from collections.abc import Callable, Sequence
from typing import Any

from krl.agent.shipped import SHIPPED_POLICIES
from krl.kernel.shipped import SHIPPED_MODELS


class CliError(Exception):
    """A user-facing error: printed as ``krl: error: <message>`` with exit status 2."""


SHIPPED_AGENTS = ", ".join(SHIPPED_POLICIES)
"""The shipped agents' names as help texts list them."""

SHIPPED_KERNELS = ", ".join(SHIPPED_MODELS)
"""The shipped kernels' names as help texts list them."""

NEGATIVE_VALUE = re.compile(r"^-\.?\d")
"""A command-line word that starts like a negative number (``-0.9,0.9``, ``-.5``, ``-3``)."""


class HelpFormatter(argparse.HelpFormatter):
    """argparse's help layout, wrapped at spaces only: a hyphenated name (``gait-ground``,
    ``--friction-sweep``) stays whole on one line instead of breaking after a hyphen, in an option's help
    (``_split_lines``) as in a description (``_fill_text``, whose paragraphs, split by a blank line, each
    start on a line of their own). An option with a default its help does not mention gets
    ``(default VALUE)`` appended (:func:`shows_default`)."""

    def _split_lines(self, text: str, width: int) -> list[str]:
        return textwrap.wrap(" ".join(text.split()), width, break_on_hyphens=False)

    def _fill_text(self, text: str, width: int, indent: str) -> str:
        lines = [line for part in text.split("\n\n") for line in self._split_lines(part, width - len(indent))]
        return "\n".join(indent + line for line in lines)

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if shows_default(action) and "default" not in text:
            text += " (default %(default)s)"
        return text


def shows_default(action: argparse.Action) -> bool:
    """Whether ``action``'s help must show a default: it takes a value and has one that is not None (a flag's
    False, --help and --version have none to show)."""
    if action.nargs == 0 or action.default in (None, argparse.SUPPRESS):
        return False
    return bool(action.option_strings) or action.nargs in ("?", "*")


class Parser(argparse.ArgumentParser):
    """The parser of ``krl`` and of each of its subcommands (``add_subparsers`` makes its own kind), with
    :class:`HelpFormatter` unless another is given.

    An option's value may start with a minus sign: argparse alone takes ``-0.9,0.9`` in ``--target
    -0.9,0.9`` for an option, as it recognises only plain negative numbers, so a word that starts like a
    negative number after an option taking a value is joined to it (``--target=-0.9,0.9``) before
    parsing. A usage error is one line on stderr (exit status 2), naming ``--help``.
    """

    def __init__(self, *args, formatter_class: type[argparse.HelpFormatter] = HelpFormatter, **kwargs):
        super().__init__(*args, formatter_class=formatter_class, **kwargs)

    def parse_known_args(self, args=None, namespace=None):
        words = sys.argv[1:] if args is None else list(args)
        return super().parse_known_args(self.join_negative_values(words), namespace)

    def join_negative_values(self, words: Sequence[str]) -> list[str]:
        """``words`` with each ``OPTION VALUE`` pair whose value starts like a negative number written as
        ``OPTION=VALUE`` (this parser's options that take one value; nothing after ``--``)."""
        takes_value = {
            option for action in self._actions if action.nargs is None for option in action.option_strings
        }
        joined: list[str] = []
        index = 0
        while index < len(words):
            word = words[index]
            if word == "--":
                return joined + list(words[index:])
            following = words[index + 1] if index + 1 < len(words) else ""
            if word in takes_value and NEGATIVE_VALUE.match(following):
                joined.append(f"{word}={following}")
                index += 2
            else:
                joined.append(word)
                index += 1
        return joined

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see `{self.prog} --help`)\n")


def interrupted_status(stop: KeyboardInterrupt) -> int:
    """Exit status of a command stopped by a signal: 128 + its number (130 for Ctrl-C, 143 for SIGTERM).

    :class:`krl.util.parallel.Interrupted` carries the signal; a plain ``KeyboardInterrupt`` is Ctrl-C.
    """
    return 128 + int(getattr(stop, "signum", signal.SIGINT))


def json_text(value: Any, **options: Any) -> str:
    """Strict JSON of a command's result, the one printer of every ``--json``: a non-finite number (NaN,
    ±inf, which JSON cannot hold) becomes ``null``, as JavaScript's ``JSON.stringify`` writes it, so the
    output always parses; ``options`` go to :func:`json.dumps`."""
    return json.dumps(_finite(value), allow_nan=False, **options)


def _finite(value: Any) -> Any:
    """``value`` with every non-finite float (nested in dicts, lists and tuples) replaced by None."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {key: _finite(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(item) for item in value]
    return value


def emit(result: dict[str, Any], as_json: bool) -> None:
    """Print a command's result: indented JSON (:func:`json_text`), or one ``key: value`` line per entry
    (a nested mapping indented under its key, a list of mappings one item per line)."""
    if as_json:
        print(json_text(result, indent=2))
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


def print_json_summary(summary: dict[str, Any], digest=None) -> None:
    """Print a figure run's summary as JSON: each figure's paths without its full table, plus
    ``digest(table)`` (a dict) where given. Shared by ``krl expert plot`` and ``krl kernel figures``."""
    printable = {
        **summary,
        "figures": {
            name: {key: value for key, value in figure.items() if key != "table"}
            | (digest(figure["table"]) if digest else {})
            for name, figure in summary["figures"].items()
        },
    }
    print(json_text(printable, indent=2, ensure_ascii=False))


def given(**options: Any) -> dict[str, Any]:
    """The options that were given (not ``None``), for a dataclass or a function to fill its fields
    from while keeping its own defaults for the others."""
    return {key: value for key, value in options.items() if value is not None}


def default_of(owner: Any, name: str) -> Any:
    """The default of field ``name`` of dataclass ``owner``, or of parameter ``name`` of function
    ``owner`` (for help texts)."""
    if dataclasses.is_dataclass(owner):
        for item in dataclasses.fields(owner):
            if item.name == name and item.default is not dataclasses.MISSING:
                return item.default
            if item.name == name and item.default_factory is not dataclasses.MISSING:
                return item.default_factory()
    else:
        parameter = inspect.signature(owner).parameters.get(name)
        if parameter is not None and parameter.default is not inspect.Parameter.empty:
            return parameter.default
    raise KeyError(f"{owner.__name__} has no {name!r} with a default")


def shown(value: Any) -> str:
    """A default as a help text writes it: a number as ``%g`` would (600.0 is 600), a sequence as a comma
    list of those."""
    if isinstance(value, (list, tuple)):
        return ",".join(shown(item) for item in value)
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def add_field_option(
    parser: argparse.ArgumentParser, flag: str, owner: Any, name: str | None = None, **options: Any
) -> argparse.Action:
    """Add ``flag``, an option that sets field ``name`` (default: the flag's name, ``--push-seed`` ->
    ``push_seed``) of dataclass ``owner``, or parameter ``name`` of function ``owner``: its value is None
    unless given (pass it on with :func:`given`), and its help ends with the owner's default
    (:func:`default_of`), so that the default is written once, in the owner; a help holding ``{default}``
    gets the value there instead. ``options`` go to ``add_argument``."""
    field = name or flag.lstrip("-").replace("-", "_")
    text, value = options.pop("help", ""), shown(default_of(owner, field))
    if "{default}" in text:
        text = text.replace("{default}", value)
    else:
        text = f"{text} (default {value})".strip()
    return parser.add_argument(flag, help=text, **options)


def parse_params(items: Sequence[str] | None) -> dict[str, Any]:
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


def parse_vector(text: str, size: int, what: str) -> list[float]:
    """``"0.5,0,0"`` -> ``[0.5, 0.0, 0.0]``; ``size`` numbers exactly, else a :class:`CliError` naming
    the option ``what``."""
    try:
        values = [float(part) for part in text.split(",")]
    except ValueError:
        raise CliError(f"{what} expects {size} comma-separated numbers, got {text!r}") from None
    if len(values) != size:
        raise CliError(f"{what} expects {size} comma-separated numbers, got {text!r}")
    return values


def parse_ints(text: str, option: str) -> list[int]:
    """``"150,215"`` -> ``[150, 215]`` (empty parts skipped); a ValueError naming ``option`` otherwise (no
    integer at all included)."""
    try:
        numbers = [int(part) for part in text.split(",") if part.strip()]
    except ValueError:
        numbers = []
    if not numbers:
        raise ValueError(f"{option} expects comma-separated integers, got {text!r}")
    return numbers


LABEL = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9._-]*")
"""A label given as ``LABEL=…``: letters, digits, '.', '_' or '-', usable as a folder name."""


def process_count(text: str) -> int:
    """The ``type`` of every option that sets a number of processes (``--workers``, ``--jobs``): an integer
    >= 1, capped at the usable cores with a note on stderr (:func:`krl.util.parallel.worker_processes`);
    a usage error (one line) otherwise."""
    from krl.util.parallel import worker_processes

    try:
        asked = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    try:
        return worker_processes(asked, lambda note: print(f"krl: note: {note}", file=sys.stderr))
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def labelled_policies(texts: Sequence[str], resolve: Callable[[str], tuple[str, Any]]) -> dict[str, Any]:
    """``--policy [LABEL=]POLICY`` options -> ``{label: resolve(POLICY)[1]}``; the label defaults to the name
    ``resolve`` gives (``krl.agent.policy.one_policy`` or ``policy_artifacts``). A CliError (one line) for a
    label that is not a folder name or is given twice; ``resolve``'s own errors pass through."""
    policies: dict[str, Any] = {}
    for text in texts:
        label, _, spec = text.rpartition("=")
        if label and not LABEL.fullmatch(label):
            raise CliError(f"--policy {text!r}: a label is letters, digits, '.', '_' or '-' (a folder name)")
        name, value = resolve(spec)
        if (label or name) in policies:
            raise CliError(f"--policy {text!r}: the label {label or name!r} is given twice")
        policies[label or name] = value
    return policies


# --- option groups -----------------------------------------------------------------------------------


def add_terrain_arguments(parser: argparse.ArgumentParser) -> None:
    """``--terrain``, ``--param KEY=VALUE`` and ``--seed`` (defaults: :func:`krl.sim.model.build_model`'s)."""
    from krl.sim.model import build_model

    parser.add_argument(
        "--terrain", default=default_of(build_model, "terrain"), help="terrain name (see `krl terrains`)"
    )
    parser.add_argument(
        "--param", action="append", metavar="KEY=VALUE", help="terrain parameter override (repeatable)"
    )
    parser.add_argument(
        "--seed",
        type=int,
        default=default_of(build_model, "seed"),
        help="seed of the run's random draws (terrain, waypoints)",
    )


def build_sim(args: argparse.Namespace):
    """The simulator on :func:`add_terrain_arguments`' terrain."""
    from krl.sim.model import build_model
    from krl.sim.robot import A1Sim

    return A1Sim(build_model(args.terrain, parse_params(args.param), args.seed))


def add_expert_arguments(parser: argparse.ArgumentParser) -> None:
    """The MPC expert's settings, shared by every command that runs the expert (defaults: ExpertParams)."""
    from krl.control.expert import ExpertParams

    def default(name: str) -> str:
        return f"(default {default_of(ExpertParams, name)})"

    parser.add_argument("--gait", help=f"gait of Table 4.1 (walk, trot, bound) {default('gait')}")
    parser.add_argument("--stance-duration", type=float, help=f"τ_stance [s] {default('stance_duration')}")
    parser.add_argument(
        "--step-height", type=float, help=f"swing apex height [m], 0.05-0.18 {default('step_height')}"
    )
    parser.add_argument(
        "--ride-height", type=float, help=f"base height [m], 0.18-0.28 {default('ride_height')}"
    )


def expert_params_from_args(args: argparse.Namespace):
    """ExpertParams from :func:`add_expert_arguments`' options (validated by ExpertParams)."""
    from krl.control.expert import ExpertParams

    return ExpertParams(
        **given(
            gait=args.gait,
            stance_duration=args.stance_duration,
            step_height=args.step_height,
            ride_height=args.ride_height,
        )
    )


def add_run_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of every ``… run`` command: waypoints or a fixed command, video, JSON (defaults:
    :class:`krl.task.walk.WalkPlan`)."""
    from krl.task.walk import WalkPlan

    add_terrain_arguments(parser)
    add_field_option(
        parser, "--targets", WalkPlan, type=int, help="number of random waypoints (seeded by --seed)"
    )
    parser.add_argument("--target", action="append", metavar="X,Y", help="a given waypoint (repeatable)")
    add_field_option(
        parser, "--target-time-limit", WalkPlan, type=float, help="time allowed per waypoint [s]"
    )
    parser.add_argument(
        "--command", metavar="VX,VY,WZ", help="walk at a fixed command instead of to waypoints"
    )
    add_field_option(parser, "--duration", WalkPlan, type=float, help="with --command: run length [s]")
    parser.add_argument("--video", help="write an MP4 of the run")
    parser.add_argument(
        "--video-size",
        metavar="WIDTHxHEIGHT",
        help=f"with --video: frame size [px] (default {video_size_default()})",
    )
    parser.add_argument("--json", action="store_true", help="print JSON")


def video_size_default() -> str:
    """``--video-size``'s default: :class:`krl.sim.video.VideoRecorder`'s frame size, as ``640x480``."""
    from krl.sim.video import VideoRecorder

    return f"{default_of(VideoRecorder, 'width')}x{default_of(VideoRecorder, 'height')}"


def parse_size(text: str, what: str) -> tuple[int, int]:
    """``"320x240"`` -> ``(320, 240)``: two positive integers, else a :class:`CliError` naming ``what``."""
    width, sep, height = text.lower().partition("x")
    try:
        size = (int(width), int(height))
    except ValueError:
        size = (0, 0)
    if not sep or min(size) < 1:
        raise CliError(f"{what} expects WIDTHxHEIGHT in pixels (e.g. 320x240), got {text!r}")
    return size


def walk_plan_from_args(args: argparse.Namespace):
    """The :class:`krl.task.walk.WalkPlan` of :func:`add_run_arguments`' options (fields not given keep
    their defaults)."""
    from krl.task.walk import WalkPlan

    command = None if args.command is None else tuple(parse_vector(args.command, 3, "--command"))
    waypoints = tuple(tuple(parse_vector(text, 2, "--target")) for text in args.target or ())
    size = None if args.video_size is None else parse_size(args.video_size, "--video-size")
    return WalkPlan(
        terrain=args.terrain,
        params=parse_params(args.param),
        seed=args.seed,
        waypoints=waypoints,
        command=command,
        video=args.video,
        video_size=size,
        **given(targets=args.targets, duration=args.duration, target_time_limit=args.target_time_limit),
    )


def run_controller(args: argparse.Namespace, controller, step_hook=None) -> dict[str, Any]:
    """Walk ``controller`` as :func:`add_run_arguments`' options say (:func:`krl.task.walk.walk`); returns
    the summary printed by ``run``. ``step_hook()`` is called after every control step."""
    from krl.task.walk import walk

    return walk(walk_plan_from_args(args), controller, step_hook)
