"""How a kernel was made, decoded from its file: the one decoder of a kernel's training settings.

A kernel file (:func:`krl.kernel.model.load_kernel`) records, in its metadata, the settings of the expert
data it was trained on (``dataset_settings``: :meth:`krl.data.collect.CollectConfig.settings`) and its
training configuration (``config``: :meth:`krl.kernel.train.TrainConfig.to_json`). Everything that needs
them (the kernel controller's default gait and heights, fresh validation data, the validation split, the
figures' expert) reads them through :func:`training_settings`, so a setting missing from an older file
falls back to the same dataclass default everywhere.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from krl.control.commands import CommandParams
from krl.control.expert import ExpertParams
from krl.control.mpc import MPCParams
from krl.data.collect import MODES, CollectConfig
from krl.kernel.model import Kernel
from krl.kernel.train import TrainConfig

EXT_HEIGHTS_BEFORE_THE_CHOICE: str = "both"
"""``ext_heights`` of ext data collected before ``krl collect --ext-heights`` existed: such data redrew
both heights every target."""


@dataclass(frozen=True)
class TrainingSettings:
    """How a kernel was made, decoded from its file's metadata (missing entries: the dataclass defaults)."""

    expert: ExpertParams = field(default_factory=ExpertParams)
    """The expert that collected the training data: gait, τ_stance [s], step and ride height [m], MPC.
    For ``ext`` data its heights are the nominal ones (the data redrew them per target)."""
    command: CommandParams = field(default_factory=CommandParams)
    """The command generator of the training data (its velocity ranges bound the kernel's inputs)."""
    mode: str = CollectConfig.mode
    """Collection mode of the training data (:data:`krl.data.collect.MODES`)."""
    ext_heights: str = CollectConfig.ext_heights
    """``ext`` data: which heights each target redrew (:data:`krl.data.collect.EXT_HEIGHTS`)."""
    train: TrainConfig | None = None
    """The training configuration (variant, network, validation split); ``None`` for a file without one."""
    dataset_hash: str | None = None
    """Content hash of the training dataset (:attr:`krl.data.reader.Dataset.content_hash`)."""

    @property
    def validation_split(self) -> tuple[float, int]:
        """``(validation_fraction, split_seed)`` of the training run's split by target.

        Raises:
            ValueError: the kernel file records no training configuration.
        """
        if self.train is None:
            raise ValueError("the kernel file records no training configuration (no validation split)")
        return self.train.validation_fraction, self.train.split_seed


def training_settings(kernel: Kernel) -> TrainingSettings:
    """Decode ``kernel``'s training settings from its metadata (the one place that reads them)."""
    metadata = kernel.metadata
    settings: dict[str, Any] = metadata.get("dataset_settings", {})
    expert = dict(settings.get("expert", {}))
    mpc = expert.pop("mpc", None)
    if mpc:
        expert["mpc"] = MPCParams(**_tuples(mpc))
    decoded: dict[str, Any] = {
        "expert": ExpertParams(**expert),
        "command": CommandParams(**_tuples(settings.get("command", {}))),
        "train": TrainConfig.from_json(metadata["config"]) if "config" in metadata else None,
        "dataset_hash": metadata.get("dataset_hash"),
    }
    if settings.get("mode") in MODES:  # an unknown mode: data collected like the default mode's
        decoded["mode"] = settings["mode"]
        if settings["mode"] == "ext":
            decoded["ext_heights"] = settings.get("ext_heights", EXT_HEIGHTS_BEFORE_THE_CHOICE)
    return TrainingSettings(**decoded)


def _tuples(values: dict[str, Any]) -> dict[str, Any]:
    """JSON lists back to the tuples the parameter dataclasses hold."""
    return {key: tuple(value) if isinstance(value, list) else value for key, value in values.items()}


__all__ = ["EXT_HEIGHTS_BEFORE_THE_CHOICE", "TrainingSettings", "training_settings"]
