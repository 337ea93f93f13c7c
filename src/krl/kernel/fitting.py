"""Fitting the kernel's network (thesis 4.2.6.3, Table 4.4): its settings, the standardisation, the
PyTorch network, Adam with a linear learning-rate decay, one epoch of L1 training and the validation in
metres. :func:`krl.kernel.train.train_kernel` runs these as a resumable run; nothing here writes files.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from krl.kernel.features import check_variant
from krl.kernel.model import NetworkConfig

MIN_STD = 1e-6
"""A feature or label whose training standard deviation is below this is constant: it is centred but not
scaled [its own unit]."""
VALIDATION_BATCH = 8192
"""Rows per forward pass when validating (memory only; the result does not depend on it)."""


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


def build_network(config: TrainConfig, n_in: int, n_out: int):
    """The kernel's PyTorch network for ``config.network``: ``n_in`` features to ``n_out`` outputs."""
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


def export_weights(net) -> list[np.ndarray]:
    """The arrays of ``net`` (:func:`build_network`'s) in :class:`krl.kernel.model.Kernel`'s order: W and b
    per linear layer, and gamma, beta, mean and var per batch-norm layer."""
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


@dataclass(frozen=True)
class Scaling:
    """Standardisation fitted on the training set, stored in the kernel: per input, shape (n_in,), and per
    output, shape (n_out,), in the features' and labels' own units."""

    input_mean: np.ndarray
    input_std: np.ndarray
    output_mean: np.ndarray
    output_std: np.ndarray

    @classmethod
    def fit(cls, x: np.ndarray, y: np.ndarray) -> Scaling:
        """From training features ``x`` (rows, n_in) and labels ``y`` (rows, n_out)."""
        input_mean, input_std = x.mean(0), x.std(0)
        input_std = np.where(input_std < MIN_STD, 1.0, input_std)  # constant inputs (e.g. fixed heights)
        output_mean, output_std = y.mean(0), y.std(0)
        output_std = np.where(output_std < MIN_STD, 1.0, output_std)
        return cls(input_mean, input_std, output_mean, output_std)


@dataclass(frozen=True)
class Tensors:
    """The standardised training and validation sets as float32 tensors: ``x_*`` (rows, n_in), ``y_*``
    (rows, n_out); ``scale`` (n_out,) turns a standardised output error back into metres."""

    x_train: Any
    y_train: Any
    x_val: Any
    y_val: Any
    scale: Any


def standardise(data: dict[str, np.ndarray], scaling: Scaling) -> Tensors:
    """:func:`prepare_data`'s sets, standardised with ``scaling``."""
    import torch

    def standard(values: np.ndarray, mean: np.ndarray, std: np.ndarray):
        return torch.from_numpy(((values - mean) / std).astype(np.float32))

    x_mean, x_std = scaling.input_mean, scaling.input_std
    y_mean, y_std = scaling.output_mean, scaling.output_std
    return Tensors(
        x_train=standard(data["x_train"], x_mean, x_std),
        y_train=standard(data["y_train"], y_mean, y_std),
        x_val=standard(data["x_val"], x_mean, x_std),
        y_val=standard(data["y_val"], y_mean, y_std),
        scale=torch.from_numpy(scaling.output_std.astype(np.float32)),
    )


@dataclass(frozen=True)
class Learner:
    """The network and everything that moves it: Adam, the learning-rate schedule, the batch-order RNG."""

    net: Any
    optimizer: Any
    scheduler: Any
    generator: Any


def build_learner(config: TrainConfig, n_in: int, n_out: int) -> Learner:
    """A freshly initialised network (seeded by ``config.seed``) with its optimiser and schedule."""
    import torch

    torch.manual_seed(config.seed)
    net = build_network(config, n_in, n_out)
    optimizer = torch.optim.Adam(net.parameters(), lr=config.learning_rate)
    last = max(1, config.epochs - 1)
    scheduler = torch.optim.lr_scheduler.LambdaLR(
        optimizer, lambda epoch: 1.0 - (1.0 - config.lr_decay) * min(epoch, last) / last
    )
    generator = torch.Generator().manual_seed(config.seed)
    return Learner(net, optimizer, scheduler, generator)


def train_epoch(learner: Learner, tensors: Tensors, batch_size: int) -> float:
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


def validate(net, tensors: Tensors) -> float:
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
