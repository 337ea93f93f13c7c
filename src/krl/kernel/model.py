"""The kernel network, its normalisers, and its file format.

A kernel is an MLP from normalised inputs to normalised foot positions, plus the input/output
normalisation (mean, std) fitted on the training data and the metadata that says how it was made. It
is saved as one ``.npz`` file of plain arrays and a JSON metadata string, loaded with
``allow_pickle=False``: loading never executes code. Inference runs in NumPy (a small MLP's forward pass
costs less than a PyTorch call's overhead: benchmarks/README.md, "Figures behind constants and design
choices"); training uses PyTorch (:mod:`krl.kernel.train`).
"""

from __future__ import annotations

import json
import zipfile
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from krl.kernel.features import check_variant, input_names, output_size
from krl.util.affine import affine
from krl.util.output import npz_bytes, write_atomic

FILE_FORMAT = "krl-kernel"
FILE_VERSION = 1
ACTIVATIONS = ("relu", "tanh")


class KernelFileError(ValueError):
    """A kernel file is missing, corrupt, of another format/version, or inconsistent with itself."""


@dataclass(frozen=True)
class NetworkConfig:
    """Architecture of the kernel MLP (thesis Table 4.4's final choice by default)."""

    hidden: tuple[int, ...] = (256, 256, 256, 256)
    """Hidden layer widths."""
    activation: str = "relu"
    """``relu`` or ``tanh``."""
    dropout: float = 0.0002
    """Dropout probability after each hidden layer (training only)."""
    batch_norm: bool = False
    """Batch normalisation after each hidden linear layer."""

    def __post_init__(self) -> None:
        if not self.hidden or min(self.hidden) < 1:
            raise ValueError(f"hidden layer widths must be positive, got {self.hidden}")
        if self.activation not in ACTIVATIONS:
            raise ValueError(f"unknown activation {self.activation!r}; known: {', '.join(ACTIVATIONS)}")
        if not 0 <= self.dropout < 1:
            raise ValueError(f"dropout must be in [0, 1), got {self.dropout}")
        object.__setattr__(self, "hidden", tuple(int(h) for h in self.hidden))


BN_EPS: float = 1e-5
"""Batch normalisation's variance epsilon (PyTorch's default), used at inference."""


@dataclass
class Kernel:
    """A trained kernel: NumPy weights, normalisers and metadata. Call :meth:`predict`."""

    variant: str
    network: NetworkConfig
    weights: list[np.ndarray]
    """Per linear layer: W (out, in), b (out,); with batch norm also gamma, beta, mean, var per hidden
    layer, in the order of :meth:`layer_arrays`."""
    input_mean: np.ndarray
    input_std: np.ndarray
    output_mean: np.ndarray
    output_std: np.ndarray
    metadata: dict[str, Any]

    @property
    def input_size(self) -> int:
        return len(self.input_mean)

    @property
    def output_size(self) -> int:
        return len(self.output_mean)

    def predict(self, features: np.ndarray, rowwise: bool = False) -> np.ndarray:
        """Foot positions [m] from raw features. Shapes: (..., n_in) -> (..., n_out). ``rowwise``: every row
        of 2-D features computed as if alone (:func:`krl.util.affine.affine`)."""
        x = np.asarray(features, dtype=np.float64)
        if x.shape[-1] != self.input_size:
            raise ValueError(f"kernel-{self.variant} expects {self.input_size} inputs, got shape {x.shape}")
        x = (x - self.input_mean) / self.input_std
        layers = self.layers()
        for index, layer in enumerate(layers):
            x = affine(x, layer["W"], layer["b"], rowwise)
            if index == len(layers) - 1:
                break
            if self.network.batch_norm:
                x = (x - layer["mean"]) / np.sqrt(layer["var"] + BN_EPS) * layer["gamma"] + layer["beta"]
            x = np.maximum(x, 0.0) if self.network.activation == "relu" else np.tanh(x)
        return x * self.output_std + self.output_mean

    @property
    def weight_count(self) -> int:
        """Weight arrays the architecture has: W and b per layer, and with batch norm gamma, beta, mean and
        var per hidden layer."""
        return len(self.network.hidden) * self._per_hidden + 2

    @property
    def _per_hidden(self) -> int:
        return 6 if self.network.batch_norm else 2

    def layers(self) -> list[dict[str, np.ndarray]]:
        """Per linear layer, its arrays by name: ``W`` (out, in), ``b`` (out,), and for hidden layers with
        batch norm ``gamma``, ``beta``, ``mean``, ``var`` (out,)."""
        per_hidden = self._per_hidden
        layers, i = [], 0
        for _ in self.network.hidden:
            keys = ("W", "b", "gamma", "beta", "mean", "var")[:per_hidden]
            layers.append(dict(zip(keys, self.weights[i : i + per_hidden], strict=True)))
            i += per_hidden
        layers.append({"W": self.weights[i], "b": self.weights[i + 1]})
        return layers

    def save(self, path: str | Path) -> Path:
        """Write the kernel atomically to ``path`` (``.npz``)."""
        path = Path(path)
        header = {
            "format": FILE_FORMAT,
            "version": FILE_VERSION,
            "variant": self.variant,
            "network": asdict(self.network),
            "num_weights": len(self.weights),
            "metadata": self.metadata,
        }
        arrays = {f"w{i:03d}": w.astype(np.float32) for i, w in enumerate(self.weights)}
        arrays.update(
            input_mean=self.input_mean,
            input_std=self.input_std,
            output_mean=self.output_mean,
            output_std=self.output_std,
            header=np.array(json.dumps(header, sort_keys=True)),
        )
        write_atomic(path, npz_bytes(arrays))
        return path


def load_kernel(path: str | Path) -> Kernel:
    """Load a kernel file, checking its format, version and internal consistency."""
    path = Path(path)
    if not path.is_file():
        raise KernelFileError(f"kernel file not found: {path}")
    try:
        with np.load(path, allow_pickle=False) as archive:
            arrays = {name: archive[name] for name in archive.files}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as error:
        raise KernelFileError(f"kernel file {path} is corrupt or not a kernel: {error}") from None
    try:
        header = json.loads(str(arrays["header"]))
        if header.get("format") != FILE_FORMAT:
            raise KernelFileError(f"{path} is not a krl kernel file (format {header.get('format')!r})")
        if header.get("version") != FILE_VERSION:
            raise KernelFileError(
                f"{path} has kernel file version {header.get('version')}, expected {FILE_VERSION}"
            )
        variant = check_variant(header["variant"])
        network = NetworkConfig(**{**header["network"], "hidden": tuple(header["network"]["hidden"])})
        weights = [arrays[f"w{i:03d}"].astype(np.float64) for i in range(int(header["num_weights"]))]
        kernel = Kernel(
            variant=variant,
            network=network,
            weights=weights,
            input_mean=arrays["input_mean"].astype(np.float64),
            input_std=arrays["input_std"].astype(np.float64),
            output_mean=arrays["output_mean"].astype(np.float64),
            output_std=arrays["output_std"].astype(np.float64),
            metadata=header.get("metadata", {}),
        )
    except KernelFileError:
        raise
    except (KeyError, TypeError, ValueError, json.JSONDecodeError) as error:
        raise KernelFileError(f"kernel file {path} is inconsistent: {error!r}") from None
    _check_shapes(kernel, path)
    return kernel


def _check_shapes(kernel: Kernel, path: Path) -> None:
    expected_in = len(input_names(kernel.variant))
    expected_out = output_size(kernel.variant)
    if kernel.input_size != expected_in or kernel.output_size != expected_out:
        raise KernelFileError(
            f"kernel file {path}: kernel-{kernel.variant} must map {expected_in} inputs to {expected_out} "
            f"outputs, the file has {kernel.input_size} -> {kernel.output_size}"
        )
    if len(kernel.weights) != kernel.weight_count:
        layers = len(kernel.network.hidden)
        norm = " with batch norm" if kernel.network.batch_norm else ""
        raise KernelFileError(
            f"kernel file {path}: {len(kernel.weights)} weight arrays, a {layers}-hidden-layer network{norm} "
            f"has {kernel.weight_count}"
        )
    width = kernel.input_size
    for number, layer in enumerate(kernel.layers(), start=1):
        matrix = layer["W"]
        if matrix.ndim != 2:
            raise KernelFileError(
                f"kernel file {path}: layer {number}'s weight matrix has shape {matrix.shape}, not 2-D"
            )
        if matrix.shape[1] != width:
            raise KernelFileError(
                f"kernel file {path}: layers do not chain: layer {number} takes {matrix.shape[1]} inputs, "
                + (f"layer {number - 1} gives {width}" if number > 1 else f"the kernel has {width}")
            )
        width = matrix.shape[0]
        for name, vector in layer.items():
            if name != "W" and vector.shape != (width,):
                raise KernelFileError(
                    f"kernel file {path}: layer {number}'s {name} has shape {vector.shape}, "
                    f"expected ({width},)"
                )
    if width != kernel.output_size:
        raise KernelFileError(
            f"kernel file {path}: last layer gives {width} outputs, expected {kernel.output_size}"
        )
    normalisers = (kernel.input_mean, kernel.input_std, kernel.output_mean, kernel.output_std)
    if not all(np.isfinite(array).all() for array in (*kernel.weights, *normalisers)):
        raise KernelFileError(f"kernel file {path}: non-finite weights or normalisers")
    if np.any(kernel.input_std <= 0) or np.any(kernel.output_std <= 0):
        raise KernelFileError(f"kernel file {path}: non-positive normaliser scale")
