"""The kernel's analysis figures (thesis Section 4.2.6.3-4.2.7): ``krl kernel figures WHICH --out DIR``.

``WHICH`` is one of (``docs/kernel_figures.md`` has every definition and the results), each drawn by its
own module of :mod:`krl.analysis.kernel`:

- ``trajectories`` (Fig. 4.9): the MPC expert walks to random waypoints (so its commands change); its
  labels for the FR foot (swing targets for a swinging leg, realised positions for a standing one: the
  kernel's training labels) against kernel-base's prediction from the same inputs; L1 per axis.
- ``command-sweep`` (Fig. 4.10): kernel-base's FR foot over one trot cycle while one command (frontal
  0..1 m/s, lateral -0.5..0.5 m/s, yaw -1..1 rad/s) varies and the others are zero.
- ``symmetry`` (Fig. 4.11): FR against RL over a cycle at vx = 0 and 0.3 m/s, kernel and expert.
- ``walk-gait`` (Fig. 4.12): kernel-base (and kernel-ind, given a file) fed the walk gait's phases,
  against the MPC expert walking with that gait.
- ``heights`` (Fig. 4.13): kernel-ext's FR z over a cycle for several step and ride heights.
- ``velocity`` (Fig. 4.15, kernel half): realised against commanded velocity with the kernel as the
  controller, beside the expert's numbers read from ``docs/figures/expert/velocity.json``.
- ``all``: the six.

Each figure gives ``NAME.png``, ``NAME.json`` and ``NAME.csv`` in the output folder, each written
atomically (temporary file + ``os.replace``) with the writers of :mod:`krl.util.output`.
"""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Any

from krl.analysis.common import check_run_options, write_figure
from krl.analysis.kernel.command_sweep import command_sweep_figure
from krl.analysis.kernel.context import CHOICES, FIGURES, FigureError, FigureRun
from krl.analysis.kernel.heights import heights_figure
from krl.analysis.kernel.symmetry import symmetry_figure
from krl.analysis.kernel.trajectories import trajectories_figure
from krl.analysis.kernel.velocity import expert_velocity_table, velocity_figure
from krl.analysis.kernel.walk_gait import walk_gait_figure

_NEEDS: dict[str, str] = {"heights": "ext"}
"""The kernel each figure needs (``base`` unless listed)."""


def _load_checked(model: str | os.PathLike, variant: str, option: str):
    from krl.kernel.model import load_kernel
    from krl.kernel.registry import resolve_model

    path = resolve_model(str(model))
    if not path.is_file():
        raise FigureError(f"{option}: kernel file not found: {path}")
    kernel = load_kernel(path)
    if kernel.variant != variant:
        raise FigureError(
            f"{option}: {path} is a kernel-{kernel.variant}, this figure needs a kernel-{variant}"
        )
    return kernel, path


def make_kernel_figures(
    which: str,
    out_dir: str | os.PathLike,
    model: str | os.PathLike = "base",
    ext_model: str | os.PathLike = "ext",
    ind_model: str | os.PathLike | None = None,
    expert_json: str | os.PathLike | None = None,
    seed: int = 0,
    quick: bool = False,
    workers: int | None = None,
    progress: bool = True,
) -> dict[str, Any]:
    """Make the figure(s) and write ``NAME.png``, ``NAME.json``, ``NAME.csv`` per figure into ``out_dir``.

    Args:
        which: a name of :data:`FIGURES` or ``all``.
        out_dir: output folder (created).
        model, ext_model: kernel-base and kernel-ext: a shipped kernel's name (``base``, ``ext``) or a
            file; ``ext_model`` is only loaded for ``heights``.
        ind_model: an optional kernel-ind file for ``walk-gait`` (its panel is left out without one).
        expert_json: the expert's velocity table (default: ``docs/figures/expert/velocity.json`` under
            the working directory or the repository); without one ``velocity`` shows the kernel only.
        seed: waypoints of ``trajectories`` and the simulator's seed.
        quick: tiny runs (tests).
        workers: processes for the velocity sweep (default: number of CPUs; 1 = in-process).

    Returns:
        ``{"figures": {name: {"png", "json", "csv", "table"}}, "workers", "wall_seconds"}``.

    Raises:
        FigureError (a ValueError): unknown ``which``, bad argument, missing or wrong-variant kernel file,
        missing explicit ``expert_json``; all checked before anything runs or is written.
    """
    if which not in CHOICES:
        raise FigureError(f"unknown figure {which!r}; choose from {', '.join(CHOICES)}")
    out = Path(out_dir)
    workers = check_run_options(workers, seed, out, FigureError)
    names = FIGURES if which == "all" else (which,)
    kernels: dict[str, Any] = {}
    paths: dict[str, Path] = {}
    if any(_NEEDS.get(name, "base") == "base" for name in names):
        kernels["base"], paths["base"] = _load_checked(model, "base", "--model")
    if "heights" in names:
        kernels["ext"], paths["ext"] = _load_checked(ext_model, "ext", "--ext-model")
    if ind_model is not None and "walk-gait" in names:
        kernels["ind"], paths["ind"] = _load_checked(ind_model, "ind", "--ind-model")
    expert = expert_velocity_table(expert_json) if "velocity" in names else (None, None)

    run = FigureRun(seed=seed, quick=quick, workers=workers, progress=progress)
    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    figures: dict[str, Any] = {}
    for name in names:
        if name == "trajectories":
            built = trajectories_figure(kernels["base"], run)
        elif name == "command-sweep":
            built = command_sweep_figure(kernels["base"], run)
        elif name == "symmetry":
            built = symmetry_figure(kernels["base"], run)
        elif name == "walk-gait":
            built = walk_gait_figure(kernels["base"], kernels.get("ind"), run)
        elif name == "heights":
            built = heights_figure(kernels["ext"], run)
        else:
            built = velocity_figure(paths["base"], expert, run)
        table, columns, rows, fig = built
        table["kernels"] = {key: str(path) for key, path in paths.items()}
        figures[name] = write_figure(out, name, fig, table, columns, rows)
        run.say(f"{name}: wrote {figures[name]['png']}")
    return {"figures": figures, "workers": workers, "wall_seconds": round(time.perf_counter() - start, 2)}
