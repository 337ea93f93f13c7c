"""Training the residual agent with Stable-Baselines3's PPO (thesis Sections 4.2.8-4.2.9).

``train(out, config, seed)`` trains into the run folder ``out`` (opened and checked by
:mod:`krl.agent.run_folder`):

| file | what |
| --- | --- |
| ``config.json`` | the resolved :class:`krl.agent.config.AgentConfig` |
| ``run.json`` | seed, kernel file and its SHA-256, software; each sitting's start, machine and software |
| ``checkpoints/<steps>/`` | the last two: model, normaliser, ``state.json`` (:mod:`krl.agent.checkpoint`) |
| ``policy.npz`` | the exported policy (:mod:`krl.agent.policy`), refreshed at every checkpoint |
| ``progress.csv``, ``events.*`` | the training log, CSV and TensorBoard (:mod:`krl.agent.callbacks`) |
| ``progress.<steps>.csv`` | the CSV log up to ``<steps>``, set aside by a resumption from there |

``train(out, config, seed, init_from=RUN)`` starts a new run from another run's newest checkpoint (its
policy, value function, optimiser state and observation normaliser): fine-tuning, for instance under
another training distribution. The two must share the kernel, the residual path, the observation and the
network; ``run.json`` and the exported policy's metadata record the run it started from and its env steps.

Calling it again on the same folder resumes from the newest checkpoint that can be read (an interruption loses
the env steps since the last checkpoint: fewer than ``checkpoint_every`` and one rollout together), with the
stored config; only the number of worker processes may change between sittings. The environments restart from
fresh episodes on resumption, seeded from the run's seed and the checkpoint's step count, so a resumed run is
reproducible but not bit-identical to an uninterrupted one; an uninterrupted run with the same seed on the
same machine is.

Nothing read from a run folder runs code (:mod:`krl.agent.checkpoint`): a model is built afresh from the
config, then given a checkpoint's weights, optimiser state, normaliser and counters.
"""

from __future__ import annotations

import os
import signal
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import torch
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.logger import configure
from stable_baselines3.common.vec_env import VecNormalize
from threadpoolctl import threadpool_limits

from krl.agent.callbacks import (
    Checkpointer,
    Clock,
    EpisodeLog,
    ProgressBar,
    StopOnSignal,
    rollout_end,
    rollout_size,
)
from krl.agent.checkpoint import Checkpoint, read_state
from krl.agent.config import AgentConfig
from krl.agent.curriculum import PushCurriculum, saved_ceiling
from krl.agent.network import PrivilegedCriticPolicy, SharedExtractor, SplitExtractor
from krl.agent.observation import observation_size
from krl.agent.process_vec_env import ProcessVecEnv
from krl.agent.run_folder import (
    TrainingError,
    archive_log,
    open_run,
    read_checked,
    record_sitting,
    resumable_checkpoint,
    run_kernel,
    software,
    starting_point,
)
from krl.agent.sb3_adapter import UnsavedSettingsPPO, restore_counters
from krl.agent.symmetric_ppo import ppo_update
from krl.agent.symmetry import MirrorError, SignedPermutation, action_mirror, observation_mirror
from krl.agent.terrain_curriculum import TerrainCurriculumLog, saved_levels
from krl.util.parallel import signals_raise

RESUME_SEED_STRIDE = 7919
"""A resumed run's environments are seeded ``seed + RESUME_SEED_STRIDE * (checkpoints passed + 1)`` (a
prime, so that the sittings' environment seeds stay apart from each other's ``seed + i``)."""


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


class ThreadedPPO(UnsavedSettingsPPO):
    """SB3's PPO whose update runs on ``update_threads`` PyTorch threads, and everything else on one.

    The environment workers step while PyTorch computes the rollout's actions, so more threads would only
    fight them for the cores. The update defaults to one thread too: on a machine with other work (a second
    training, an evaluation) more threads make an update much slower (PyTorch's OpenMP threads wait for
    each other at every operation), and with the machine to itself they save little of a training's wall
    time (measured in ``benchmarks/README.md``, "PPO's update: one thread").
    """

    update_threads: int = 1
    unsaved_settings = ("update_threads",)

    def train(self) -> None:
        torch.set_num_threads(self.update_threads)
        try:
            self._update()
        finally:
            torch.set_num_threads(1)

    def _update(self) -> None:
        """One PPO update after a rollout: SB3's."""
        super().train()


class SymmetricPPO(ThreadedPPO):
    """:class:`ThreadedPPO` whose update asks for left-right symmetry (:mod:`krl.agent.symmetric_ppo`).

    Set after construction: ``symmetry`` (``augment`` or ``loss``), ``mirror_loss_coef``, and the mirrors
    ``observation_mirror`` and ``action_mirror`` (:mod:`krl.agent.symmetry`).
    """

    symmetry: str = "augment"
    mirror_loss_coef: float = 1.0
    observation_mirror: SignedPermutation
    action_mirror: SignedPermutation
    unsaved_settings = (
        *ThreadedPPO.unsaved_settings,
        "symmetry",
        "mirror_loss_coef",
        "observation_mirror",
        "action_mirror",
    )

    def _update(self) -> None:
        ppo_update(self, self.observation_mirror, self.action_mirror)


def mirrors(config: AgentConfig, kernel_path: str) -> tuple[SignedPermutation, SignedPermutation]:
    """The observation's and the action's mirrors for ``config`` with the kernel at ``kernel_path``;
    TrainingError (one line) where the mirror misses a feature or an action part's range is not symmetric."""
    from krl.agent.action import action_parts
    from krl.kernel.model import load_kernel

    try:
        return (
            observation_mirror(config.observation.all_features, config.observation.scan),
            action_mirror(action_parts(config.residual, load_kernel(kernel_path))),
        )
    except MirrorError as error:
        raise TrainingError(f"symmetry {config.ppo.symmetry!r}: {error}") from None


def _policy_class(config: AgentConfig) -> str | type:
    """SB3's shared-layer MLP policy, or for a critic with features of its own
    :class:`krl.agent.network.PrivilegedCriticPolicy`."""
    return PrivilegedCriticPolicy if config.observation.critic_features else "MlpPolicy"


def _policy_kwargs(config: AgentConfig) -> dict[str, Any]:
    ppo = config.ppo
    extractor: dict[str, Any] = {"features_extractor_kwargs": {"hidden": list(ppo.shared)}}
    if config.observation.critic_features:
        actor_size = observation_size(config.observation.features, config.observation.scan)
        extractor = {
            "features_extractor_class": SplitExtractor,
            "features_extractor_kwargs": {"hidden": list(ppo.shared), "actor_size": actor_size},
        }
    else:
        extractor["features_extractor_class"] = SharedExtractor
    return {
        **extractor,
        "share_features_extractor": True,
        "net_arch": {"pi": list(ppo.actor), "vf": list(ppo.critic)},
        "activation_fn": torch.nn.Tanh,
        "log_std_init": ppo.log_std_init,
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
        seed: the run's seed, from 0 to 2**32 - 1 (default 0); must match a resumed run's.
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
        callbacks: more SB3 callbacks, called after krl's own (so a rollout's ``episode/*`` values are
            logged, :func:`krl.agent.sb3_adapter.logged_value`, at ``_on_rollout_end``); one whose
            ``_on_step`` returns False ends the training early, saving its last checkpoint and policy as
            at the end (an agent study's pruning).

    Raises:
        TrainingError: (one line, before anything is written) a run folder or checkpoint that cannot be
            used, a folder of other files, a seed out of range, ``total_steps`` or ``update_threads``
            below 1, a symmetric PPO whose observation or action the mirror does not cover.
    """
    out = Path(out)
    if total_steps is not None and total_steps < 1:
        raise TrainingError(f"total_steps must be at least 1 env step, got {total_steps}")
    if update_threads < 1:
        raise TrainingError(f"update_threads must be at least 1, got {update_threads}")
    device = training_device(device)
    symmetric = None
    if config is not None and config.ppo.symmetry != "none":  # refused before the run folder is written
        from krl.kernel.registry import resolve_model

        symmetric = mirrors(config, str(resolve_model(config.residual.kernel)))
    config, run = open_run(out, config, seed, init_from, workers, num_envs, device)
    total = config.total_steps if total_steps is None else total_steps
    latest = resumable_checkpoint(out, log)
    done, wall_before = (0, 0.0) if latest is None else read_checked(read_state, latest)
    if done >= total:
        log(f"run {out} already has {done} env steps (of {total}); nothing to do")
        return _summary(out, done, wall_before)
    start = starting_point(run, latest)  # read whole before anything is written
    kernel_path = run_kernel(out, config, run)
    if symmetric is None and config.ppo.symmetry != "none":  # a resumption with its stored config
        symmetric = mirrors(config, kernel_path)
    os.environ["OPENBLAS_NUM_THREADS"] = "1"  # inherited by the spawned workers
    torch.set_num_threads(1)  # small networks: extra intra-op threads only spin against the env workers
    env_seed = _env_seed(run["seed"], config, None if latest is None else done)
    venv = ProcessVecEnv(config, config.workers, config.num_envs, env_seed, kernel_path)
    try:
        model = _new_model(config, venv, run["seed"], total, device, symmetric)
        model.update_threads = update_threads
        _load_start(model, out, run, latest, start, done, log)
        model.set_logger(configure(str(out), ["csv", "tensorboard"]))
        curricula = _curricula(config, venv, latest)
        run = record_sitting(out, run, done)
        return _learn(model, out, config, run, total, Clock(wall_before), progress, log, curricula, callbacks)
    finally:
        venv.close()


def _load_start(model, out: Path, run: dict[str, Any], latest, start, done: int, log) -> None:
    """Put the run's own ``latest`` checkpoint (a resumption, ``done`` env steps in) or the run it
    starts from (``start``, :func:`starting_point`) into ``model``, and say which; nothing for a fresh
    run. Then set the log past ``done`` aside (:func:`archive_log`; also where a run starts again from
    step 0, which trains those env steps again)."""
    if latest is not None:
        _resume(model, start)
        log(f"resuming {out} from {latest.name} ({done} env steps)")
    elif start is not None:
        _start_from(model, start)
        log(f"starting {out} from {run['initialized_from']['run']} ({start.num_timesteps} env steps)")
    archive_log(out, done)


def training_device(asked: str) -> str:
    """``cpu`` or ``cuda`` for ``asked`` (``auto``: CUDA when PyTorch sees a device); TrainingError (one
    line) for an unknown name or CUDA asked for where there is none."""
    if asked not in ("auto", "cpu", "cuda"):
        raise TrainingError(f"unknown device {asked!r}; known: auto, cpu, cuda")
    available = torch.cuda.is_available()
    if asked == "cuda" and not available:
        raise TrainingError("device cuda asked for, but PyTorch sees no CUDA device")
    return "cuda" if asked == "cuda" or (asked == "auto" and available) else "cpu"


def _curricula(config: AgentConfig, venv: ProcessVecEnv, latest: Path | None) -> list[BaseCallback]:
    """The run's curricula: a push curriculum, its ceiling set in ``venv``, and a terrain curriculum's log,
    the robots' levels set in ``venv``: the ones ``latest`` saved, where a run resumes."""
    curricula: list[BaseCallback] = []
    if config.env.push_curriculum:
        ceiling = saved_ceiling(latest, config.env)
        venv.set_push_ceiling(ceiling)
        curricula.append(PushCurriculum(config.env, ceiling))
    if config.env.terrain_curriculum is not None:
        levels = saved_levels(latest)
        if levels is not None:
            venv.set_terrain_levels(levels)
        curricula.append(TerrainCurriculumLog())
    return curricula


def _summary(out: Path, env_steps: int, wall_seconds: float) -> dict[str, Any]:
    return {
        "out": str(out),
        "env_steps": env_steps,
        "wall_seconds": wall_seconds,
        "policy": str(out / "policy.npz"),
    }


def _env_seed(seed: int, config: AgentConfig, resumed_at: int | None) -> int:
    """Seed of environment 0: the run's ``seed``, or for a sitting resumed at ``resumed_at`` env steps,
    one of the checkpoints passed (so that each sitting's environments start afresh)."""
    if resumed_at is None:
        return seed
    return seed + RESUME_SEED_STRIDE * (resumed_at // config.checkpoint_every + 1)


def _new_model(
    config: AgentConfig,
    venv,
    seed: int,
    total: int,
    device: str,
    symmetric: tuple[SignedPermutation, SignedPermutation] | None = None,
) -> ThreadedPPO:
    """A PPO of the config's settings on ``device``, freshly initialised from ``seed``, on ``venv`` wrapped
    in a running normaliser; its learning rate follows the schedule up to ``total`` env steps. With
    ``symmetric`` (the observation's and the action's mirrors) a :class:`SymmetricPPO` of
    ``config.ppo.symmetry``."""
    ppo = config.ppo
    env = VecNormalize(
        venv, norm_obs=ppo.normalize_observations, norm_reward=ppo.normalize_rewards, gamma=ppo.gamma
    )
    model = (ThreadedPPO if symmetric is None else SymmetricPPO)(
        _policy_class(config),
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
    if symmetric is not None:
        model.symmetry, model.mirror_loss_coef = ppo.symmetry, ppo.mirror_loss_coef
        model.observation_mirror, model.action_mirror = symmetric
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
    restore_counters(model, checkpoint.num_timesteps, checkpoint.n_updates, checkpoint.episodes)


def _start_from(model: PPO, checkpoint: Checkpoint) -> None:
    """Start a new run's ``model`` from another run's ``checkpoint``: its weights, optimiser state and
    normaliser statistics (the normaliser's settings are this run's)."""
    _load(model, checkpoint, settings=False)


def _learn(
    model: PPO,
    out: Path,
    config: AgentConfig,
    run: dict[str, Any],
    total: int,
    clock: Clock,
    progress: bool,
    log,
    curricula: Sequence[BaseCallback] = (),
    callbacks: Sequence[BaseCallback] = (),
) -> dict[str, Any]:
    """Train ``model`` to ``total`` env steps (to the end of the rollout that reaches them, said in one
    line where that is further) with the logging, ``curricula`` (:func:`_curricula`), checkpointing and
    progress callbacks; Ctrl-C or SIGTERM saves a checkpoint and re-raises. Returns the summary of
    :func:`train`."""
    stop = rollout_end(model, total)
    if stop > total:
        rollout = rollout_size(model)
        log(f"PPO trains whole rollouts of {rollout} env steps: this sitting trains to {stop}, not {total}")

    def extra_state() -> dict[str, Any]:
        return {key: value for curriculum in curricula for key, value in curriculum.state().items()}

    checkpointer = Checkpointer(out, config, run, clock, software(), extra_state)
    bar = ProgressBar(progress)
    try:
        with signals_raise((signal.SIGTERM,)), threadpool_limits(1, user_api="blas"):
            model.learn(
                total - model.num_timesteps,
                callback=[EpisodeLog(clock), *curricula, checkpointer, bar, StopOnSignal(), *callbacks],
                reset_num_timesteps=model.num_timesteps == 0,  # a resumed model counts on
            )
    except KeyboardInterrupt:  # Ctrl-C or SIGTERM: keep what was learnt, then stop
        path = checkpointer.save(model)
        log(f"interrupted: saved {path.name} ({model.num_timesteps} env steps); run again to resume")
        raise
    finally:
        bar.close()
    checkpointer.save(model, final=True)
    return _summary(out, int(model.num_timesteps), round(clock(), 1))
