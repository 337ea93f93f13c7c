"""``krl agent …``: train, run, inspect and export the residual agent."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from krl.cli import runs, study
from krl.cli.common import (
    SHIPPED_AGENTS,
    CliError,
    add_field_option,
    default_of,
    emit,
    given,
    labelled_policies,
    process_count,
    run_controller,
)
from krl.cli.common import add_run_arguments as add_common_run_arguments


def _config(args: argparse.Namespace):
    from krl.agent.config import AgentConfig

    return AgentConfig.load(args.config) if args.config else None


def run_train(args: argparse.Namespace) -> int:
    from krl.agent.process_vec_env import WorkerError
    from krl.agent.train import TrainingError, train

    if args.steps is not None and args.steps < 1:
        raise CliError(f"--steps must be at least 1 env step, got {args.steps}")
    if args.update_threads < 1:
        raise CliError(f"--update-threads must be at least 1, got {args.update_threads}")
    try:
        summary = train(
            args.out,
            _config(args),
            args.seed,
            args.steps,
            progress=not args.quiet,
            init_from=args.init_from,
            workers=args.workers,
            num_envs=args.num_envs,
            device=args.device,
            update_threads=args.update_threads,
            log=_note if args.json else print,
        )
    except TrainingError as error:
        raise CliError(str(error)) from None
    except WorkerError as error:
        raise CliError(f"{error}; the same command resumes from the last checkpoint in {args.out}") from None
    emit(summary, args.json)
    return 0


def _note(message: str) -> None:
    """A one-line message on stderr, so that ``--json`` output stays JSON alone."""
    print(message, file=sys.stderr)


def _policy(args: argparse.Namespace):
    from krl.agent.policy import load_policy, one_policy

    _, path = one_policy(args.policy)
    return path, load_policy(path)


def _shown(path: Path) -> str:
    """A policy file as output names it: a shipped one as ``krl/agent/policies/...`` (the same on every
    machine), any other as given."""
    from krl.agent.policy import shipped_policy_dir

    try:
        inside = Path(path).resolve().relative_to(shipped_policy_dir().resolve())
    except ValueError:
        return str(path)
    return f"krl/agent/policies/{inside.as_posix()}"


def run_run(args: argparse.Namespace) -> int:
    from krl.agent.controller import AgentController

    path, policy = _policy(args)
    controller = AgentController(policy)
    summary = run_controller(args, controller)
    summary["policy"] = _shown(path)
    summary["kernel"] = policy.config.residual.kernel
    emit(summary, args.json)
    return 0


def run_info(args: argparse.Namespace) -> int:
    from krl.agent.action import describe_parts
    from krl.agent.observation import layout
    from krl.agent.policy import check_kernel_file
    from krl.kernel.model import load_kernel
    from krl.task.reward import reward_name

    path, policy = _policy(args)
    reward = policy.config.env.reward
    kernel = load_kernel(check_kernel_file(policy, None, path))
    action = [
        {"name": part.pop("name"), "slice": f"{part.pop('start')}:{part.pop('stop')}", **part}
        for part in describe_parts(policy.config.residual, kernel)
    ]
    emit(
        {
            "policy": _shown(path),
            "kernel": policy.config.residual.kernel,
            "kernel_sha256": policy.metadata.get("kernel_sha256"),
            "training": policy.metadata.get("training"),
            "software": policy.metadata.get("software"),
            "residual_bound": list(policy.config.residual.residual_bound),
            "residual_alpha": policy.config.residual.residual_alpha,
            "reward": reward_name(reward) or reward.to_json(),
            "observation": [
                {"name": row["name"], "slice": f"{row['start']}:{row['stop']}", "unit": row["unit"]}
                for row in layout(policy.config.observation.features, policy.config.observation.scan)
            ],
            "action": action,
        },
        args.json,
    )
    return 0


def run_curves(args: argparse.Namespace) -> int:
    from krl.agent.curves import plot_seed_groups, plot_training_curves, reach_rows, write_reach

    if not args.run and not args.group:
        raise CliError("give run folders, or --group LABEL=RUN,RUN,... (or both)")
    if args.reach and not args.group:
        raise CliError("--reach needs --group: the level is a group's final success rate")
    groups: dict[str, list[Path]] = {}
    for text in args.group or []:
        label, _, runs = text.partition("=")
        if not label or not runs:
            raise CliError(f"--group {text!r}: expected LABEL=RUN,RUN,...")
        groups[label] = _group_runs([Path(run) for run in runs.split(",")])
    paths = []
    if args.run:
        paths += plot_training_curves([Path(run) for run in args.run], Path(args.out))
    if args.window is not None and not args.reach:
        raise CliError("--window needs --reach: it averages the curves that --reach reads")
    # a bad label or window: refused before anything is drawn
    rows = reach_rows(groups, args.reach, args.window) if args.reach else None
    if groups:
        paths += plot_seed_groups(groups, Path(args.out))
    result: dict = {"figures": [str(p) for p in paths]}
    if rows is not None:
        result |= {"reach": rows, "tables": [str(p) for p in write_reach(rows, args.reach, Path(args.out))]}
    emit(result, args.json)
    return 0


def _group_runs(paths: list[Path]) -> list[Path]:
    """The run folders of a ``--group``: the folders given, or for one folder holding no training log, the
    run folders inside it (a seed group such as ``runs/agent-rp/seed150``, ``.../seed215``)."""
    if len(paths) == 1 and paths[0].is_dir() and not (paths[0] / "progress.csv").exists():
        inside = sorted(run.parent for run in paths[0].glob("*/progress.csv"))
        if inside:
            return inside
    return paths


def run_stairs(args: argparse.Namespace) -> int:
    from krl.agent.policy import one_policy
    from krl.analysis.agent.stairs import stairs_diagnosis, stairs_figure
    from krl.eval.courses import load_course

    policies = labelled_policies(args.policy, one_policy)
    course = load_course(args.course)
    if course.terrain != "stairs":
        raise CliError(f"--course {args.course} is on {course.terrain!r}, not on stairs")
    written = stairs_figure(stairs_diagnosis(policies, course), course, Path(args.out))
    emit(
        {kind: written[kind] for kind in ("png", "gait_png", "json", "csv")}
        | {"runs": written["table"]["runs"]},
        args.json,
    )
    return 0


def run_rhythm(args: argparse.Namespace) -> int:
    from krl.analysis.agent.rhythm import clock_rate_walks

    try:
        rates = [float(text) for text in args.rates.split(",") if text.strip()]
    except ValueError:
        raise CliError(f"--rates must be a comma-separated list of numbers, got {args.rates!r}") from None
    if not rates or min(rates) <= 0:
        raise CliError(f"--rates must be positive numbers, got {args.rates!r}")
    from krl.task.runner import HOLD_RAMP, HOLD_SETTLE

    if args.seconds is not None and not args.seconds > HOLD_RAMP + HOLD_SETTLE:
        raise CliError(
            f"--seconds must exceed the {HOLD_RAMP + HOLD_SETTLE:g} s command ramp and settling, "
            f"got {args.seconds}"
        )
    options = given(terrains=args.terrain, seconds=args.seconds, kernel=args.kernel)
    emit({"walks": clock_rate_walks(rates, **options)}, args.json)
    return 0


def run_push(args: argparse.Namespace) -> int:
    from krl.analysis.push import PushProbe, push_trace, write_push_report
    from krl.eval.controllers import distinct_controllers, parse_controller

    probe = PushProbe(
        **given(magnitude=args.magnitude, direction=args.direction, start_time=args.at, point=args.point)
    )
    specs = distinct_controllers([parse_controller(text) for text in args.controller or PUSH_CONTROLLERS])
    runs = {spec.driven_label: push_trace(probe, spec.build()) for spec in specs}
    written = write_push_report(probe, runs, Path(args.out))
    for row in written["table"]["controllers"]:
        if row["error"] is not None:  # as krl evaluate records it: the run counts as a fall
            _note(
                f"krl: warning: {row['controller']}: {row['error']} "
                "(counted as a fall, as krl evaluate counts it)"
            )
    emit({kind: written[kind] for kind in ("png", "json", "csv", "npz")} | written["table"], args.json)
    return 0


def run_heldout(args: argparse.Namespace) -> int:
    from krl.agent.policy import policy_artifacts
    from krl.analysis.agent.heldout_choice import run_heldout
    from krl.analysis.agent.heldout_request import HeldoutError, HeldoutRequest
    from krl.util.progress import progress_bar

    request = HeldoutRequest(
        groups=labelled_policies(args.policy, policy_artifacts),
        out=Path(args.out),
        episodes=args.episodes,
        workers=args.workers,
        candidates=tuple(label.strip() for label in args.choose.split(",")) if args.choose else (),
        baseline=args.baseline,
        env=args.env,
        baseline_env=args.baseline_env,
        seed_group=Path(args.seed_group) if args.seed_group else None,
    )
    try:
        with progress_bar(not args.quiet, unit="episodes") as bar:
            result = run_heldout(request, bar)
    except HeldoutError as error:
        raise CliError(str(error)) from None
    emit(result, args.json)
    return 0


PUSH_CONTROLLERS: tuple[str, ...] = ("agent", "expert", "kernel")
"""``krl agent push``'s controllers unless given: agent-rp's first seed, the MPC expert, kernel-base."""


def register(subparsers) -> None:
    """Add ``krl agent`` and its subcommands to the main parser's subcommands."""
    group = subparsers.add_parser("agent", help="the residual PPO agent").add_subparsers(
        dest="agent_command", required=True, metavar="AGENT_COMMAND"
    )
    study.register(group)
    for add in (_add_train, _add_run, _add_info, _add_curves, _add_stairs, _add_push, _add_heldout):
        add(group)
    _add_rhythm(group)
    _add_digest(group)
    _add_config(group)
    runs.register(group)


def _add_train(group) -> None:
    """``krl agent train``."""
    p = group.add_parser("train", help="train (or resume) a residual agent with PPO")
    p.add_argument(
        "--out", required=True, help="run folder: a new or empty one starts a run, a run folder resumes"
    )
    p.add_argument("--seed", type=int, help="seed of the run, 0 to 4294967295 (default 0)")
    p.add_argument("--config", help="agent config file (.json or .toml; default: the thesis's agent-rp)")
    p.add_argument(
        "--steps",
        type=int,
        help="env steps to train to, up to the end of that rollout (default: the config's total_steps)",
    )
    p.add_argument(
        "--workers",
        type=process_count,
        help="environment processes (default: the config's, else one per usable core; may change to resume)",
    )
    p.add_argument("--num-envs", type=int, help="environments per process (default: the config's)")
    p.add_argument(
        "--device",
        choices=("auto", "cpu", "cuda"),
        default="auto",
        help="where PPO's update runs (default auto: CUDA when PyTorch sees a device); recorded in run.json",
    )
    p.add_argument(
        "--update-threads",
        type=int,
        default=1,
        help="PyTorch threads for PPO's update on the CPU (default 1; more pay only on a machine to itself)",
    )
    p.add_argument(
        "--init-from",
        help="a new run starts from this run folder's newest checkpoint (fine-tuning; docs/agent.md)",
    )
    _add_output(p, quiet=True)
    p.set_defaults(func=run_train)


def _add_output(parser: argparse.ArgumentParser, quiet: bool = False) -> None:
    """``--quiet`` (where ``quiet``) and ``--json``."""
    if quiet:
        parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument("--json", action="store_true", help="print JSON")


def _add_policy(parser: argparse.ArgumentParser) -> None:
    """``--policy``: one shipped agent, policy file or seed group."""
    parser.add_argument(
        "--policy",
        default="rp",
        help=f"shipped agent ({SHIPPED_AGENTS}), a policy file or a seed group; NAME@SEED picks a "
        "group's seed (default: its first, rp is rp@150)",
    )


def _add_run(group) -> None:
    """``krl agent run``."""
    p = group.add_parser("run", help="walk the agent to waypoints or at a fixed command")
    add_common_run_arguments(p)
    _add_policy(p)
    p.set_defaults(func=run_run)


def _add_info(group) -> None:
    """``krl agent info``."""
    p = group.add_parser("info", help="a policy file's metadata and observation layout")
    _add_policy(p)
    _add_output(p)
    p.set_defaults(func=run_info)


def _add_curves(group) -> None:
    """``krl agent curves``."""
    p = group.add_parser(
        "curves", help="training curves (reward, targets reached, falls vs env steps) as PNG"
    )
    p.add_argument("run", nargs="*", help="run folders of krl agent train: one line each")
    p.add_argument(
        "--group",
        action="append",
        help="LABEL=RUN,RUN,... or LABEL=FOLDER of run folders: the runs of one agent's seeds, drawn as "
        "their mean and spread (seed-groups.png, Fig. 4.23); repeat for each agent",
    )
    p.add_argument(
        "--reach",
        metavar="LABEL",
        help="with --group: the env steps at which each group's mean training success rate first reaches "
        "LABEL's final one (reach.md, reach.json): sample efficiency",
    )
    p.add_argument(
        "--window",
        type=float,
        metavar="STEPS",
        help="with --reach: read every curve as its mean over the trailing STEPS env steps (a multiple of "
        "the curves' env-step grid, e.g. 2e6), the level too; default: single rollouts",
    )
    p.add_argument("--out", required=True, help="output folder")
    _add_output(p)
    p.set_defaults(func=run_curves)


def _add_stairs(group) -> None:
    """``krl agent stairs``."""
    p = group.add_parser(
        "stairs",
        help="why agents fall on a stairs course: their paths, falls, swing past the side, command "
        "following, and the step and ride heights and clock rate the kernel was given",
    )
    p.add_argument(
        "--policy",
        action="append",
        required=True,
        help=f"[LABEL=]POLICY: a shipped name ({SHIPPED_AGENTS}) or a policy file; repeat to compare",
    )
    p.add_argument(
        "--course", default="stairs", help="a course on stairs: shipped name or file (default stairs)"
    )
    p.add_argument("--out", required=True, help="output folder (stairs-diagnosis.png, .json, .csv)")
    _add_output(p)
    p.set_defaults(func=run_stairs)


def _add_push(group) -> None:
    """``krl agent push`` (the push's defaults: :class:`krl.analysis.push.PushProbe`)."""
    from krl.analysis.push import PROBE_DIRECTIONS, PROBE_POINTS, PushProbe

    p = group.add_parser(
        "push",
        help="what controllers do through one push: speed along it, trunk height, roll, gait clock, steps",
    )
    p.add_argument(
        "--controller",
        action="append",
        help="as krl evaluate's (a seed group drives its first seed, or NAME@SEED); repeat; "
        f"default {', '.join(PUSH_CONTROLLERS)}",
    )
    add_field_option(p, "--magnitude", PushProbe, type=float, help="push force [N]")
    add_field_option(
        p, "--direction", PushProbe, choices=tuple(PROBE_DIRECTIONS), help="relative to the walk"
    )
    add_field_option(
        p,
        "--at",
        PushProbe,
        "start_time",
        type=float,
        help="the push's start [s] (default {default}: mid-swing)",
    )
    add_field_option(
        p,
        "--point",
        PushProbe,
        choices=tuple(PROBE_POINTS),
        help="where it strikes: the trunk's centre, or the middle of its top or bottom face",
    )
    p.add_argument("--out", required=True, help="output folder (push-trace.png, .json, .csv, .npz)")
    _add_output(p)
    p.set_defaults(func=run_push)


def _add_heldout(group) -> None:
    """``krl agent heldout``."""
    from krl.analysis.agent.heldout_request import HELDOUT_BATCH, MAX_EPISODES, HeldoutRequest

    p = group.add_parser(
        "heldout",
        help="policies on held-out episodes of their training distribution (choosing without the courses)",
    )
    p.add_argument(
        "--policy",
        action="append",
        required=True,
        help=f"[LABEL=]POLICY: a shipped name ({SHIPPED_AGENTS}), a policy file or a seed group (its "
        "seeds); repeat",
    )
    p.add_argument(
        "--episodes",
        type=int,
        default=default_of(HeldoutRequest, "episodes"),
        help=f"episodes per policy file (default %(default)s, at most {MAX_EPISODES}; walked "
        f"{HELDOUT_BATCH} at a time)",
    )
    _add_heldout_choice(p)
    p.add_argument(
        "--workers", type=process_count, help="environment processes (default: one per usable core)"
    )
    p.add_argument("--out", required=True, help="output folder: one record per policy file, heldout.md/.csv")
    _add_output(p, quiet=True)
    p.set_defaults(func=run_heldout)


def _add_heldout_choice(p: argparse.ArgumentParser) -> None:
    """``krl agent heldout``'s options of the choice: --choose, --seed-group, --env, --baseline(-env)."""
    p.add_argument(
        "--choose",
        help="LABEL,LABEL,...: choose one of these by held-out success, ties within one episode by targets; "
        "writes choice.json and the chosen recipe's chosen-config.json",
    )
    p.add_argument(
        "--seed-group",
        help="with --choose: copy the chosen label's policies (and run files) into this seed group as "
        "seed<S>/, beside the seeds chosen-config.json trains",
    )
    p.add_argument(
        "--env",
        help="an agent config file: every policy walks the episodes of its env section (terrains, pushes, "
        "reward) instead of its own training environment's, to compare recipes trained on different ground",
    )
    p.add_argument(
        "--baseline",
        help="with --choose: a --policy label the choice must beat by more than one episode's success rate, "
        "else nothing is chosen (choice.json says why; no chosen-config.json, nothing copied)",
    )
    p.add_argument(
        "--baseline-env",
        help="with --baseline: an agent config file on whose env's episodes the choice must also be no worse "
        "than the baseline by more than one episode (records under OUT/baseline-env)",
    )


def _add_rhythm(group) -> None:
    """``krl agent rhythm`` (defaults: :func:`krl.analysis.agent.rhythm.clock_rate_walks`)."""
    from krl.analysis.agent.rhythm import clock_rate_walks

    p = group.add_parser(
        "rhythm",
        help="the kernel walking with its gait clock at fixed rates: the bounds a gait-driving agent may use",
    )
    p.add_argument(
        "--rates", default="0.5,0.75,1,1.25,1.5,1.75,2", help="clock rates, multiples of the kernel's own"
    )
    p.add_argument(
        "--terrain",
        action="append",
        help=f"terrain (repeat; default {' and '.join(default_of(clock_rate_walks, 'terrains'))})",
    )
    add_field_option(p, "--kernel", clock_rate_walks, help="shipped kernel or kernel file")
    add_field_option(p, "--seconds", clock_rate_walks, type=float, help="walk length [s]")
    _add_output(p)
    p.set_defaults(func=run_rhythm)


def run_digest(args: argparse.Namespace) -> int:
    from krl.agent.config import AgentConfig
    from krl.analysis.agent.transitions import transition_digest

    for name, value in (("--envs", args.envs), ("--steps", args.steps)):
        if value is not None and value < 1:
            raise CliError(f"{name} must be >= 1, got {value}")
    configs = {path: AgentConfig.load(path) for path in args.config or ()} or {"agent-rp": AgentConfig()}
    options = given(num_envs=args.envs, steps=args.steps, seed=args.seed)
    emit(
        {"digests": [{"config": name, **transition_digest(c, **options)} for name, c in configs.items()]},
        args.json,
    )
    return 0


def _add_digest(group) -> None:
    """``krl agent digest`` (defaults: :func:`krl.analysis.agent.transitions.transition_digest`)."""
    from krl.analysis.agent.transitions import transition_digest

    p = group.add_parser(
        "digest",
        help="SHA-256 of the residual env's transitions under random actions: compare before and after a "
        "change to the engine, on one machine",
    )
    p.add_argument(
        "--config", action="append", help="an agent config file (repeat; default: the thesis's agent-rp)"
    )
    add_field_option(p, "--envs", transition_digest, "num_envs", type=int, help="robots")
    add_field_option(p, "--steps", transition_digest, type=int, help="control steps")
    add_field_option(p, "--seed", transition_digest, type=int, help="seed of robot 0 and of the actions")
    _add_output(p)
    p.set_defaults(func=run_digest)


def run_config(args: argparse.Namespace) -> int:
    import json

    from krl.agent.config import AgentConfig
    from krl.util.output import write_atomic

    config = AgentConfig.load_layers(args.layers)  # an AgentConfigError is a one-line error (krl.cli.main)
    text = json.dumps(config.to_json(), indent=2) + "\n"
    if args.out is None:
        sys.stdout.write(text)
        return 0
    write_atomic(Path(args.out), text)
    emit({"config": args.out, "layers": args.layers}, args.json)
    return 0


def _add_config(group) -> None:
    """``krl agent config``."""
    p = group.add_parser(
        "config",
        help="an agent config laid together from files, each over those before it (a recipe, then its "
        "changes), checked and written whole",
    )
    p.add_argument(
        "layers",
        nargs="+",
        metavar="CONFIG",
        help="agent config files (.json or .toml): the first a recipe, each next one a change laid over it "
        "(tables merge key by key, anything else replaces)",
    )
    p.add_argument("--out", help="write the config here (default: print it)")
    _add_output(p)
    p.set_defaults(func=run_config)
