"""The controllers an evaluation can score, named by a short spec string.

| spec | controller |
| --- | --- |
| ``expert`` | the MPC expert, τ_stance 0.2 s |
| ``expert:stance=0.3`` | the expert with another stance duration [s] (also ``step=``, ``ride=`` [m]) |
| ``kernel`` | the shipped kernel-base |
| ``kernel:ext`` | a shipped kernel by name |
| ``kernel:PATH`` | a kernel file (``krl kernel train`` output) |

A :class:`ControllerSpec` is plain data, so worker processes rebuild the controller from it. Every
controller implements :class:`krl.control.types.Controller`, so one runner scores them all.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

CONTROLLER_KINDS: tuple[str, ...] = ("expert", "kernel")
"""Kinds of controller ``krl evaluate`` knows."""

_EXPERT_OPTIONS = {"stance": "stance_duration", "step": "step_height", "ride": "ride_height"}


class ControllerSpecError(ValueError):
    """An unknown controller, a bad option, or a missing model file."""


@dataclass(frozen=True)
class ControllerSpec:
    """What to build in each run."""

    kind: str
    """One of :data:`CONTROLLER_KINDS`."""
    label: str
    """A file-name-safe name for results (``expert-stance0.2``, ``kernel-base``)."""
    options: tuple[tuple[str, Any], ...] = ()
    """Keyword options of the controller's constructor."""
    model: str | None = None
    """Kernel file, for ``kind == "kernel"``."""
    model_sha256: str | None = None
    """SHA-256 of the kernel file: stored results are tied to the file's content, not its path."""
    seeded: bool = False
    """Whether the controller depends on the run's seed (deterministic controllers run once per start)."""

    def build(self, seed: int | None = None):
        """A fresh controller for one run (``seed`` selects seed-dependent controllers' randomness)."""
        if self.kind == "expert":
            from krl.control.expert import ExpertParams, MPCExpert

            return MPCExpert(ExpertParams(**dict(self.options)))
        from krl.kernel.controller import KernelController
        from krl.kernel.model import load_kernel

        assert self.model is not None
        return KernelController(load_kernel(self.model), **dict(self.options))

    def describe(self) -> dict[str, Any]:
        """JSON-ready description, stored with every result."""
        return {
            "kind": self.kind,
            "label": self.label,
            "options": dict(self.options),
            "model_sha256": self.model_sha256,
        }


def parse_controller(text: str) -> ControllerSpec:
    """Parse a spec string (module docstring); raises :class:`ControllerSpecError` with one line."""
    kind, _, rest = text.partition(":")
    kind = kind.strip()
    if kind == "expert":
        options: dict[str, float] = {"stance_duration": 0.2}
        for item in filter(None, (part.strip() for part in rest.split(","))):
            key, sep, value = item.partition("=")
            if not sep or key not in _EXPERT_OPTIONS:
                raise ControllerSpecError(
                    f"controller {text!r}: expert options are "
                    f"{', '.join(k + '=VALUE' for k in _EXPERT_OPTIONS)}, got {item!r}"
                )
            try:
                number = float(value)
            except ValueError:
                number = math.nan
            if not math.isfinite(number):
                raise ControllerSpecError(f"controller {text!r}: {key} must be a number, got {value!r}")
            options[_EXPERT_OPTIONS[key]] = number
        from krl.control.expert import ExpertParams

        try:
            ExpertParams(**options)
        except ValueError as error:
            raise ControllerSpecError(f"controller {text!r}: {error}") from None
        label = f"expert-stance{options['stance_duration']:g}" + "".join(
            f"-{key.split('_')[0]}{value:g}"
            for key, value in sorted(options.items())
            if key != "stance_duration"
        )
        return ControllerSpec("expert", label, tuple(sorted(options.items())))
    if kind == "kernel":
        from krl.kernel.cli import SHIPPED_MODELS, resolve_model
        from krl.kernel.model import KernelFileError, load_kernel

        model = rest.strip() or "base"
        path = resolve_model(model)
        if not path.is_file():
            raise ControllerSpecError(
                f"controller {text!r}: no kernel file {str(path)!r} (shipped: {', '.join(SHIPPED_MODELS)})"
            )
        try:
            load_kernel(path)
        except KernelFileError as error:
            raise ControllerSpecError(f"controller {text!r}: {error}") from None
        name = model if model in SHIPPED_MODELS else Path(model).stem.removeprefix("kernel-")
        digest = hashlib.sha256(path.read_bytes()).hexdigest()
        return ControllerSpec("kernel", f"kernel-{name}", (), str(path.resolve()), digest)
    raise ControllerSpecError(
        f"unknown controller {text!r}; known: {', '.join(CONTROLLER_KINDS)} (see --help)"
    )
