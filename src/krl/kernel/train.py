"""Training the kernel (thesis 4.2.6.3, Table 4.4) as a run: L1 loss, Adam, linear learning-rate decay.

``train_kernel`` fits a kernel variant on an expert dataset, validating on whole held-out targets
(80/20 by default), with a progress bar, TensorBoard logs, early stopping on the validation loss and a
checkpoint after every epoch from which an interrupted run resumes exactly. The figure reported as
``val_l1`` is the mean absolute error of the foot positions **in metres** over all outputs of the
validation set (the thesis's "validation loss"; the network itself is trained on standardised outputs).
The network and its optimisation are :mod:`krl.kernel.fitting`'s; this module runs them, resumably.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from krl.kernel.features import features_from_columns, input_names, labels_from_columns, split_by_target
from krl.kernel.fitting import (
    Learner,
    Scaling,
    Tensors,
    TrainConfig,
    build_learner,
    export_weights,
    standardise,
    train_epoch,
    validate,
)
from krl.kernel.model import Kernel
from krl.util.output import write_atomic

CHECKPOINT_NAME = "checkpoint.pt"
KERNEL_NAME = "kernel.npz"
CONFIG_NAME = "config.json"

_COLUMNS = (
    "v_cmd",
    "yaw_cmd",
    "normalised_phase",
    "sine_phase",
    "stance",
    "foot_ref",
    "foot_pos_next",
    "step_height",
    "ride_height",
    "base_lin_vel",
    "base_ang_vel",
    "q",
    "dq",
    "com",
    "projected_gravity",
    "new_segment",
    "episode",
    "target_index",
)


@dataclass
class TrainResult:
    """Outcome of a training run."""

    kernel: Kernel
    val_l1: float
    """Best validation mean absolute error [m]."""
    best_epoch: int
    epochs_run: int
    train_seconds: float
    """Wall time spent training, summed over resumed sessions [s]."""
    history: list[dict[str, float]]
    kernel_path: Path


def prepare_data(dataset, config: TrainConfig) -> dict[str, np.ndarray]:
    """Features, labels and the train/validation split of ``dataset`` for ``config``."""
    columns = {name: dataset[name] for name in _COLUMNS if name in dataset}
    features = features_from_columns(config.variant, columns)
    labels = labels_from_columns(config.variant, columns)
    target = np.asarray(columns["target_index"])
    validation = split_by_target(target, config.validation_fraction, config.split_seed)
    train = ~validation
    if config.max_train_targets is not None:
        train_targets = np.unique(target[train])
        if config.max_train_targets > len(train_targets):
            raise ValueError(
                f"max_train_targets={config.max_train_targets} exceeds the "
                f"{len(train_targets)} training targets"
            )
        keep = np.random.default_rng(config.seed + 1).choice(
            train_targets, config.max_train_targets, replace=False
        )
        train &= np.isin(target, keep)
    train_targets = len(np.unique(target[train]))
    val_targets = len(np.unique(target[validation]))
    if config.variant == "ind":  # four samples (legs) per row
        validation = np.repeat(validation, 4)
        train = np.repeat(train, 4)
    return {
        "x_train": features[train],
        "y_train": labels[train],
        "x_val": features[validation],
        "y_val": labels[validation],
        "train_targets": train_targets,
        "val_targets": val_targets,
    }


def run_hash(config: TrainConfig, dataset_hash: str) -> str:
    """Identity of a training run: its settings and its data (stored in ``config.json``)."""
    text = json.dumps({"config": config.to_json(), "dataset": dataset_hash}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _atomic_torch_save(obj: Any, path: Path) -> None:
    import torch

    temporary = path.with_name(f".{path.name}.tmp")
    torch.save(obj, temporary)
    os.replace(temporary, path)


def train_kernel(
    dataset,
    config: TrainConfig,
    out_dir: str | Path,
    progress: bool = True,
    tensorboard: bool = True,
    data: dict[str, np.ndarray] | None = None,
    on_epoch: Callable[[int, float], None] | None = None,
) -> TrainResult:
    """Train (or resume training) a kernel; writes ``kernel.npz``, ``config.json`` and a checkpoint.

    Args:
        dataset: a :class:`krl.data.reader.Dataset`.
        config: the run's settings.
        out_dir: where outputs go; an existing checkpoint there with the same config and dataset is
            resumed, a different one is an error.
        progress: show a progress bar.
        tensorboard: write TensorBoard logs to ``out_dir/tb``.
        data: precomputed :func:`prepare_data` output (to share between runs on one dataset).
        on_epoch: called with (epoch, validation L1 [m]) after each epoch's checkpoint is written;
            it may raise to stop the run (Optuna pruning, tests), which can then be resumed.
    """
    import torch

    out = Path(out_dir)
    dataset_hash = dataset.content_hash
    this_run = _check_run_folder(out, config, dataset_hash)
    # Every check of the data comes before the first write, so a refused run leaves --out as it was.
    data = data or prepare_data(dataset, config)
    _start_run_folder(out, this_run, config, dataset_hash)

    if config.threads:
        torch.set_num_threads(config.threads)
    scaling = Scaling.fit(data["x_train"], data["y_train"])
    tensors = standardise(data, scaling)
    learner = build_learner(config, tensors.x_train.shape[1], tensors.y_train.shape[1])
    checkpoint_path = out / CHECKPOINT_NAME
    state = _resume(checkpoint_path, this_run, learner) if checkpoint_path.exists() else _fresh_state()

    writer = None
    if tensorboard:
        from torch.utils.tensorboard import SummaryWriter

        writer = SummaryWriter(log_dir=str(out / "tb"), purge_step=state["epoch"])
    _run_epochs(learner, tensors, config, state, this_run, checkpoint_path, writer, progress, on_epoch)
    if writer is not None:
        writer.close()
    return _export(learner.net, state, config, scaling, dataset, dataset_hash, data, out)


def _check_run_folder(out: Path, config: TrainConfig, dataset_hash: str) -> str:
    """The run's hash (:func:`run_hash`); ValueError when ``out`` holds a run of other settings or data."""
    this_run = run_hash(config, dataset_hash)
    config_path = out / CONFIG_NAME
    if config_path.exists():
        saved = json.loads(config_path.read_text())
        if saved.get("run_hash") != this_run:
            raise ValueError(
                f"{out} holds a training run with other settings or data (run {saved.get('run_hash')}, "
                f"this one {this_run}); choose another --out"
            )
    return this_run


def _start_run_folder(out: Path, this_run: str, config: TrainConfig, dataset_hash: str) -> None:
    """Create ``out`` with its ``config.json`` (the run's identity and settings) unless it has one."""
    config_path = out / CONFIG_NAME
    if not config_path.exists():
        out.mkdir(parents=True, exist_ok=True)
        _write_json(
            config_path, {"run_hash": this_run, "dataset_hash": dataset_hash, "config": config.to_json()}
        )


def _fresh_state() -> dict[str, Any]:
    """The loop state before the first epoch (saved in every checkpoint)."""
    return {
        "epoch": 0,
        "best": float("inf"),
        "best_epoch": -1,
        "best_state": None,
        "history": [],
        "seconds": 0.0,
    }


def _run_epochs(
    learner: Learner,
    tensors: Tensors,
    config: TrainConfig,
    state: dict[str, Any],
    this_run: str,
    checkpoint_path: Path,
    writer,
    progress: bool,
    on_epoch: Callable[[int, float], None] | None,
) -> None:
    """Train from ``state`` (updated in place) until ``config.epochs`` or early stopping; after each epoch
    log it to ``writer`` (a TensorBoard writer, or None), write the checkpoint, then call ``on_epoch``."""
    from krl.util.progress import progress_bar

    with progress_bar(progress, unit="epochs") as bar:
        task = bar.add_task(f"kernel-{config.variant}", total=config.epochs, completed=state["epoch"])
        while state["epoch"] < config.epochs and state["epoch"] - state["best_epoch"] <= config.patience:
            started = time.perf_counter()
            train_loss = train_epoch(learner, tensors, config.batch_size)
            learner.scheduler.step()
            val_l1 = validate(learner.net, tensors)
            epoch = state["epoch"]
            if not np.isfinite(val_l1):
                raise ValueError(
                    f"epoch {epoch}: the validation L1 is not finite ({val_l1}); training diverged "
                    "(try a lower --lr, with another --out)"
                )
            state["seconds"] += time.perf_counter() - started
            _record_epoch(state, learner, train_loss, val_l1)
            if writer is not None:
                _log_epoch(writer, state["history"][-1])
            _save_checkpoint(checkpoint_path, this_run, learner, state)
            bar.update(task, advance=1, description=f"kernel-{config.variant} val L1 {val_l1:.2e} m")
            if on_epoch is not None:
                on_epoch(epoch, val_l1)


def _record_epoch(state: dict[str, Any], learner: Learner, train_loss: float, val_l1: float) -> None:
    """Append the epoch that just ran to ``state``'s history, keep the network if it is the best, move on."""
    epoch = state["epoch"]
    state["history"].append(
        {"epoch": epoch, "train_loss": train_loss, "val_l1": val_l1, "lr": learner.scheduler.get_last_lr()[0]}
    )
    if val_l1 < state["best"]:
        state["best"], state["best_epoch"] = val_l1, epoch
        state["best_state"] = {k: v.clone() for k, v in learner.net.state_dict().items()}
    state["epoch"] = epoch + 1


def _log_epoch(writer, entry: dict[str, float]) -> None:
    """Write one history entry (:func:`_record_epoch`) to TensorBoard."""
    epoch = entry["epoch"]
    writer.add_scalar("loss/train_normalised_l1", entry["train_loss"], epoch)
    writer.add_scalar("loss/val_l1_m", entry["val_l1"], epoch)
    writer.add_scalar("lr", entry["lr"], epoch)
    writer.flush()


def _save_checkpoint(path: Path, this_run: str, learner: Learner, state: dict[str, Any]) -> None:
    """Everything an interrupted run needs to resume exactly (:func:`_resume`), written atomically."""
    import torch

    _atomic_torch_save(
        {
            "run_hash": this_run,
            "net": learner.net.state_dict(),
            "optimizer": learner.optimizer.state_dict(),
            "scheduler": learner.scheduler.state_dict(),
            "generator": learner.generator.get_state(),
            "torch_rng": torch.get_rng_state(),
            "state": state,
        },
        path,
    )


def _export(
    net,
    state: dict[str, Any],
    config: TrainConfig,
    scaling: Scaling,
    dataset,
    dataset_hash: str,
    data: dict[str, np.ndarray],
    out: Path,
) -> TrainResult:
    """Load the best epoch's weights into ``net`` and save them, with ``scaling`` and the run's metadata, as
    ``out/kernel.npz``; the run's result."""
    net.load_state_dict(state["best_state"])
    net.eval()
    kernel = Kernel(
        variant=config.variant,
        network=config.network,
        weights=export_weights(net),
        input_mean=scaling.input_mean.astype(np.float64),
        input_std=scaling.input_std.astype(np.float64),
        output_mean=scaling.output_mean.astype(np.float64),
        output_std=scaling.output_std.astype(np.float64),
        metadata={
            "variant": config.variant,
            "config": config.to_json(),
            "inputs": input_names(config.variant),
            "dataset_hash": dataset_hash,
            "dataset_settings": _json_safe(getattr(dataset, "settings", {})),
            "train_targets": data["train_targets"],
            "val_targets": data["val_targets"],
            "val_l1": state["best"],
            "best_epoch": state["best_epoch"],
            "epochs_run": state["epoch"],
            "train_seconds": state["seconds"],
            "created": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        },
    )
    kernel_path = kernel.save(out / KERNEL_NAME)
    return TrainResult(
        kernel=kernel,
        val_l1=state["best"],
        best_epoch=state["best_epoch"],
        epochs_run=state["epoch"],
        train_seconds=state["seconds"],
        history=state["history"],
        kernel_path=kernel_path,
    )


def _resume(checkpoint_path: Path, this_run: str, learner: Learner) -> dict[str, Any]:
    """Restore the network, optimiser, schedule and random states from a checkpoint; return the loop state.

    Raises ValueError with one line naming the file when it is not a checkpoint of this run (torch's own
    messages run over several lines and suggest loading with ``weights_only=False``, which would run
    pickled code, so they are not passed on).
    """
    import torch

    try:
        checkpoint = torch.load(checkpoint_path, weights_only=True)
    except Exception:  # torch raises several types for damaged files, none of them telling more
        raise ValueError(
            f"checkpoint {checkpoint_path} is corrupt or not a krl training checkpoint (torch cannot load "
            "it); delete it to start over"
        ) from None
    if not isinstance(checkpoint, dict):
        raise ValueError(
            f"checkpoint {checkpoint_path} is not a krl training checkpoint (it holds a "
            f"{type(checkpoint).__name__}); delete it to start over"
        )
    if checkpoint.get("run_hash") != this_run:
        raise ValueError(f"checkpoint {checkpoint_path} belongs to another run; choose another --out")
    try:
        learner.net.load_state_dict(checkpoint["net"])
        learner.optimizer.load_state_dict(checkpoint["optimizer"])
        learner.scheduler.load_state_dict(checkpoint["scheduler"])
        learner.generator.set_state(checkpoint["generator"])
        torch.set_rng_state(checkpoint["torch_rng"])
        return checkpoint["state"]
    except Exception as error:  # missing keys, tensors of other shapes, foreign objects
        raise ValueError(
            f"checkpoint {checkpoint_path} is damaged ({type(error).__name__} restoring it); "
            "delete it to start over"
        ) from None


def _json_safe(value: Any) -> Any:
    return json.loads(json.dumps(value, default=str))


def _write_json(path: Path, value: Any) -> None:
    write_atomic(path, json.dumps(value, indent=2, sort_keys=True))


__all__ = ["TrainConfig", "TrainResult", "prepare_data", "run_hash", "train_kernel"]
