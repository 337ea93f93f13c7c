"""The shipped kernels: a name (``base``, ``ext``) -> its file, and loading a kernel by name or path.

How a kernel was made (its training data's expert and gait, its validation split) is decoded by
:mod:`krl.kernel.settings`; this module imports only the kernel file format, so what needs a kernel's path
does not pull in data collection or the MPC expert.
"""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

from krl.kernel.model import Kernel, load_kernel
from krl.kernel.shipped import SHIPPED_MODELS


def shipped_model_path(name: str) -> Path:
    """Path of a shipped kernel by name."""
    return Path(str(files("krl.kernel") / "models" / f"kernel-{name}.npz"))


def resolve_model(model: str) -> Path:
    """A shipped model's name (``base``, ``ext``) or a path to a kernel file -> the file's path."""
    if model in SHIPPED_MODELS:
        return shipped_model_path(model)
    return Path(model)


def load_model(model: str) -> Kernel:
    """Load a shipped kernel by name (``base``, ``ext``) or a kernel file."""
    return load_kernel(resolve_model(model))


__all__ = ["SHIPPED_MODELS", "load_model", "resolve_model", "shipped_model_path"]
