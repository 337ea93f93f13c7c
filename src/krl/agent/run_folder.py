"""An agent's run folder (:func:`krl.agent.train.train`): opening one, new or resumed, and what it holds.

A new run writes ``run.json`` (seed, kernel file and its SHA-256, workers, device, software versions) and
``config.json`` (the resolved :class:`krl.agent.config.AgentConfig`) before anything trains; a resumed one
is read back and refused, with one line and before anything is written, when it was started with another
config, seed or run to start from, or when its kernel file is gone. Every sitting, the first and each
resumption, is appended to ``run.json``'s ``sittings`` (:func:`record_sitting`): the env steps it starts
from, when, and the machine and software it trains on, since a run's last bits depend on the machine's
arithmetic and a run may be resumed elsewhere. The checkpoints themselves are
:mod:`krl.agent.checkpoint`'s.
"""

from __future__ import annotations

import csv
import json
import time
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from krl.agent.checkpoint import (
    Checkpoint,
    CheckpointError,
    checkpoint_folders,
    read_checkpoint,
    steps_name,
)
from krl.agent.config import AgentConfig, AgentConfigError
from krl.agent.curves import STEPS_COLUMN
from krl.util.hashing import file_sha256
from krl.util.machine import machine
from krl.util.output import write_atomic
from krl.util.parallel import usable_cores


class TrainingError(RuntimeError):
    """A run folder that cannot be used (another config, a corrupt checkpoint); one line."""


SEED_LIMIT: int = 2**32
"""A run's seed is at least 0 and below this: NumPy's global seeding, with which SB3 seeds a run, takes no
other."""


def software() -> dict[str, str]:
    """The versions of krl and of the libraries a run's results depend on."""
    import mujoco
    import stable_baselines3
    import torch

    from krl import __version__

    return {
        "krl": __version__,
        "stable_baselines3": stable_baselines3.__version__,
        "torch": torch.__version__,
        "mujoco": mujoco.__version__,
    }


def open_run(
    out: Path,
    config: AgentConfig | None,
    seed: int | None,
    init_from: str | Path | None,
    workers: int | None,
    num_envs: int | None,
    device: str,
) -> tuple[AgentConfig, dict[str, Any]]:
    """The run's config and run record: read (a resumption, :func:`_reopen_run`) or written (a new run,
    :func:`_new_run`, on ``device``, into an absent or empty folder), with the ``workers`` and ``num_envs``
    given. Every argument is checked before anything is written."""
    if seed is not None and not 0 <= seed < SEED_LIMIT:
        raise TrainingError(f"the seed must be an integer from 0 to {SEED_LIMIT - 1}, got {seed}")
    overrides = {
        name: value for name, value in (("workers", workers), ("num_envs", num_envs)) if value is not None
    }
    source = None if init_from is None else Path(init_from)
    if (out / "config.json").is_file():
        return _reopen_run(out, config, seed, source, overrides)
    if out.exists() and not (out.is_dir() and not any(out.iterdir())):
        raise TrainingError(
            f"{out} is not a run folder of krl agent train (it has no config.json) and not an empty folder: "
            "nothing in it is written over; give a new or empty folder"
        )
    config = replace(config or AgentConfig(), **overrides)
    if config.workers is None:
        config = replace(config, workers=usable_cores())
    return config, _new_run(out, config, seed, source, device)


def _reopen_run(
    out: Path, config: AgentConfig | None, seed: int | None, init_from: Path | None, overrides: dict[str, int]
) -> tuple[AgentConfig, dict[str, Any]]:
    """A resumed run's stored config (with the worker count asked for; one per usable core where the
    config asked with names none, as for a new run) and run record; refuses a
    resumption asked with another config (``workers`` aside: it only spreads the env steps over
    processes), another seed or another run to start from."""
    try:
        stored, run = _read_run(out)
    except (OSError, ValueError, AgentConfigError) as error:
        raise TrainingError(f"run {out} cannot be resumed: {error}") from None
    asked = replace(config or stored, **overrides)
    difference = _difference(stored, replace(asked, workers=stored.workers))
    if difference is not None:
        raise TrainingError(
            f"run {out} was started with another config (its {difference}); use a new --out, or drop "
            "--config and --num-envs to resume it"
        )
    if seed is not None and seed != run["seed"]:
        raise TrainingError(f"run {out} was started with seed {run['seed']}, not {seed}")
    started_from = run.get("initialized_from", {}).get("run")
    if init_from is not None and (
        started_from is None or Path(started_from).resolve() != init_from.resolve()
    ):
        raise TrainingError(f"run {out} was not started from {init_from}; drop --init-from to resume it")
    workers = usable_cores() if asked.workers is None else asked.workers  # a config that names none
    return replace(stored, workers=workers), run


def _difference(stored: AgentConfig, asked: AgentConfig) -> str | None:
    """The first setting in which ``asked`` differs from ``stored``, as ``section.name is X, not Y``."""
    theirs, mine = stored.to_json(), asked.to_json()
    for section, value in theirs.items():
        pairs = (
            [(f"{section}.{name}", item, mine[section][name]) for name, item in value.items()]
            if isinstance(value, dict)
            else [(section, value, mine[section])]
        )
        for name, their_value, my_value in pairs:
            if their_value != my_value:
                return f"{name} is {their_value!r}, not {my_value!r}"
    return None


def _new_run(
    out: Path, config: AgentConfig, seed: int | None, init_from: Path | None, device: str
) -> dict[str, Any]:
    """Check the kernel (and the run to start from), then write the new run's ``run.json`` (with the
    workers and the device it starts on) and ``config.json``; returns the run record."""
    from krl.kernel.model import load_kernel
    from krl.kernel.registry import resolve_model

    kernel_path = resolve_model(config.residual.kernel)
    if not kernel_path.is_file():
        raise TrainingError(f"kernel file {kernel_path} not found")
    load_kernel(kernel_path)  # a one-line KernelFileError before anything is written
    run = {
        "seed": 0 if seed is None else seed,
        "kernel_path": str(kernel_path.resolve()),
        "kernel_sha256": file_sha256(kernel_path),
        "workers": config.workers,
        "device": device,
        "software": software(),
    }
    if init_from is not None:
        run["initialized_from"] = _initial_run(init_from, config, run["kernel_sha256"])
    out.mkdir(parents=True, exist_ok=True)
    write_atomic(out / "run.json", (json.dumps(run, indent=2) + "\n").encode())
    write_atomic(out / "config.json", (json.dumps(config.to_json(), indent=2) + "\n").encode())
    return run


def record_sitting(out: Path, run: dict[str, Any], env_steps: int) -> dict[str, Any]:
    """The run record with this sitting appended to its ``sittings``, written to ``out/run.json``
    (atomically): ``env_steps`` it starts from, ``started`` (UTC, ISO 8601), ``machine``
    (:func:`krl.util.machine.machine` and PyTorch's CPU kernels, ``torch_cpu``) and ``software``."""
    import torch

    sitting = {
        "env_steps": env_steps,
        "started": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "machine": {**machine(), "torch_cpu": torch.backends.cpu.get_cpu_capability()},
        "software": software(),
    }
    run = {**run, "sittings": [*run.get("sittings", []), sitting]}
    write_atomic(out / "run.json", (json.dumps(run, indent=2) + "\n").encode())
    return run


def _read_run(folder: Path) -> tuple[AgentConfig, dict[str, Any]]:
    """A run folder's config and run record; ``OSError``, ``ValueError`` or ``AgentConfigError`` if either
    cannot be read."""
    config_path = folder / "config.json"
    config = AgentConfig.from_json(json.loads(config_path.read_text()), str(config_path))
    return config, json.loads((folder / "run.json").read_text())


def latest_checkpoint(out: Path) -> Path | None:
    latest = out / "checkpoints" / "latest"
    if not latest.is_file():
        return None
    path = out / "checkpoints" / latest.read_text().strip()
    if not (path / "state.json").is_file():
        raise TrainingError(f"run {out}: checkpoint {path.name} named by checkpoints/latest is incomplete")
    return path


def resumable_checkpoint(out: Path, log: Callable[[str], None]) -> Path | None:
    """The run's newest checkpoint that can be read whole (:func:`read_checkpoint`), ``log`` told in one
    line of each newer one passed over; None where the run has none. TrainingError (one line) where it has
    checkpoints but none can be read."""
    errors = []
    for folder in checkpoint_folders(out / "checkpoints"):
        try:
            read_checkpoint(folder)
        except CheckpointError as error:
            errors.append(str(error))
            continue
        for error in errors:
            log(f"{error}: passed over")
        return folder
    if errors:
        raise TrainingError(f"{errors[0]}, and no checkpoint before it can be read either")
    return None


def read_checked(reader, checkpoint: Path):
    """``reader(checkpoint)`` (:func:`read_state`, :func:`read_checkpoint`) with its error as a
    TrainingError."""
    try:
        return reader(checkpoint)
    except CheckpointError as error:
        raise TrainingError(str(error)) from None


def _initial_run(source: Path, config: AgentConfig, kernel_sha256: str) -> dict[str, Any]:
    """What a run started from ``source`` records of it; refuses a source the new run cannot start from
    (its whole checkpoint is read here, before the new run writes anything)."""
    latest = latest_checkpoint(source)
    if latest is None or not (source / "config.json").is_file():
        raise TrainingError(f"--init-from {source}: not a run folder of krl agent train with a checkpoint")
    try:
        theirs, their_run = _read_run(source)
    except (OSError, ValueError, AgentConfigError) as error:
        raise TrainingError(f"--init-from {source}: {error}") from None
    network = ("shared", "actor", "critic", "log_std_init", "normalize_observations")
    for name, mine, other in (
        ("residual", config.residual, theirs.residual),
        ("observation", config.observation, theirs.observation),
        *((f"ppo.{key}", getattr(config.ppo, key), getattr(theirs.ppo, key)) for key in network),
    ):
        if mine != other:
            raise TrainingError(f"--init-from {source}: its {name} is {other!r}, this run's is {mine!r}")
    if their_run.get("kernel_sha256") != kernel_sha256:
        raise TrainingError(f"--init-from {source}: it was trained with another kernel file")
    checkpoint = read_checked(read_checkpoint, latest)
    return {
        "run": str(source),
        "checkpoint": latest.name,
        "env_steps": checkpoint.num_timesteps,
        "wall_seconds": checkpoint.wall_seconds,
        "seed": their_run.get("seed"),
    }


def starting_point(run: dict[str, Any], latest: Path | None) -> Checkpoint | None:
    """The checkpoint training continues from: the run's newest, else the one of the run it starts from
    (``initialized_from``), else None (a new run from scratch)."""
    if latest is not None:
        return read_checked(read_checkpoint, latest)
    start = run.get("initialized_from")
    if start is None:
        return None
    checkpoint = Path(start["run"]) / "checkpoints" / start["checkpoint"]
    if not checkpoint.is_dir():
        raise TrainingError(f"checkpoint {checkpoint} that this run starts from is gone (trained on since?)")
    return read_checked(read_checkpoint, checkpoint)


def run_kernel(out: Path, config: AgentConfig, run: dict[str, Any]) -> str:
    """The run's kernel file: the one it recorded, or (a run folder moved to another machine) the one its
    config names, provided it has the recorded SHA-256."""
    from krl.kernel.registry import resolve_model

    for candidate in (Path(run["kernel_path"]), resolve_model(config.residual.kernel)):
        if candidate.is_file() and file_sha256(candidate) == run["kernel_sha256"]:
            return str(candidate)
    raise TrainingError(
        f"run {out} was trained with the kernel of SHA-256 {run['kernel_sha256'][:12]}…, which is neither "
        f"{run['kernel_path']} nor {config.residual.kernel!r} here"
    )


def archive_log(out: Path, steps: int) -> None:
    """Before a sitting that trains on from ``steps`` env steps (0: from the start), set ``progress.csv``
    aside as ``progress.<steps>.csv`` (SB3's CSV logger starts its file afresh) without its rows past
    ``steps``, which are trained again; so the joined segments hold every env step once. A segment set
    aside past ``steps`` (by a resumption from a later checkpoint, since passed over or removed) is
    trained again too: it gives its rows up to ``steps`` instead of ``progress.csv``, whose rows all lie
    past it. A log with no row left (a second resumption from one checkpoint) is dropped, keeping the
    segment the first one made."""
    later = [path for path in sorted(out.glob("progress.*.csv")) if _segment_steps(path) > steps]
    logs = [path for path in (*later, out / "progress.csv") if path.is_file()]
    if not logs:
        return
    lines = logs[0].read_text().splitlines(keepends=True)  # only the first holds rows up to ``steps``
    if lines:
        column = next(csv.reader(lines[:1])).index(STEPS_COLUMN)
        kept = [line for line in lines[1:] if float(next(csv.reader([line]))[column]) <= steps]
        if kept:
            write_atomic(out / f"progress.{steps_name(steps)}.csv", "".join([lines[0], *kept]))
    for log in logs:
        log.unlink()


def _segment_steps(path: Path) -> int:
    """The env steps of a log segment ``progress.<steps>.csv``; -1 for any other name (never past any)."""
    middle = path.name.removeprefix("progress.").removesuffix(".csv")
    return int(middle) if middle.isdigit() else -1


SNAPSHOT_LEFT_OUT = "events.out"
"""TensorBoard's event files start so: a snapshot leaves them out (they repeat ``progress*.csv``)."""


def snapshot_run(run: Path, target: Path) -> int:
    """Copy the run folder ``run`` into ``target``: its config, run record, training logs
    (``progress*.csv``), policy and checkpoints (a run keeps its last two), not TensorBoard's event files;
    what ``target`` holds beyond them (an older checkpoint) is removed once the new files are in. Each file
    is written through a temporary name and renamed, so a snapshot stopped halfway leaves every file whole.
    Returns the bytes copied."""
    kept = {
        path.relative_to(run)
        for path in run.rglob("*")
        if path.is_file() and not path.name.startswith(SNAPSHOT_LEFT_OUT)
    }
    for relative in sorted(kept):
        write_atomic(target / relative, (run / relative).read_bytes())
    for path in sorted(target.rglob("*"), reverse=True):  # files before the folders holding them
        relative = path.relative_to(target)
        if path.is_file() and relative not in kept:
            path.unlink()
        elif path.is_dir() and not any(path.iterdir()):
            path.rmdir()
    return sum((run / relative).stat().st_size for relative in kept)


def snapshot_runs(runs: Sequence[Path], dest: Path) -> dict[str, Any]:
    """Copy each run folder of ``runs`` into ``dest/<its name>`` (:func:`snapshot_run`): what resuming
    it needs, small enough to commit or to carry to another machine; copied back into a runs folder,
    ``krl agent train --out`` there goes on from its newest checkpoint. Returns ``runs`` (the copies'
    paths) and ``bytes``.

    Raises:
        ValueError: a path is not a run folder of ``krl agent train`` (no ``config.json`` and ``run.json``),
            two runs share a name, or ``dest`` is, or lies inside, one of the runs (its copy would overwrite
            the run itself); nothing is written then.
    """
    names: dict[str, Path] = {}
    for run in runs:
        if not ((run / "config.json").is_file() and (run / "run.json").is_file()):
            raise ValueError(f"{run} is not a run folder of krl agent train (no config.json and run.json)")
        if run.name in names:
            raise ValueError(f"two runs are named {run.name} ({names[run.name]}, {run}): snapshot them apart")
        if dest.resolve() == run.resolve() or run.resolve() in dest.resolve().parents:
            raise ValueError(f"--out {dest} lies in the run {run}: give a folder outside it")
        if (dest / run.name).resolve() == run.resolve():
            raise ValueError(f"--out {dest} already holds the run {run} itself: give another folder")
        names[run.name] = run
    copied = sum(snapshot_run(run, dest / name) for name, run in names.items())
    return {"runs": [str(dest / name) for name in names], "bytes": copied}
