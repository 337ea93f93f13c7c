"""Training the residual agent with Stable-Baselines3's PPO (thesis Sections 4.2.8-4.2.9).

``train(out, config, seed)`` trains into the run folder ``out``:

| file | what |
| --- | --- |
| ``config.json`` | the resolved :class:`krl.agent.config.AgentConfig` |
| ``run.json`` | seed, kernel file and its SHA-256, krl version |
| ``checkpoints/<steps>/`` | SB3 model, observation normaliser, ``state.json``; ``latest`` names the newest |
| ``policy.npz`` | the exported policy (:mod:`krl.agent.policy`), refreshed at every checkpoint |
| ``progress.csv``, ``events.*`` | the training log, CSV and TensorBoard (:mod:`krl.agent.callbacks`) |
| ``progress.<steps>.csv`` | the CSV log before a resumption at ``<steps>`` (SB3 starts its CSV afresh) |

``train(out, config, seed, init_from=RUN)`` starts a new run from another run's newest checkpoint (its
policy, value function, optimiser state and observation normaliser): fine-tuning, for instance under
another training distribution. The two must share the kernel, the residual path, the observation and the
network; ``run.json`` and the exported policy's metadata record the run it started from and its env steps.

Calling it again on the same folder resumes from the newest checkpoint (an interruption loses at most
``checkpoint_every`` env steps). The environments restart from fresh episodes on resumption, seeded from
the run's seed and the checkpoint's step count, so a resumed run is reproducible but not bit-identical to
an uninterrupted one; an uninterrupted run with the same seed on the same machine is.
"""

from __future__ import annotations

import json
import os
import signal
from pathlib import Path
from typing import Any

from krl.agent.config import AgentConfig, AgentConfigError
from krl.util.hashing import file_sha256
from krl.util.output import write_atomic
from krl.util.parallel import Interrupted


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


def _policy_kwargs(config: AgentConfig) -> dict[str, Any]:
    import torch

    from krl.agent.network import SharedExtractor

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
    import torch

    from krl import __version__

    return {
        "krl": __version__,
        "stable_baselines3": stable_baselines3.__version__,
        "torch": torch.__version__,
        "mujoco": mujoco.__version__,
    }


def _latest_checkpoint(out: Path) -> Path | None:
    latest = out / "checkpoints" / "latest"
    if not latest.is_file():
        return None
    path = out / "checkpoints" / latest.read_text().strip()
    if not (path / "state.json").is_file():
        raise TrainingError(f"run {out}: checkpoint {path.name} named by checkpoints/latest is incomplete")
    return path


def _read_run(folder: Path) -> tuple[AgentConfig, dict[str, Any]]:
    """A run folder's config and run record; ``OSError``, ``ValueError`` or ``AgentConfigError`` if either
    cannot be read."""
    config_path = folder / "config.json"
    config = AgentConfig.from_json(json.loads(config_path.read_text()), str(config_path))
    return config, json.loads((folder / "run.json").read_text())


def _corrupt(checkpoint: Path, error: Exception) -> TrainingError:
    """The one-line error for a checkpoint SB3 or pickle cannot load (they raise many types)."""
    first = str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__
    return TrainingError(f"checkpoint {checkpoint} is corrupt: {first}")


def _open_run(
    out: Path, config: AgentConfig | None, seed: int | None, init_from: Path | None = None
) -> tuple[AgentConfig, dict[str, Any]]:
    """Read (resuming) or create the run folder; returns its config and run record."""
    if (out / "config.json").is_file():
        try:
            stored, run = _read_run(out)
        except (OSError, ValueError, AgentConfigError) as error:
            raise TrainingError(f"run {out} cannot be resumed: {error}") from None
        if config is not None and config != stored:
            raise TrainingError(
                f"run {out} was started with another config; use a new --out or drop --config"
            )
        if seed is not None and seed != run["seed"]:
            raise TrainingError(f"run {out} was started with seed {run['seed']}, not {seed}")
        started_from = run.get("initialized_from", {}).get("run")
        if init_from is not None and (
            started_from is None or Path(started_from).resolve() != Path(init_from).resolve()
        ):
            raise TrainingError(f"run {out} was not started from {init_from}; drop --init-from to resume it")
        return stored, run
    config = config or AgentConfig()
    from krl.kernel.registry import resolve_model

    kernel_path = resolve_model(config.residual.kernel)
    if not kernel_path.is_file():
        raise TrainingError(f"kernel file {kernel_path} not found")
    from krl.kernel.model import load_kernel

    load_kernel(kernel_path)  # a one-line KernelFileError before anything is written
    run = {
        "seed": 0 if seed is None else seed,
        "kernel_path": str(kernel_path.resolve()),
        "kernel_sha256": file_sha256(kernel_path),
        "software": _software(),
    }
    if init_from is not None:
        run["initialized_from"] = _initial_run(init_from, config, run["kernel_sha256"])
    out.mkdir(parents=True, exist_ok=True)
    write_atomic(out / "run.json", (json.dumps(run, indent=2) + "\n").encode())
    write_atomic(out / "config.json", (json.dumps(config.to_json(), indent=2) + "\n").encode())
    return config, run


def _initial_run(source: Path, config: AgentConfig, kernel_sha256: str) -> dict[str, Any]:
    """What a run started from ``source`` records of it; refuses a source the new run cannot start from."""
    checkpoint = _latest_checkpoint(source)
    if checkpoint is None or not (source / "config.json").is_file():
        raise TrainingError(f"--init-from {source}: not a run folder of krl agent train with a checkpoint")
    try:
        theirs, their_run = _read_run(source)
        state = json.loads((checkpoint / "state.json").read_text())
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
    return {
        "run": str(source),
        "checkpoint": checkpoint.name,
        "env_steps": int(state["num_timesteps"]),
        "wall_seconds": float(state["wall_seconds"]),
        "seed": their_run.get("seed"),
    }


def _start_from(model, env, start: dict[str, Any]) -> None:
    """Load the checkpoint a new run records in ``initialized_from`` (``start``) into its ``model``
    (weights and optimiser state) and its normaliser ``env`` (running statistics)."""
    from stable_baselines3.common.vec_env import VecNormalize

    checkpoint = Path(start["run"]) / "checkpoints" / start["checkpoint"]
    if not (checkpoint / "model.zip").is_file():
        raise TrainingError(f"checkpoint {checkpoint} that this run starts from is gone (trained on since?)")
    try:
        model.set_parameters(str(checkpoint / "model.zip"), exact_match=True, device="cpu")
        normaliser = checkpoint / "normaliser.pkl"
        if normaliser.is_file():
            theirs = VecNormalize.load(str(normaliser), env.venv)
            env.obs_rms, env.ret_rms = theirs.obs_rms, theirs.ret_rms
    except Exception as error:
        raise _corrupt(checkpoint, error) from None


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


def train(
    out: str | Path,
    config: AgentConfig | None = None,
    seed: int | None = None,
    total_steps: int | None = None,
    progress: bool = True,
    log=print,
    init_from: str | Path | None = None,
) -> dict[str, Any]:
    """Train (or resume) a residual agent in ``out``; returns a summary (steps, wall time, policy path).

    Args:
        out: the run folder.
        config: the agent's configuration (default :class:`AgentConfig`); must match a resumed run's.
        seed: the run's seed (default 0); must match a resumed run's.
        total_steps: env steps to train to (default ``config.total_steps``); may extend a finished run.
        progress: show a progress bar.
        log: where one-line messages go.
        init_from: a run folder whose newest checkpoint a new run starts from (module docstring).
    """
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.logger import configure
    from stable_baselines3.common.vec_env import VecNormalize
    from threadpoolctl import threadpool_limits

    from krl.agent.callbacks import TrainingCallback
    from krl.agent.workers import ProcessVecEnv

    out = Path(out)
    source = None if init_from is None else Path(init_from)
    config, run = _open_run(out, config, seed, source)
    seed = run["seed"]
    total = int(total_steps or config.total_steps)
    checkpoint = _latest_checkpoint(out)
    done_steps, wall_before = 0, 0.0
    if checkpoint is not None:
        state = json.loads((checkpoint / "state.json").read_text())
        done_steps, wall_before = int(state["num_timesteps"]), float(state["wall_seconds"])
    if done_steps >= total:
        log(f"run {out} already has {done_steps} env steps (of {total}); nothing to do")
        return {
            "out": str(out),
            "env_steps": done_steps,
            "wall_seconds": wall_before,
            "policy": str(out / "policy.npz"),
        }
    os.environ["OPENBLAS_NUM_THREADS"] = "1"  # inherited by the spawned workers
    torch.set_num_threads(1)  # small networks: extra intra-op threads only spin against the env workers
    env_seed = seed if checkpoint is None else seed + 7919 * (done_steps // config.checkpoint_every + 1)
    kernel_path = _run_kernel(out, config, run)
    venv = ProcessVecEnv(config, config.workers, config.num_envs, env_seed, kernel_path)
    num_envs = venv.num_envs
    try:
        ppo = config.ppo
        if checkpoint is None:
            env = VecNormalize(
                venv, norm_obs=ppo.normalize_observations, norm_reward=ppo.normalize_rewards, gamma=ppo.gamma
            )
            model = PPO(
                "MlpPolicy",
                env,
                learning_rate=LearningRate(ppo, total),
                n_steps=max(1, ppo.rollout_steps // num_envs),
                batch_size=ppo.batch_size,
                n_epochs=ppo.n_epochs,
                gamma=ppo.gamma,
                gae_lambda=ppo.gae_lambda,
                clip_range=ppo.clip_range,
                ent_coef=ppo.ent_coef,
                policy_kwargs=_policy_kwargs(config),
                seed=seed,
                device="cpu",
                verbose=0,
            )
            start = run.get("initialized_from")
            if start is not None:
                _start_from(model, env, start)
                log(f"starting {out} from {start['run']} ({start['env_steps']} env steps)")
        else:
            try:
                env = VecNormalize.load(str(checkpoint / "normaliser.pkl"), venv)
                model = PPO.load(
                    str(checkpoint / "model.zip"),
                    env=env,
                    device="cpu",
                    custom_objects={
                        "learning_rate": LearningRate(ppo, total),
                        "lr_schedule": LearningRate(ppo, total),
                    },
                )
            except Exception as error:
                raise _corrupt(checkpoint, error) from None
            model.num_timesteps = done_steps
            log(f"resuming {out} from {checkpoint.name} ({done_steps} env steps)")
        log_path = out / "progress.csv"
        if checkpoint is not None and log_path.is_file():  # SB3's CSV logger starts its file afresh
            os.replace(log_path, out / f"progress.{done_steps:011d}.csv")
        model.set_logger(configure(str(out), ["csv", "tensorboard"]))
        callback = TrainingCallback(out, config, run, wall_before, _software(), progress)
        previous = signal.signal(signal.SIGTERM, _terminate)
        try:
            with threadpool_limits(1, user_api="blas"):
                model.learn(
                    total - done_steps,
                    callback=callback,
                    reset_num_timesteps=checkpoint is None,
                )
        except KeyboardInterrupt:  # Ctrl-C or SIGTERM: keep what was learnt, then stop
            path = callback.save_checkpoint(model)
            log(f"interrupted: saved {path.name} ({model.num_timesteps} env steps); run again to resume")
            raise
        finally:
            callback.close_progress()
            signal.signal(signal.SIGTERM, previous)
        callback.save_checkpoint(model, final=True)
        return {
            "out": str(out),
            "env_steps": int(model.num_timesteps),
            "wall_seconds": round(callback.wall_seconds(), 1),
            "policy": str(out / "policy.npz"),
        }
    finally:
        venv.close()
