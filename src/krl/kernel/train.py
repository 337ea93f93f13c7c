"""Training the kernel (thesis 4.2.6.3, Table 4.4): L1 loss, Adam, linear learning-rate decay.

``train_kernel`` fits a kernel variant on an expert dataset, validating on whole held-out targets
(80/20 by default), with a progress bar, TensorBoard logs, early stopping on the validation loss and a
checkpoint after every epoch from which an interrupted run resumes exactly. The figure reported as
``val_l1`` is the mean absolute error of the foot positions **in metres** over all outputs of the
validation set (the thesis's "validation loss"; the network itself is trained on standardised outputs).
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from krl.kernel.features import (
    check_variant,
    features_from_columns,
    input_names,
    labels_from_columns,
    split_by_target,
)
from krl.kernel.model import Kernel, NetworkConfig
from krl.util.output import write_atomic

CHECKPOINT_NAME = "checkpoint.pt"
KERNEL_NAME = "kernel.npz"
CONFIG_NAME = "config.json"
MIN_STD = 1e-6
"""A feature or label whose training standard deviation is below this is constant: it is centred but not
scaled [its own unit]."""
VALIDATION_BATCH = 8192
"""Rows per forward pass when validating (memory only; the result does not depend on it)."""

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


@dataclass(frozen=True)
class TrainConfig:
    """Everything that determines a training run (saved beside its outputs)."""

    variant: str = "base"
    """Kernel variant (``krl.kernel.features.VARIANTS``)."""
    network: NetworkConfig = field(default_factory=NetworkConfig)
    """Architecture."""
    learning_rate: float = 0.0024
    """Initial Adam learning rate."""
    lr_decay: float = 0.7
    """The learning rate falls linearly from its initial value to ``lr_decay`` times it at the last
    epoch (our reading of the thesis's "linear LR decay 0.7", docs/kernel.md)."""
    batch_size: int = 200
    epochs: int = 30
    """Maximum number of epochs."""
    patience: int = 5
    """Stop after this many epochs without a new best validation loss."""
    validation_fraction: float = 0.2
    """Fraction of targets held out for validation."""
    max_train_targets: int | None = None
    """Use only this many of the training targets (the data-size study); the validation set does not
    change with it."""
    seed: int = 0
    """Seeds the initialisation, dropout, the batch order and the training-target subsample."""
    split_seed: int = 0
    """Seeds the train/validation split (kept fixed across seeds so studies share one validation set)."""
    threads: int | None = None
    """PyTorch CPU threads (default: PyTorch's choice)."""

    def __post_init__(self) -> None:
        check_variant(self.variant)
        if not self.learning_rate > 0:
            raise ValueError(f"learning_rate must be > 0, got {self.learning_rate}")
        if not 0 < self.lr_decay <= 1:
            raise ValueError(f"lr_decay must be in (0, 1], got {self.lr_decay}")
        if self.batch_size < 1 or self.epochs < 1 or self.patience < 1:
            raise ValueError("batch_size, epochs and patience must be >= 1")
        if self.max_train_targets is not None and self.max_train_targets < 1:
            raise ValueError(f"max_train_targets must be >= 1, got {self.max_train_targets}")

    def to_json(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> TrainConfig:
        network = NetworkConfig(**{**data["network"], "hidden": tuple(data["network"]["hidden"])})
        return cls(**{**data, "network": network})


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


def _build_network(config: TrainConfig, n_in: int, n_out: int):
    import torch.nn as nn

    layers: list[nn.Module] = []
    width = n_in
    for hidden in config.network.hidden:
        layers.append(nn.Linear(width, hidden))
        if config.network.batch_norm:
            layers.append(nn.BatchNorm1d(hidden))
        layers.append(nn.ReLU() if config.network.activation == "relu" else nn.Tanh())
        if config.network.dropout > 0:
            layers.append(nn.Dropout(config.network.dropout))
        width = hidden
    layers.append(nn.Linear(width, n_out))
    return nn.Sequential(*layers)


def _export_weights(net, config: TrainConfig) -> list[np.ndarray]:
    import torch.nn as nn

    weights: list[np.ndarray] = []
    for module in net:
        if isinstance(module, nn.Linear):
            weights += [module.weight.detach().numpy().copy(), module.bias.detach().numpy().copy()]
        elif isinstance(module, nn.BatchNorm1d):
            weights += [
                module.weight.detach().numpy().copy(),
                module.bias.detach().numpy().copy(),
                module.running_mean.numpy().copy(),
                module.running_var.numpy().copy(),
            ]
    return weights


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
    scaling = _Scaling.fit(data["x_train"], data["y_train"])
    tensors = _standardise(data, scaling)
    learner = _build_learner(config, tensors.x_train.shape[1], tensors.y_train.shape[1])
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


@dataclass(frozen=True)
class _Scaling:
    """Standardisation fitted on the training set, stored in the kernel: per input, shape (n_in,), and per
    output, shape (n_out,), in the features' and labels' own units."""

    input_mean: np.ndarray
    input_std: np.ndarray
    output_mean: np.ndarray
    output_std: np.ndarray

    @classmethod
    def fit(cls, x: np.ndarray, y: np.ndarray) -> _Scaling:
        """From training features ``x`` (rows, n_in) and labels ``y`` (rows, n_out)."""
        input_mean, input_std = x.mean(0), x.std(0)
        input_std = np.where(input_std < MIN_STD, 1.0, input_std)  # constant inputs (e.g. fixed heights)
        output_mean, output_std = y.mean(0), y.std(0)
        output_std = np.where(output_std < MIN_STD, 1.0, output_std)
        return cls(input_mean, input_std, output_mean, output_std)


@dataclass(frozen=True)
class _Tensors:
    """The standardised training and validation sets as float32 tensors: ``x_*`` (rows, n_in), ``y_*``
    (rows, n_out); ``scale`` (n_out,) turns a standardised output error back into metres."""

    x_train: Any
    y_train: Any
    x_val: Any
    y_val: Any
    scale: Any


def _standardise(data: dict[str, np.ndarray], scaling: _Scaling) -> _Tensors:
    """:func:`prepare_data`'s sets, standardised with ``scaling``."""
    import torch

    def standard(values: np.ndarray, mean: np.ndarray, std: np.ndarray):
        return torch.from_numpy(((values - mean) / std).astype(np.float32))

    x_mean, x_std = scaling.input_mean, scaling.input_std
    y_mean, y_std = scaling.output_mean, scaling.output_std
    return _Tensors(
        x_train=standard(data["x_train"], x_mean, x_std),
        y_train=standard(data["y_train"], y_mean, y_std),
        x_val=standard(data["x_val"], x_mean, x_std),
        y_val=standard(data["y_val"], y_mean, y_std),
        scale=torch.from_numpy(scaling.output_std.astype(np.float32)),
    )


@dataclass(frozen=True)
class _Learner:
    """The network and everything that moves it: Adam, the learning-rate schedule, the batch-order RNG."""

    net: Any
    optimizer: Any
    scheduler: Any
    generator: Any


def _build_learner(config: TrainConfig, n_in: int, n_out: int) -> _Learner:
    """A freshly initialised network (seeded by ``config.seed``) with its optimiser and schedule."""
    import torch

    torch.manual_seed(config.seed)
    net = _build_network(config, n_in, n_out)
    optimizer = torch.optim.Adam(net.parameters(), lr=config.learning_rate)
    last = max(1, config.epochs - 1)
    scheduler = torch.optim.lr_scheduler.LambdaLR(
        optimizer, lambda epoch: 1.0 - (1.0 - config.lr_decay) * min(epoch, last) / last
    )
    generator = torch.Generator().manual_seed(config.seed)
    return _Learner(net, optimizer, scheduler, generator)


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
    learner: _Learner,
    tensors: _Tensors,
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
            train_loss = _train_epoch(learner, tensors, config.batch_size)
            learner.scheduler.step()
            val_l1 = _validate(learner.net, tensors)
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


def _train_epoch(learner: _Learner, tensors: _Tensors, batch_size: int) -> float:
    """One pass over the training set in a random order; the mean of the batches' standardised L1 losses."""
    import torch

    net, x, y = learner.net, tensors.x_train, tensors.y_train
    net.train()
    order = torch.randperm(len(x), generator=learner.generator)
    batches = (len(x) + batch_size - 1) // batch_size
    total = 0.0
    for b in range(batches):
        index = order[b * batch_size : (b + 1) * batch_size]
        loss = (net(x[index]) - y[index]).abs().mean()
        learner.optimizer.zero_grad()
        loss.backward()
        learner.optimizer.step()
        total += float(loss.detach())
    return total / batches


def _validate(net, tensors: _Tensors) -> float:
    """Mean absolute error over all outputs of the validation set [m]."""
    import torch

    x, y = tensors.x_val, tensors.y_val
    net.eval()
    with torch.no_grad():
        total = 0.0
        for start in range(0, len(x), VALIDATION_BATCH):
            prediction = net(x[start : start + VALIDATION_BATCH])
            total += float(((prediction - y[start : start + VALIDATION_BATCH]).abs() * tensors.scale).sum())
    return total / (len(x) * y.shape[1])


def _record_epoch(state: dict[str, Any], learner: _Learner, train_loss: float, val_l1: float) -> None:
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


def _save_checkpoint(path: Path, this_run: str, learner: _Learner, state: dict[str, Any]) -> None:
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
    scaling: _Scaling,
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
        weights=_export_weights(net, config),
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


def _resume(checkpoint_path: Path, this_run: str, learner: _Learner) -> dict[str, Any]:
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
