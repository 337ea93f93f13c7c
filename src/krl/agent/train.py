"""Training the residual agent with Stable-Baselines3's PPO (thesis Sections 4.2.8-4.2.9).

``train(out, config, seed)`` trains into the run folder ``out``:

| file | what |
| --- | --- |
| ``config.json`` | the resolved :class:`krl.agent.config.AgentConfig` |
| ``run.json`` | seed, kernel file and its SHA-256, krl version |
| ``checkpoints/<steps>/`` | model, normaliser, ``state.json`` (:mod:`krl.agent.checkpoint`); ``latest`` |
| ``policy.npz`` | the exported policy (:mod:`krl.agent.policy`), refreshed at every checkpoint |
| ``progress.csv``, ``events.*`` | the training log, CSV and TensorBoard (:mod:`krl.agent.callbacks`) |
| ``progress.<steps>.csv`` | the CSV log up to ``<steps>``, set aside by a resumption from there |

``train(out, config, seed, init_from=RUN)`` starts a new run from another run's newest checkpoint (its
policy, value function, optimiser state and observation normaliser): fine-tuning, for instance under
another training distribution. The two must share the kernel, the residual path, the observation and the
network; ``run.json`` and the exported policy's metadata record the run it started from and its env steps.

Calling it again on the same folder resumes from the newest checkpoint (an interruption loses at most
``checkpoint_every`` env steps), with the stored config; only the number of worker processes may change
between sittings. The environments restart from fresh episodes on resumption, seeded from the run's seed
and the checkpoint's step count, so a resumed run is reproducible but not bit-identical to an
uninterrupted one; an uninterrupted run with the same seed on the same machine is.

Nothing read from a run folder runs code (:mod:`krl.agent.checkpoint`): a model is built afresh from the
config, then given a checkpoint's weights, optimiser state, normaliser and counters.
"""

from __future__ import annotations

import csv
import json
import os
import signal
from collections import deque
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import torch
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.logger import configure
from stable_baselines3.common.vec_env import VecNormalize
from threadpoolctl import threadpool_limits

from krl.agent.callbacks import Checkpointer, Clock, EpisodeLog, ProgressBar
from krl.agent.checkpoint import Checkpoint, CheckpointError, read_checkpoint, read_state
from krl.agent.config import AgentConfig, AgentConfigError
from krl.agent.curves import STEPS_COLUMN
from krl.agent.network import SharedExtractor
from krl.agent.process_vec_env import ProcessVecEnv
from krl.util.hashing import file_sha256
from krl.util.output import write_atomic
from krl.util.parallel import Interrupted, usable_cores

RESUME_SEED_STRIDE = 7919
"""A resumed run's environments are seeded ``seed + RESUME_SEED_STRIDE * (checkpoints passed + 1)`` (a
prime, so that the sittings' environment seeds stay apart from each other's ``seed + i``)."""


class TrainingError(RuntimeError):
    """A run folder that cannot be used (another config, a corrupt checkpoint); one line."""


def _terminate(signum: int, frame: object) -> None:
    raise Interrupted(signum)


class LearningRate:
    """The thesis's learning-rate schedule as SB3 sees it (a function of the progress remaining).

    Every ``learn`` call of :func:`train` ends at ``total_steps``, so the env steps so far are
    ``(1 - progress_remaining) * total_steps``.
    """

    def __init__(self, ppo, total_steps: int) -> None:
        self.ppo = ppo
        self.total_steps = total_steps

    def __call__(self, progress_remaining: float) -> float:
        return float(self.ppo.learning_rate_at((1.0 - progress_remaining) * self.total_steps))


class ThreadedPPO(PPO):
    """SB3's PPO whose update runs on ``update_threads`` PyTorch threads, and everything else on one.

    The environment workers step while PyTorch computes the rollout's actions, so more threads would only
    fight them for the cores. The update defaults to one thread too: on a machine with other work (a second
    training, an evaluation) two threads made one update 9-18 x slower than one (PyTorch's OpenMP threads
    wait for each other at every operation), and with the machine to itself they saved only ~4 % of a
    training's wall time (``benchmarks/README.md``, "PPO's update: one thread").
    """

    update_threads: int = 1

    def train(self) -> None:
        torch.set_num_threads(self.update_threads)
        try:
            super().train()
        finally:
            torch.set_num_threads(1)

    def _excluded_save_params(self) -> list[str]:
        return [*super()._excluded_save_params(), "update_threads"]


def _policy_kwargs(config: AgentConfig) -> dict[str, Any]:
    ppo = config.ppo
    return {
        "features_extractor_class": SharedExtractor,
        "features_extractor_kwargs": {"hidden": list(ppo.shared)},
        "share_features_extractor": True,
        "net_arch": {"pi": list(ppo.actor), "vf": list(ppo.critic)},
        "activation_fn": torch.nn.Tanh,
        "log_std_init": ppo.log_std_init,
    }


def _software() -> dict[str, str]:
    import mujoco
    import stable_baselines3

    from krl import __version__

    return {
        "krl": __version__,
        "stable_baselines3": stable_baselines3.__version__,
        "torch": torch.__version__,
        "mujoco": mujoco.__version__,
    }


def train(
    out: str | Path,
    config: AgentConfig | None = None,
    seed: int | None = None,
    total_steps: int | None = None,
    progress: bool = True,
    log=print,
    init_from: str | Path | None = None,
    workers: int | None = None,
    num_envs: int | None = None,
    device: str = "auto",
    update_threads: int = 1,
    callbacks: Sequence[BaseCallback] = (),
) -> dict[str, Any]:
    """Train (or resume) a residual agent in ``out``; returns a summary (steps, wall time, policy path).

    Args:
        out: the run folder.
        config: the agent's configuration (default :class:`AgentConfig`); a resumed run's must be its
            stored one, but for ``workers``.
        seed: the run's seed (default 0); must match a resumed run's.
        total_steps: env steps to train to, >= 1 (default ``config.total_steps``); may extend a finished
            run.
        progress: show a progress bar.
        log: where one-line messages go.
        init_from: a run folder whose newest checkpoint a new run starts from (module docstring).
        workers: worker processes (default: the config's, and where it gives none one per usable core); may
            differ from a resumed run's.
        num_envs: environments per worker (default: the config's); must match a resumed run's.
        device: where PPO's update runs: ``cpu``, ``cuda`` or ``auto`` (CUDA when PyTorch sees a device);
            the environments always run on the CPU workers.
        update_threads: PyTorch threads for PPO's update on the CPU, >= 1 (:class:`ThreadedPPO`); more
            than one only pays when nothing else runs on the machine. Results differ by rounding only.
        callbacks: more SB3 callbacks, called after krl's own (so a rollout's ``episode/*`` values are in
            ``logger.name_to_value`` at ``_on_rollout_end``); one whose ``_on_step`` returns False ends the
            training early, saving its last checkpoint and policy as at the end (an agent study's pruning).

    Raises:
        TrainingError: (one line, before anything is written) a run folder or checkpoint that cannot be
            used, ``total_steps`` or ``update_threads`` below 1.
    """
    out = Path(out)
    if total_steps is not None and total_steps < 1:
        raise TrainingError(f"total_steps must be at least 1 env step, got {total_steps}")
    if update_threads < 1:
        raise TrainingError(f"update_threads must be at least 1, got {update_threads}")
    device = training_device(device)
    config, run = _open_run(out, config, seed, init_from, workers, num_envs, device)
    total = config.total_steps if total_steps is None else total_steps
    latest = _latest_checkpoint(out)
    done, wall_before = (0, 0.0) if latest is None else _read(read_state, latest)
    if done >= total:
        log(f"run {out} already has {done} env steps (of {total}); nothing to do")
        return _summary(out, done, wall_before)
    start = _starting_point(run, latest)  # read whole before anything is written
    os.environ["OPENBLAS_NUM_THREADS"] = "1"  # inherited by the spawned workers
    torch.set_num_threads(1)  # small networks: extra intra-op threads only spin against the env workers
    env_seed = _env_seed(run["seed"], config, None if latest is None else done)
    venv = ProcessVecEnv(config, config.workers, config.num_envs, env_seed, _run_kernel(out, config, run))
    try:
        model = _new_model(config, venv, run["seed"], total, device)
        model.update_threads = update_threads
        if latest is not None:
            _resume(model, start)
            log(f"resuming {out} from {latest.name} ({done} env steps)")
            _archive_log(out, done)
        elif start is not None:
            _start_from(model, start)
            log(f"starting {out} from {run['initialized_from']['run']} ({start.num_timesteps} env steps)")
        model.set_logger(configure(str(out), ["csv", "tensorboard"]))
        return _learn(model, out, config, run, total, Clock(wall_before), progress, log, callbacks)
    finally:
        venv.close()


def training_device(asked: str) -> str:
    """``cpu`` or ``cuda`` for ``asked`` (``auto``: CUDA when PyTorch sees a device); TrainingError (one
    line) for an unknown name or CUDA asked for where there is none."""
    if asked not in ("auto", "cpu", "cuda"):
        raise TrainingError(f"unknown device {asked!r}; known: auto, cpu, cuda")
    available = torch.cuda.is_available()
    if asked == "cuda" and not available:
        raise TrainingError("device cuda asked for, but PyTorch sees no CUDA device")
    return "cuda" if asked == "cuda" or (asked == "auto" and available) else "cpu"


def _summary(out: Path, env_steps: int, wall_seconds: float) -> dict[str, Any]:
    return {
        "out": str(out),
        "env_steps": env_steps,
        "wall_seconds": wall_seconds,
        "policy": str(out / "policy.npz"),
    }


def _open_run(
    out: Path,
    config: AgentConfig | None,
    seed: int | None,
    init_from: str | Path | None,
    workers: int | None,
    num_envs: int | None,
    device: str,
) -> tuple[AgentConfig, dict[str, Any]]:
    """The run's config and run record: read (a resumption, :func:`_reopen_run`) or written (a new run,
    :func:`_new_run`, on ``device``), with the ``workers`` and ``num_envs`` given."""
    overrides = {
        name: value for name, value in (("workers", workers), ("num_envs", num_envs)) if value is not None
    }
    source = None if init_from is None else Path(init_from)
    if (out / "config.json").is_file():
        return _reopen_run(out, config, seed, source, overrides)
    config = replace(config or AgentConfig(), **overrides)
    if config.workers is None:
        config = replace(config, workers=usable_cores())
    return config, _new_run(out, config, seed, source, device)


def _reopen_run(
    out: Path, config: AgentConfig | None, seed: int | None, init_from: Path | None, overrides: dict[str, int]
) -> tuple[AgentConfig, dict[str, Any]]:
    """A resumed run's stored config (with the worker count asked for) and run record; refuses a
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
    return replace(stored, workers=asked.workers), run


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
        "software": _software(),
    }
    if init_from is not None:
        run["initialized_from"] = _initial_run(init_from, config, run["kernel_sha256"])
    out.mkdir(parents=True, exist_ok=True)
    write_atomic(out / "run.json", (json.dumps(run, indent=2) + "\n").encode())
    write_atomic(out / "config.json", (json.dumps(config.to_json(), indent=2) + "\n").encode())
    return run


def _read_run(folder: Path) -> tuple[AgentConfig, dict[str, Any]]:
    """A run folder's config and run record; ``OSError``, ``ValueError`` or ``AgentConfigError`` if either
    cannot be read."""
    config_path = folder / "config.json"
    config = AgentConfig.from_json(json.loads(config_path.read_text()), str(config_path))
    return config, json.loads((folder / "run.json").read_text())


def _latest_checkpoint(out: Path) -> Path | None:
    latest = out / "checkpoints" / "latest"
    if not latest.is_file():
        return None
    path = out / "checkpoints" / latest.read_text().strip()
    if not (path / "state.json").is_file():
        raise TrainingError(f"run {out}: checkpoint {path.name} named by checkpoints/latest is incomplete")
    return path


def _read(reader, checkpoint: Path):
    """``reader(checkpoint)`` (:func:`read_state`, :func:`read_checkpoint`) with its error as a
    TrainingError."""
    try:
        return reader(checkpoint)
    except CheckpointError as error:
        raise TrainingError(str(error)) from None


def _initial_run(source: Path, config: AgentConfig, kernel_sha256: str) -> dict[str, Any]:
    """What a run started from ``source`` records of it; refuses a source the new run cannot start from
    (its whole checkpoint is read here, before the new run writes anything)."""
    latest = _latest_checkpoint(source)
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
    checkpoint = _read(read_checkpoint, latest)
    return {
        "run": str(source),
        "checkpoint": latest.name,
        "env_steps": checkpoint.num_timesteps,
        "wall_seconds": checkpoint.wall_seconds,
        "seed": their_run.get("seed"),
    }


def _starting_point(run: dict[str, Any], latest: Path | None) -> Checkpoint | None:
    """The checkpoint training continues from: the run's newest, else the one of the run it starts from
    (``initialized_from``), else None (a new run from scratch)."""
    if latest is not None:
        return _read(read_checkpoint, latest)
    start = run.get("initialized_from")
    if start is None:
        return None
    checkpoint = Path(start["run"]) / "checkpoints" / start["checkpoint"]
    if not checkpoint.is_dir():
        raise TrainingError(f"checkpoint {checkpoint} that this run starts from is gone (trained on since?)")
    return _read(read_checkpoint, checkpoint)


def _run_kernel(out: Path, config: AgentConfig, run: dict[str, Any]) -> str:
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


def _env_seed(seed: int, config: AgentConfig, resumed_at: int | None) -> int:
    """Seed of environment 0: the run's ``seed``, or for a sitting resumed at ``resumed_at`` env steps,
    one of the checkpoints passed (so that each sitting's environments start afresh)."""
    if resumed_at is None:
        return seed
    return seed + RESUME_SEED_STRIDE * (resumed_at // config.checkpoint_every + 1)


def _new_model(config: AgentConfig, venv, seed: int, total: int, device: str) -> ThreadedPPO:
    """A PPO of the config's settings on ``device``, freshly initialised from ``seed``, on ``venv`` wrapped
    in a running normaliser; its learning rate follows the schedule up to ``total`` env steps."""
    ppo = config.ppo
    env = VecNormalize(
        venv, norm_obs=ppo.normalize_observations, norm_reward=ppo.normalize_rewards, gamma=ppo.gamma
    )
    model = ThreadedPPO(
        "MlpPolicy",
        env,
        learning_rate=LearningRate(ppo, total),
        n_steps=max(1, ppo.rollout_steps // venv.num_envs),
        batch_size=ppo.batch_size,
        n_epochs=ppo.n_epochs,
        gamma=ppo.gamma,
        gae_lambda=ppo.gae_lambda,
        clip_range=ppo.clip_range,
        ent_coef=ppo.ent_coef,
        policy_kwargs=_policy_kwargs(config),
        seed=seed,
        device=device,
        verbose=0,
    )
    return model


def _load(model: PPO, checkpoint: Checkpoint, settings: bool) -> None:
    """The checkpoint's network, optimiser state and normaliser statistics (with ``settings``, also the
    normaliser's settings) into ``model``, which must have the same layers."""
    try:
        model.set_parameters(checkpoint.params, exact_match=True, device=model.device)
        if checkpoint.normaliser is not None:
            checkpoint.normaliser.restore(model.get_vec_normalize_env(), settings)
    except Exception as error:  # torch raises RuntimeError, KeyError or ValueError on a mismatch
        first = str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__
        raise TrainingError(f"checkpoint {checkpoint.folder} is corrupt: {first}") from None


def _resume(model: PPO, checkpoint: Checkpoint) -> None:
    """Continue the run's own ``checkpoint`` in a new ``model``: what SB3's ``PPO.load`` restores that
    training reads (weights, optimiser state, the normaliser's statistics and settings, env steps, update
    count, the recent episodes behind ``rollout/ep_rew_mean``), and nothing else."""
    _load(model, checkpoint, settings=True)
    model.num_timesteps = checkpoint.num_timesteps
    model._n_updates = checkpoint.n_updates
    model.ep_info_buffer = deque(checkpoint.episodes, maxlen=model._stats_window_size)
    model.ep_success_buffer = deque(maxlen=model._stats_window_size)


def _start_from(model: PPO, checkpoint: Checkpoint) -> None:
    """Start a new run's ``model`` from another run's ``checkpoint``: its weights, optimiser state and
    normaliser statistics (the normaliser's settings are this run's)."""
    _load(model, checkpoint, settings=False)


def _archive_log(out: Path, steps: int) -> None:
    """Before a resumption from the checkpoint at ``steps``, set ``progress.csv`` aside as
    ``progress.<steps>.csv`` (SB3's CSV logger starts its file afresh) without its rows past ``steps``,
    which are trained again. A log with no row left (a second resumption from one checkpoint) is dropped,
    keeping the archive the first one made."""
    log = out / "progress.csv"
    if not log.is_file():
        return
    lines = log.read_text().splitlines(keepends=True)
    if lines:
        column = next(csv.reader(lines[:1])).index(STEPS_COLUMN)
        kept = [line for line in lines[1:] if float(next(csv.reader([line]))[column]) <= steps]
        if kept:
            write_atomic(out / f"progress.{steps:011d}.csv", "".join([lines[0], *kept]))
    log.unlink()


def _learn(
    model: PPO,
    out: Path,
    config: AgentConfig,
    run: dict[str, Any],
    total: int,
    clock: Clock,
    progress: bool,
    log,
    callbacks: Sequence[BaseCallback] = (),
) -> dict[str, Any]:
    """Train ``model`` to ``total`` env steps with the logging, checkpointing and progress callbacks;
    Ctrl-C or SIGTERM saves a checkpoint and re-raises. Returns the summary of :func:`train`."""
    checkpointer = Checkpointer(out, config, run, clock, _software())
    bar = ProgressBar(progress)
    previous = signal.signal(signal.SIGTERM, _terminate)
    try:
        with threadpool_limits(1, user_api="blas"):
            model.learn(
                total - model.num_timesteps,
                callback=[EpisodeLog(clock), checkpointer, bar, *callbacks],
                reset_num_timesteps=model.num_timesteps == 0,  # a resumed model counts on
            )
    except KeyboardInterrupt:  # Ctrl-C or SIGTERM: keep what was learnt, then stop
        path = checkpointer.save(model)
        log(f"interrupted: saved {path.name} ({model.num_timesteps} env steps); run again to resume")
        raise
    finally:
        bar.close()
        signal.signal(signal.SIGTERM, previous)
    checkpointer.save(model, final=True)
    return _summary(out, int(model.num_timesteps), round(clock(), 1))
