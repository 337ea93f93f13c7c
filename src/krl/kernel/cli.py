"""``krl kernel …``: train, evaluate and run kernels."""

from __future__ import annotations

import argparse
import itertools
import tempfile
from importlib.resources import files
from pathlib import Path
from typing import Any

import numpy as np

SHIPPED_MODELS: tuple[str, ...] = ("base", "ext")
"""Kernels shipped with krl (``src/krl/kernel/models/kernel-<name>.npz``)."""


def shipped_model_path(name: str) -> Path:
    """Path of a shipped kernel by name."""
    return Path(str(files("krl.kernel") / "models" / f"kernel-{name}.npz"))


def resolve_model(model: str) -> Path:
    """A shipped model's name (``base``, ``ext``) or a path to a kernel file -> the file's path."""
    if model in SHIPPED_MODELS:
        return shipped_model_path(model)
    return Path(model)


def _load(model: str):
    from krl.kernel.model import load_kernel

    return load_kernel(resolve_model(model))


# --- train -------------------------------------------------------------------------------------------


def add_train_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--data", required=True, help="expert dataset directory (krl collect)")
    parser.add_argument(
        "--out", required=True, help="run directory: kernel.npz, config.json, checkpoint, tb/"
    )
    parser.add_argument("--variant", default="base", help="base, ind, ext, dyn1, dyn2")
    parser.add_argument("--epochs", type=int, default=30)
    parser.add_argument("--patience", type=int, default=5, help="early-stopping patience [epochs]")
    parser.add_argument("--lr", type=float, default=0.0024, help="initial learning rate")
    parser.add_argument("--lr-decay", type=float, default=0.7, help="final/initial learning rate (linear)")
    parser.add_argument("--batch-size", type=int, default=200)
    parser.add_argument("--hidden", default="256,256,256,256", help="hidden layer widths")
    parser.add_argument("--activation", default="relu", choices=["relu", "tanh"])
    parser.add_argument("--dropout", type=float, default=0.0002)
    parser.add_argument("--batch-norm", action="store_true")
    parser.add_argument("--max-train-targets", type=int, help="train on this many targets only")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, help="PyTorch CPU threads")
    parser.add_argument("--no-tensorboard", action="store_true")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument("--json", action="store_true")


def config_from_args(args: argparse.Namespace):
    from krl.kernel.model import NetworkConfig
    from krl.kernel.train import TrainConfig

    try:
        hidden = tuple(int(part) for part in args.hidden.split(","))
    except ValueError:
        raise ValueError(f"--hidden expects comma-separated integers, got {args.hidden!r}") from None
    return TrainConfig(
        variant=args.variant,
        network=NetworkConfig(
            hidden=hidden, activation=args.activation, dropout=args.dropout, batch_norm=args.batch_norm
        ),
        learning_rate=args.lr,
        lr_decay=args.lr_decay,
        batch_size=args.batch_size,
        epochs=args.epochs,
        patience=args.patience,
        max_train_targets=args.max_train_targets,
        seed=args.seed,
        threads=args.threads,
    )


def run_train(args: argparse.Namespace) -> int:
    from krl.cli import emit
    from krl.data.schema import load_dataset
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
    parser.add_argument("--data", required=True, help="expert dataset directory (krl collect)")
    parser.add_argument("--out", required=True, help="directory for trials, study.db and best.json")
    parser.add_argument("--trials", type=int, default=20, help="trials to add to the study")
    parser.add_argument("--epochs", type=int, default=10, help="epochs per trial (thesis: 10)")
    parser.add_argument("--variant", default="base")
    parser.add_argument("--storage", help="Optuna storage URL (default: sqlite:///OUT/study.db)")
    parser.add_argument("--study-name", default="kernel")
    parser.add_argument(
        "--seed",
        type=int,
        default=0,
        help="seed of the sampler and of the trials' training (the data split is fixed); "
        "give each process of a shared study its own",
    )
    parser.add_argument("--threads", type=int, help="PyTorch CPU threads")
    parser.add_argument("--quiet", action="store_true")
    parser.add_argument("--json", action="store_true")


def run_tune(args: argparse.Namespace) -> int:
    from krl.cli import emit
    from krl.data.schema import load_dataset
    from krl.kernel.train import TrainConfig
    from krl.kernel.tune import tune

    base = TrainConfig(
        variant=args.variant, epochs=args.epochs, patience=args.epochs, seed=args.seed, threads=args.threads
    )
    summary = tune(
        load_dataset(args.data),
        args.out,
        args.trials,
        base=base,
        storage=args.storage,
        study_name=args.study_name,
        seed=args.seed,
        progress=not args.quiet,
    )
    emit(summary, args.json)
    return 0


# --- studies -----------------------------------------------------------------------------------------


def _ints(text: str, option: str) -> list[int]:
    try:
        return [int(part) for part in text.split(",") if part]
    except ValueError:
        raise ValueError(f"{option} expects comma-separated integers, got {text!r}") from None


def add_study_arguments(parser: argparse.ArgumentParser) -> None:
    from krl.kernel.studies import STUDIES, THESIS_SEEDS, VARIANT_DATA

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
    parser.add_argument("--sizes", default="10,25,50,100,200,400", help="data-size: training targets")
    parser.add_argument(
        "--epochs",
        type=int,
        default=10,
        help="epochs per run (default 10, the thesis's training length for kernel comparisons)",
    )
    parser.add_argument(
        "--walk-targets",
        type=int,
        default=5,
        help="data-size, stance: count the kernels that walk to this many random waypoints (0: skip)",
    )
    parser.add_argument("--threads", type=int, help="PyTorch CPU threads")
    parser.add_argument("--quiet", action="store_true")
    parser.add_argument("--json", action="store_true")


def run_study(args: argparse.Namespace) -> int:
    import shlex

    from krl.cli import emit
    from krl.kernel import studies
    from krl.kernel.train import TrainConfig

    seeds = _ints(args.seeds, "--seeds")
    base = TrainConfig(epochs=args.epochs, threads=args.threads)
    if args.study == "variants":
        data = {
            k: v for k, v in (("base", args.data_base), ("ext", args.data_ext), ("dyn2", args.data_dyn2)) if v
        }
        if not data:
            raise ValueError("variants needs at least one of --data-base, --data-ext, --data-dyn2")
        variants = [v for v in args.variants.split(",") if v]
        unknown = sorted(set(variants) - set(studies.VARIANT_DATA))
        if unknown or not variants:
            raise ValueError(
                f"--variants: unknown variant(s) {', '.join(unknown) or '(none given)'}; "
                f"known: {', '.join(studies.VARIANT_DATA)}"
            )
        runs, key = studies.plan_variants(data, seeds, base, variants), "variant"
    elif args.study == "data-size":
        if not args.data:
            raise ValueError("data-size needs --data (a base dataset)")
        runs, key = studies.plan_data_size(args.data, _ints(args.sizes, "--sizes"), seeds, base), "targets"
    else:
        stance_data = {}
        for item in args.data_stance or ():
            tau, sep, path = item.partition("=")
            try:
                stance_data[float(tau)] = path
            except ValueError:
                sep = ""
            if not sep or not path:
                raise ValueError(f"--data-stance expects TAU=DIR, got {item!r}")
        if not stance_data:
            raise ValueError("stance needs --data-stance TAU=DIR (one per stance duration)")
        runs, key = studies.plan_stance(stance_data, seeds, base), "stance_duration"
    if args.finished_only:
        records, missing = studies.finished(runs, Path(args.runs) / args.study)
        if not records:
            raise ValueError(f"no run of this study has finished in {Path(args.runs) / args.study}")
    else:
        records, missing = studies.execute(runs, Path(args.runs) / args.study, progress=not args.quiet), []
    rows = studies.thesis_columns(args.study, studies.summarise(records, key))
    if args.study != "variants" and args.walk_targets > 0:
        studies.add_walking(rows, records, key, args.walk_targets)
    command = "krl " + shlex.join(args.argv)
    path = studies.write_table(args.study, rows, records, Path(args.out), command, missing)
    emit({"study": args.study, "table": str(path), "rows": rows, "unfinished": missing}, args.json)
    return 0


# --- eval --------------------------------------------------------------------------------------------


def add_eval_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--model", default="base", help="shipped kernel name (base, ext) or a kernel file")
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


TIME_BINS: tuple[float, ...] = (0.0, 0.5, 1.0, 2.0, np.inf)
"""Edges [s] of ``--breakdown``'s bins of time since the walk to the current target started."""
CLEARANCE_BINS: tuple[float, ...] = (-np.inf, 0.04, 0.06, 0.08, 0.10, np.inf)
"""Edges [m] of ``--breakdown``'s bins of ride height minus step height (how far below the hips the
swing apex stays)."""


def score(kernel, dataset, validation_only: bool = False, breakdown: bool = False) -> dict[str, Any]:
    """Mean absolute error [m] of ``kernel`` on the rows of ``dataset``, overall and per axis.

    ``validation_only``: only the targets that the kernel's training run held out (the dataset must be
    the one it was trained on). ``breakdown``: also the error by leg phase, by time since the target
    started and by swing clearance; each bin reports its share of rows and its mean error.
    """
    from krl.kernel.features import features_from_columns, labels_from_columns, split_by_target
    from krl.kernel.train import TrainConfig

    columns = {name: np.asarray(dataset[name]) for name in dataset.keys()}
    if validation_only:
        trained_on = kernel.metadata.get("dataset_hash")
        if trained_on != dataset.content_hash:
            raise ValueError(
                f"--validation: the kernel was trained on dataset {str(trained_on)[:12]}, "
                f"not on this one ({dataset.content_hash[:12]})"
            )
        config = TrainConfig.from_json(kernel.metadata["config"])
        rows = split_by_target(columns["target_index"], config.validation_fraction, config.split_seed)
        columns = {name: column[rows] for name, column in columns.items()}
    features = features_from_columns(kernel.variant, columns)
    labels = labels_from_columns(kernel.variant, columns)
    n = len(columns["target_index"])
    error = np.abs(kernel.predict(features) - labels).reshape(n, -1, 3)
    result: dict[str, Any] = {
        "val_l1": float(error.mean()),
        "val_l1_xyz": [float(e) for e in error.mean(axis=(0, 1))],
        "rows": n,
        "targets": len(np.unique(columns["target_index"])),
    }
    if breakdown:
        result["breakdown"] = error_breakdown(error, columns)
    return result


def error_breakdown(error: np.ndarray, columns: dict[str, np.ndarray]) -> dict[str, Any]:
    """Where the error is. ``error``: |prediction − label| [m], shape (N, 4, 3), rows in dataset order."""
    stance = np.asarray(columns["stance"], dtype=bool)
    target = columns["target_index"]
    first = np.r_[True, target[1:] != target[:-1]]
    started = np.maximum.accumulate(np.where(first, np.arange(len(target)), 0))
    since_target = columns["time"] - columns["time"][started]
    clearance = columns["ride_height"] - columns["step_height"]

    def bins(values: np.ndarray, edges: tuple[float, ...], unit: str) -> list[dict[str, Any]]:
        out = []
        for low, high in itertools.pairwise(edges):
            rows = (values >= low) & (values < high)
            if rows.any():
                label = f"[{low:g}, {high:g}) {unit}"
                out.append({"bin": label, "rows": float(rows.mean()), "l1": float(error[rows].mean())})
        return out

    return {
        "stance_l1": float(error[stance].mean()) if stance.any() else None,
        "swing_l1": float(error[~stance].mean()) if (~stance).any() else None,
        "by_time_since_target": bins(since_target, TIME_BINS, "s"),
        "by_swing_clearance": bins(clearance, CLEARANCE_BINS, "m"),
    }


def fresh_validation_data(kernel, targets: int, seed: int, directory: Path):
    """Collect ``targets`` targets of expert data with the kernel's training settings into ``directory``."""
    from krl.control.expert import ExpertParams
    from krl.control.mpc import MPCParams
    from krl.data.collect import CollectConfig, collect_dataset
    from krl.data.schema import load_dataset

    settings = kernel.metadata.get("dataset_settings", {})
    expert = dict(settings.get("expert", {}))
    mpc = expert.pop("mpc", None)
    params = ExpertParams(**expert, **({"mpc": MPCParams(**_tuples(mpc))} if mpc else {}))
    mode = settings.get("mode", "base")
    if mode not in ("base", "ext", "dyn2"):
        mode = "base"
    config = CollectConfig(
        targets=targets,
        mode=mode,
        seed=seed,
        expert=params,
        targets_per_episode=targets,
        ext_heights=settings.get("ext_heights", "both"),  # ext data made before the choice: both
    )
    collect_dataset(directory, config)
    return load_dataset(directory)


def _tuples(values: dict[str, Any]) -> dict[str, Any]:
    return {key: tuple(value) if isinstance(value, list) else value for key, value in values.items()}


def run_eval(args: argparse.Namespace) -> int:
    from krl.cli import emit
    from krl.data.schema import load_dataset

    kernel = _load(args.model)
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
    from krl.cli import add_run_arguments as add_common

    add_common(parser)
    parser.add_argument("--model", default="base", help="shipped kernel name (base, ext) or a kernel file")
    parser.add_argument("--step-height", type=float, help="kernel-ext: step height [m], 0.05-0.18")
    parser.add_argument("--ride-height", type=float, help="kernel-ext: ride height [m], 0.18-0.28")
    parser.add_argument(
        "--gait", help="gait of Table 4.1 fed to the kernel (default: its training data's; Fig. 4.12: walk)"
    )


def run_run(args: argparse.Namespace) -> int:
    from krl.cli import emit, run_controller
    from krl.kernel.controller import KernelController

    kernel = _load(args.model)
    controller = KernelController(
        kernel, gait=args.gait, step_height=args.step_height, ride_height=args.ride_height
    )
    summary = run_controller(args, controller)
    summary["model"] = str(resolve_model(args.model))
    summary["variant"] = kernel.variant
    summary["gait"] = controller.gait_name
    emit(summary, args.json)
    return 0


def register(subparsers) -> None:
    """Add ``krl kernel train|tune|study|eval|run|figures`` to the main parser's subcommands."""
    from krl.kernel import figures

    kernel = subparsers.add_parser("kernel", help="the kernel: train, tune, study, evaluate, run, figures")
    commands = kernel.add_subparsers(dest="kernel_command", required=True, metavar="KERNEL_COMMAND")
    for name, help_text, add, run in (
        ("train", "train a kernel variant on an expert dataset", add_train_arguments, run_train),
        ("tune", "Optuna search over Table A.2's space (resumable)", add_tune_arguments, run_tune),
        ("study", "the result tables 4.3-4.5 (resumable training runs)", add_study_arguments, run_study),
        ("eval", "score a kernel on fresh expert data (or --data)", add_eval_arguments, run_eval),
        ("run", "walk with a kernel to waypoints or at a fixed command", add_run_arguments, run_run),
        ("figures", "the kernel's figures (Figs. 4.9-4.13, 4.15)", figures.add_arguments, figures.run),
    ):
        parser = commands.add_parser(name, help=help_text)
        add(parser)
        parser.set_defaults(func=run)
