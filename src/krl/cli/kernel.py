"""``krl kernel …``: train, tune, study, evaluate, run kernels and make their figures.

Training options default to ``None`` and fill only the fields given, so :class:`krl.kernel.train.TrainConfig`
and :class:`krl.kernel.model.NetworkConfig` stay the one home of every training default; the help texts
read the defaults from them.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path
from typing import Any

from krl.cli.common import (
    SHIPPED_KERNELS,
    default_of,
    emit,
    given,
    parse_ints,
    print_json_summary,
    process_count,
    run_controller,
)
from krl.cli.common import (
    add_run_arguments as add_common_run_arguments,
)

# --- train -------------------------------------------------------------------------------------------


def add_train_arguments(parser: argparse.ArgumentParser) -> None:
    from krl.kernel.features import VARIANTS
    from krl.kernel.model import ACTIVATIONS, NetworkConfig
    from krl.kernel.train import TrainConfig

    def default(name: str) -> str:
        return f"(default {default_of(TrainConfig, name)})"

    network = NetworkConfig()
    parser.add_argument("--data", required=True, help="expert dataset directory (krl collect)")
    parser.add_argument(
        "--out", required=True, help="run directory: kernel.npz, config.json, checkpoint, tb/"
    )
    parser.add_argument("--variant", help=f"{', '.join(VARIANTS)} {default('variant')}")
    parser.add_argument("--epochs", type=int, help=f"maximum number of epochs {default('epochs')}")
    parser.add_argument(
        "--patience", type=int, help=f"early-stopping patience [epochs] {default('patience')}"
    )
    parser.add_argument("--lr", type=float, help=f"initial learning rate {default('learning_rate')}")
    parser.add_argument(
        "--lr-decay", type=float, help=f"final/initial learning rate (linear) {default('lr_decay')}"
    )
    parser.add_argument("--batch-size", type=int, help=f"batch size {default('batch_size')}")
    parser.add_argument(
        "--hidden", help=f"hidden layer widths (default {','.join(map(str, network.hidden))})"
    )
    parser.add_argument(
        "--activation", choices=ACTIVATIONS, help=f"hidden activation (default {network.activation})"
    )
    parser.add_argument("--dropout", type=float, help=f"dropout probability (default {network.dropout})")
    parser.add_argument(
        "--batch-norm",
        action=argparse.BooleanOptionalAction,
        help=f"batch normalisation after each hidden layer (default {network.batch_norm})",
    )
    parser.add_argument("--max-train-targets", type=int, help="train on this many targets only")
    parser.add_argument("--seed", type=int, help=f"training seed {default('seed')}")
    parser.add_argument("--threads", type=int, help="PyTorch CPU threads")
    parser.add_argument("--no-tensorboard", action="store_true")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument("--json", action="store_true")


def config_from_args(args: argparse.Namespace):
    """The TrainConfig of :func:`add_train_arguments`' options (fields not given keep their defaults)."""
    from krl.kernel.model import NetworkConfig
    from krl.kernel.train import TrainConfig

    hidden = None if args.hidden is None else tuple(parse_ints(args.hidden, "--hidden"))
    network = NetworkConfig(
        **given(hidden=hidden, activation=args.activation, dropout=args.dropout, batch_norm=args.batch_norm)
    )
    return TrainConfig(
        network=network,
        **given(
            variant=args.variant,
            learning_rate=args.lr,
            lr_decay=args.lr_decay,
            batch_size=args.batch_size,
            epochs=args.epochs,
            patience=args.patience,
            max_train_targets=args.max_train_targets,
            seed=args.seed,
            threads=args.threads,
        ),
    )


def run_train(args: argparse.Namespace) -> int:
    from krl.data.reader import load_dataset
    from krl.kernel.train import train_kernel

    config = config_from_args(args)
    dataset = load_dataset(args.data)
    result = train_kernel(
        dataset, config, args.out, progress=not args.quiet, tensorboard=not args.no_tensorboard
    )
    emit(
        {
            "variant": config.variant,
            "val_l1": result.val_l1,
            "train_seconds": round(result.train_seconds, 1),
            "best_epoch": result.best_epoch,
            "epochs_run": result.epochs_run,
            "train_targets": result.kernel.metadata["train_targets"],
            "val_targets": result.kernel.metadata["val_targets"],
            "kernel": str(result.kernel_path),
        },
        args.json,
    )
    return 0


# --- tune --------------------------------------------------------------------------------------------


def add_tune_arguments(parser: argparse.ArgumentParser) -> None:
    from krl.kernel.train import TrainConfig
    from krl.kernel.tune import tune
    from krl.util.thesis import COMPARISON_EPOCHS

    parser.add_argument("--data", required=True, help="expert dataset directory (krl collect)")
    parser.add_argument("--out", required=True, help="directory for trials, study.db and best.json")
    parser.add_argument("--trials", type=int, default=20, help="trials to add to the study")
    parser.add_argument(
        "--epochs",
        type=int,
        default=COMPARISON_EPOCHS,
        help="epochs per trial (default: the thesis's %(default)s)",
    )
    parser.add_argument("--variant", help=f"kernel variant (default {default_of(TrainConfig, 'variant')})")
    parser.add_argument("--storage", help="Optuna storage URL (default: sqlite:///OUT/study.db)")
    parser.add_argument("--study-name", help=f"Optuna study name (default {default_of(tune, 'study_name')})")
    parser.add_argument(
        "--seed",
        type=int,
        help="seed of the sampler and of the trials' training (the data split is fixed); "
        f"give each process of a shared study its own (default {default_of(tune, 'seed')})",
    )
    parser.add_argument("--threads", type=int, help="PyTorch CPU threads")
    parser.add_argument("--quiet", action="store_true")
    parser.add_argument("--json", action="store_true")


def run_tune(args: argparse.Namespace) -> int:
    from krl.data.reader import load_dataset
    from krl.kernel.train import TrainConfig
    from krl.kernel.tune import tune

    base = TrainConfig(
        epochs=args.epochs,
        patience=args.epochs,
        **given(variant=args.variant, seed=args.seed, threads=args.threads),
    )
    summary = tune(
        load_dataset(args.data),
        args.out,
        args.trials,
        base=base,
        **given(storage=args.storage, study_name=args.study_name, seed=args.seed),
        progress=not args.quiet,
    )
    emit(summary, args.json)
    return 0


# --- studies -----------------------------------------------------------------------------------------


def add_study_arguments(parser: argparse.ArgumentParser) -> None:
    from krl.kernel.studies import STUDIES, THESIS_DATA_SIZE, VARIANT_DATA, StudyRequest
    from krl.util.thesis import COMPARISON_EPOCHS, THESIS_SEEDS

    parser.add_argument("study", choices=STUDIES, help="variants (Table 4.4), data-size (4.5), stance (4.3)")
    parser.add_argument("--out", default="docs/results/kernel", help="where the tables go")
    parser.add_argument("--runs", default="runs/studies", help="where the training runs go (resumable)")
    parser.add_argument("--data", help="data-size: the base dataset")
    parser.add_argument("--data-base", help="variants: base dataset (base, ind, dyn1)")
    parser.add_argument("--data-ext", help="variants: ext dataset")
    parser.add_argument("--data-dyn2", help="variants: dyn2 dataset (collected with resets)")
    parser.add_argument(
        "--data-stance", action="append", metavar="TAU=DIR", help="stance: a dataset per stance duration"
    )
    parser.add_argument("--seeds", default=",".join(map(str, THESIS_SEEDS)), help="training seeds")
    parser.add_argument(
        "--variants", default=",".join(VARIANT_DATA), help="variants: which variants to train (comma list)"
    )
    parser.add_argument(
        "--finished-only",
        action="store_true",
        help="train nothing: write the table from the runs that have finished, listing the others",
    )
    parser.add_argument(
        "--sizes", default=",".join(map(str, THESIS_DATA_SIZE)), help="data-size: training targets"
    )
    parser.add_argument(
        "--epochs",
        type=int,
        default=COMPARISON_EPOCHS,
        help="epochs per run (default %(default)s, the thesis's training length for kernel comparisons)",
    )
    parser.add_argument(
        "--walk-targets",
        type=int,
        default=default_of(StudyRequest, "walk_targets"),
        help="data-size, stance: count the kernels that walk to this many random waypoints (0: skip)",
    )
    parser.add_argument("--threads", type=int, help="PyTorch CPU threads")
    parser.add_argument("--quiet", action="store_true")
    parser.add_argument("--json", action="store_true")


def _stance_data(items: list[str] | None) -> dict[float, str]:
    """``--data-stance TAU=DIR`` items as {stance duration [s]: dataset}."""
    stance_data = {}
    for item in items or ():
        tau, sep, path = item.partition("=")
        try:
            stance_data[float(tau)] = path
        except ValueError:
            sep = ""
        if not sep or not path:
            raise ValueError(f"--data-stance expects TAU=DIR, got {item!r}")
    return stance_data


def run_study(args: argparse.Namespace) -> int:
    import shlex

    from krl.kernel import studies
    from krl.kernel.train import TrainConfig

    kinds = {"base": args.data_base, "ext": args.data_ext, "dyn2": args.data_dyn2}
    if args.study == "data-size":
        kinds = {"base": args.data}
    request = studies.StudyRequest(
        study=args.study,
        seeds=tuple(parse_ints(args.seeds, "--seeds")),
        train=TrainConfig(epochs=args.epochs, threads=args.threads),
        runs=Path(args.runs),
        out=Path(args.out),
        command="krl " + shlex.join(args.argv),
        datasets={kind: path for kind, path in kinds.items() if path},
        variants=tuple(v for v in args.variants.split(",") if v),
        sizes=tuple(parse_ints(args.sizes, "--sizes")) if args.study == "data-size" else (),
        stance_data=_stance_data(args.data_stance),
        finished_only=args.finished_only,
        walk_targets=args.walk_targets,
        progress=not args.quiet,
    )
    emit(studies.run_study(request), args.json)
    return 0


# --- eval --------------------------------------------------------------------------------------------


def add_eval_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--model", default="base", help=f"shipped kernel name ({SHIPPED_KERNELS}) or a kernel file"
    )
    parser.add_argument("--data", help="score on this dataset instead of fresh expert data")
    parser.add_argument("--targets", type=int, default=3, help="targets of fresh validation data")
    parser.add_argument("--seed", type=int, default=12345, help="seed of the fresh validation data")
    parser.add_argument(
        "--validation",
        action="store_true",
        help="with --data: score only the validation targets of the kernel's own training split",
    )
    parser.add_argument(
        "--breakdown",
        action="store_true",
        help="also the error of stance and swing legs, by time since the target started, and by swing "
        "clearance (ride minus step height)",
    )
    parser.add_argument("--json", action="store_true")


def run_eval(args: argparse.Namespace) -> int:
    from krl.data.reader import load_dataset
    from krl.kernel.registry import load_model, resolve_model
    from krl.kernel.scoring import fresh_validation_data, score

    kernel = load_model(args.model)
    if args.data:
        result = score(kernel, load_dataset(args.data), args.validation, args.breakdown)
        source = args.data + (" (validation targets)" if args.validation else "")
    else:
        if args.validation:
            raise ValueError("--validation needs --data (the kernel's training dataset)")
        if args.targets < 1:
            raise ValueError(f"--targets must be >= 1, got {args.targets}")
        with tempfile.TemporaryDirectory(prefix="krl-eval-") as directory:
            fresh = fresh_validation_data(kernel, args.targets, args.seed, Path(directory))
            result = score(kernel, fresh, breakdown=args.breakdown)
        source = f"fresh expert data ({args.targets} targets, seed {args.seed})"
    emit(
        {
            "variant": kernel.variant,
            "model": str(resolve_model(args.model)),
            **result,
            "data": source,
            "train_val_l1": kernel.metadata.get("val_l1"),
            "train_seconds": kernel.metadata.get("train_seconds"),
            "train_targets": kernel.metadata.get("train_targets"),
        },
        args.json,
    )
    return 0


# --- run ---------------------------------------------------------------------------------------------


def add_run_arguments(parser: argparse.ArgumentParser) -> None:
    add_common_run_arguments(parser)
    parser.add_argument(
        "--model", default="base", help=f"shipped kernel name ({SHIPPED_KERNELS}) or a kernel file"
    )
    parser.add_argument("--step-height", type=float, help="kernel-ext: step height [m], 0.05-0.18")
    parser.add_argument("--ride-height", type=float, help="kernel-ext: ride height [m], 0.18-0.28")
    parser.add_argument(
        "--gait", help="gait of Table 4.1 fed to the kernel (default: its training data's; Fig. 4.12: walk)"
    )


def run_run(args: argparse.Namespace) -> int:
    from krl.kernel.controller import KernelController
    from krl.kernel.registry import load_model, resolve_model

    kernel = load_model(args.model)
    controller = KernelController(
        kernel, gait=args.gait, step_height=args.step_height, ride_height=args.ride_height
    )
    summary = run_controller(args, controller)
    summary["model"] = str(resolve_model(args.model))
    summary["variant"] = kernel.variant
    summary["gait"] = controller.gait_name
    emit(summary, args.json)
    return 0


# --- figures -----------------------------------------------------------------------------------------


def add_figures_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``krl kernel figures``
    (defaults: :func:`krl.analysis.kernel.driver.make_kernel_figures`)."""
    from krl.analysis.kernel.context import CHOICES
    from krl.analysis.kernel.driver import make_kernel_figures

    def default(name: str) -> str:
        return f"(default {default_of(make_kernel_figures, name)})"

    parser.add_argument("which", metavar="WHICH", help=f"figure to make: {', '.join(CHOICES)}")
    parser.add_argument(
        "--out", required=True, metavar="DIR", help="output folder (PNG, JSON, CSV per figure)"
    )
    parser.add_argument("--model", help=f"kernel-base: shipped name or file {default('model')}")
    parser.add_argument(
        "--ext-model", help=f"kernel-ext for `heights`: shipped name or file {default('ext_model')}"
    )
    parser.add_argument("--ind-model", help="optional kernel-ind file for `walk-gait`")
    parser.add_argument("--expert-json", help="the expert's velocity.json (default docs/figures/expert/...)")
    parser.add_argument("--seed", type=int, help=f"seed of the waypoints and the simulator {default('seed')}")
    parser.add_argument(
        "--workers", type=process_count, help="processes for the velocity sweep (default: number of CPUs)"
    )
    parser.add_argument("--quick", action="store_true", help="tiny runs (tests)")
    parser.add_argument("--json", action="store_true", help="print a JSON summary instead of text")


def _figure_headline(name: str, table: dict[str, Any]) -> list[str]:
    def mm(value) -> str:
        return "nan" if value is None else f"{1e3 * value:.2f}"

    if name == "trajectories":
        fr, legs = table["l1_fr"], table["l1_all_legs"]
        return [f"  L1 FR x/y/z {mm(fr['x'])}/{mm(fr['y'])}/{mm(fr['z'])} mm, all legs {mm(legs['mean'])} mm"]
    if name == "symmetry":
        return [
            f"  {r['source']} vx={r['vx']}: y_asym {mm(r.get('y_asym'))} mm, y_corr {r.get('y_corr')}"
            for r in table["conditions"]
        ]
    if name == "walk-gait":
        return [
            f"  {m}: L1 FR x/y/z {mm(r['l1_fr']['x'])}/{mm(r['l1_fr']['y'])}/{mm(r['l1_fr']['z'])} mm, "
            f"phantom lifts {r['phantom_lift_fraction']}"
            for m, r in table["results"].items()
        ]
    if name in ("velocity", "heights"):
        return [
            f"  {key}: slope {fit['slope']}, offset {fit['offset']}"
            + (f", falls {fit['falls']}" if "falls" in fit else "")
            for key, fit in table["fits"].items()
        ]
    return []


def run_figures(args: argparse.Namespace) -> int:
    """``krl kernel figures``: make the figure(s); print a summary (text or ``--json``)."""
    from krl.analysis.kernel.driver import make_kernel_figures

    summary = make_kernel_figures(
        args.which,
        args.out,
        **given(
            model=args.model,
            ext_model=args.ext_model,
            ind_model=args.ind_model,
            expert_json=args.expert_json,
            seed=args.seed,
            workers=args.workers,
        ),
        quick=args.quick,
    )
    if args.json:
        print_json_summary(summary)
    else:
        for name, figure in summary["figures"].items():
            print(f"{name} ({figure['table']['thesis_figure']}): {figure['png']}")
            for line in _figure_headline(name, figure["table"]):
                print(line)
        print(f"{summary['workers']} worker(s), {summary['wall_seconds']} s")
    return 0


def register(subparsers) -> None:
    """Add ``krl kernel train|tune|study|eval|run|figures`` to the main parser's subcommands."""
    kernel = subparsers.add_parser("kernel", help="the kernel: train, tune, study, evaluate, run, figures")
    commands = kernel.add_subparsers(dest="kernel_command", required=True, metavar="KERNEL_COMMAND")
    for name, help_text, add, run in (
        ("train", "train a kernel variant on an expert dataset", add_train_arguments, run_train),
        ("tune", "Optuna search over Table A.2's space (resumable)", add_tune_arguments, run_tune),
        ("study", "the result tables 4.3-4.5 (resumable training runs)", add_study_arguments, run_study),
        ("eval", "score a kernel on fresh expert data (or --data)", add_eval_arguments, run_eval),
        ("run", "walk with a kernel to waypoints or at a fixed command", add_run_arguments, run_run),
        ("figures", "the kernel's figures (Figs. 4.9-4.13, 4.15)", add_figures_arguments, run_figures),
    ):
        parser = commands.add_parser(name, help=help_text)
        add(parser)
        parser.set_defaults(func=run)
