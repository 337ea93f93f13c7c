"""What :func:`krl.agent.train.train` logs and saves while PPO learns.

Four SB3 callbacks, one job each: :class:`EpisodeLog` logs the episodes of every rollout,
:class:`Checkpointer` saves a checkpoint (:mod:`krl.agent.checkpoint` describes one and reads it back) every
``checkpoint_every`` env steps, :class:`ProgressBar` shows the env steps on the terminal,
:class:`StopOnSignal` stops on a stop signal whose exception was lost. They share a :class:`Clock` (the
run's wall time over all its sittings).
"""

from __future__ import annotations

import json
import os
import shutil
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback

from krl.agent.checkpoint import (
    KEPT_CHECKPOINTS,
    NORMALISER_FILE,
    NormaliserState,
    checkpoint_folders,
    steps_name,
)
from krl.agent.config import AgentConfig
from krl.agent.network import export_policy
from krl.agent.sb3_adapter import step_infos, training_goal
from krl.util.output import write_atomic
from krl.util.parallel import raise_if_interrupted
from krl.util.progress import progress_bar
from krl.util.timing import CONTROL_DT


class Clock:
    """A run's wall time [s]: ``before`` (its earlier sittings) plus the time since this one started."""

    def __init__(self, before: float) -> None:
        self.before = before
        self.started = time.perf_counter()

    def __call__(self) -> float:
        return self.before + time.perf_counter() - self.started


class EpisodeLog(BaseCallback):
    """Logs, after every rollout (TensorBoard and ``progress.csv``), the means over the episodes that
    ended in it: ``episode/reward``, ``episode/targets_reached``, ``episode/fall_rate``,
    ``episode/success_rate`` (:data:`SUCCESS_TARGETS`), ``episode/length_s`` [s], ``episode/count``,
    ``reward_terms/<term>`` (per-episode sums); and ``time/env_steps_per_s`` (the rollout's and the
    previous update's wall time together), ``time/wall_seconds``. SB3 adds ``train/approx_kl``,
    ``train/clip_fraction``, ``train/learning_rate`` and the losses."""

    def __init__(self, clock: Clock) -> None:
        super().__init__()
        self.clock = clock
        self.episodes: list[dict[str, Any]] = []
        self.last_time = clock.started
        self.last_steps = 0

    def _on_training_start(self) -> None:
        self.last_steps = self.num_timesteps

    def _on_step(self) -> bool:
        for info in step_infos(self):
            episode = info.get("episode")
            if episode is not None:
                self.episodes.append(episode)
        return True

    def _on_rollout_end(self) -> None:
        now = time.perf_counter()
        record = self.logger.record
        record(
            "time/env_steps_per_s", (self.num_timesteps - self.last_steps) / max(now - self.last_time, 1e-9)
        )
        record("time/wall_seconds", self.clock())
        self.last_time, self.last_steps = now, self.num_timesteps
        if not self.episodes:
            return
        episodes, self.episodes = self.episodes, []
        record("episode/reward", float(np.mean([e["r"] for e in episodes])))
        record("episode/targets_reached", float(np.mean([e["targets_reached"] for e in episodes])))
        record("episode/fall_rate", float(np.mean([e["fell"] for e in episodes])))
        success = [e["targets_reached"] >= SUCCESS_TARGETS and not e["fell"] for e in episodes]
        record("episode/success_rate", float(np.mean(success)))
        record("episode/length_s", float(np.mean([e["l"] for e in episodes])) * CONTROL_DT)
        record("episode/count", len(episodes))
        for name in episodes[0]["terms"]:
            record(f"reward_terms/{name}", float(np.mean([e["terms"].get(name, 0.0) for e in episodes])))


SUCCESS_TARGETS: int = 2
"""An episode succeeds when it reaches at least this many waypoints without falling (the thesis's success
rate of the agent studies, 4.2.8.2: "navigating to at least two target locations and not falling")."""


class ProgressBar(BaseCallback):
    """The env steps on the terminal (nothing when ``show`` is false)."""

    def __init__(self, show: bool) -> None:
        super().__init__()
        self.bar = progress_bar(show)
        self.task = None

    def _on_training_start(self) -> None:
        goal = rollout_end(self.model, training_goal(self))  # the bar counts whole rollouts
        self.bar.start()
        self.task = self.bar.add_task("env steps", total=goal, completed=self.num_timesteps)

    def _on_step(self) -> bool:
        self.bar.update(self.task, completed=self.num_timesteps)
        return True

    def _on_training_end(self) -> None:
        self.close()

    def close(self) -> None:
        """Take the bar off the terminal (also after an interruption)."""
        self.bar.stop()


def rollout_size(model) -> int:
    """The env steps of one of ``model``'s rollouts (SB3's PPO: ``n_steps`` of each of ``n_envs``)."""
    return model.n_steps * model.n_envs


def rollout_end(model, total_steps: int) -> int:
    """The env steps at which ``model`` (SB3's PPO) stops when it learns to ``total_steps``: the end of the
    rollout that reaches them, as it trains whole rollouts (:func:`rollout_size`)."""
    rollout = rollout_size(model)
    remaining = max(0, total_steps - model.num_timesteps)
    return model.num_timesteps + -(-remaining // rollout) * rollout


class StopOnSignal(BaseCallback):
    """Raises :class:`krl.util.parallel.Interrupted` at the next env step once SIGINT or SIGTERM arrived in a
    :func:`krl.util.parallel.signals_raise` scope and Python swallowed the handler's exception (it was raised
    inside a finaliser: :func:`krl.util.parallel.raise_if_interrupted`); otherwise training would go on."""

    def _on_step(self) -> bool:
        raise_if_interrupted()
        return True


class Checkpointer(BaseCallback):
    """Saves a checkpoint (module docstring) and exports ``policy.npz`` at the end of each rollout that
    passes a multiple of ``config.checkpoint_every`` env steps; :meth:`save` also at the end of training
    and on an interruption.

    Args:
        out: the run folder.
        config: the agent's configuration (the one this sitting trains with).
        run: the run record (``run.json``): seed, kernel SHA-256, ``initialized_from``.
        clock: the run's wall time.
        software: the versions recorded in the policy's metadata.
        extra_state: what else ``state.json`` saves (a push curriculum's ceiling), called at each save.
    """

    def __init__(
        self,
        out: Path,
        config: AgentConfig,
        run: dict[str, Any],
        clock: Clock,
        software: dict[str, str],
        extra_state: Callable[[], dict[str, Any]] = dict,
    ) -> None:
        super().__init__()
        self.out, self.config, self.run, self.clock, self.software = out, config, run, clock, software
        self.extra_state = extra_state
        self.last_checkpoint = -1

    def _on_training_start(self) -> None:
        self.last_checkpoint = self.num_timesteps // self.config.checkpoint_every

    def _on_step(self) -> bool:
        return True

    def _on_rollout_end(self) -> None:
        if self.num_timesteps // self.config.checkpoint_every > self.last_checkpoint:
            self.last_checkpoint = self.num_timesteps // self.config.checkpoint_every
            self.save(self.model)

    def save(self, model, final: bool = False) -> Path:
        """Save the model, its normaliser and the exported policy; the newest checkpoint is named in
        ``checkpoints/latest`` only once all of it is written, and then older ones are removed
        (:func:`remove_old_checkpoints`). Returns the checkpoint's folder."""
        steps = int(model.num_timesteps)
        directory = self.out / "checkpoints"
        directory.mkdir(parents=True, exist_ok=True)
        name = steps_name(steps)
        temporary = directory / f".{name}.tmp"
        temporary.mkdir(exist_ok=True)
        model.save(str(temporary / "model.zip"))
        normaliser = model.get_vec_normalize_env()
        if normaliser is not None:
            NormaliserState.of(normaliser).save(temporary / NORMALISER_FILE)
        state = {"num_timesteps": steps, "wall_seconds": round(self.clock(), 3), "final": final}
        state.update(self.extra_state())
        (temporary / "state.json").write_text(json.dumps(state) + "\n")
        folder = directory / name
        if folder.exists():
            shutil.rmtree(folder)
        os.replace(temporary, folder)
        metadata = self._metadata(state, model.device.type, model.update_threads)
        export_policy(model, normaliser, self.config, metadata).save(self.out / "policy.npz")
        write_atomic(directory / "latest", (name + "\n").encode())
        remove_old_checkpoints(directory, name)
        return folder

    def _metadata(self, state: dict[str, Any], device: str, update_threads: int) -> dict[str, Any]:
        """The exported policy's header: kernel, how it was trained (``state``: a checkpoint's state.json;
        the workers, PPO's ``device`` and its ``update_threads`` of this sitting; every sitting's machine,
        :func:`krl.agent.run_folder.record_sitting`) and the software."""
        training = {
            "env_steps": state["num_timesteps"],
            "wall_seconds": state["wall_seconds"],
            "seed": self.run["seed"],
            "workers": self.config.workers,
            "num_envs": self.config.num_envs,
            "device": device,
            "update_threads": update_threads,
        }
        if "initialized_from" in self.run:
            training["initialized_from"] = self.run["initialized_from"]
        if "sittings" in self.run:  # where each stretch trained (runs started before 2026-12-07 lack it)
            training["sittings"] = self.run["sittings"]
        return {"kernel_sha256": self.run["kernel_sha256"], "training": training, "software": self.software}


def remove_old_checkpoints(directory: Path, saved: str) -> None:
    """Delete every folder in ``directory`` but the checkpoint ``saved`` and the newest before it, up to
    :data:`KEPT_CHECKPOINTS` in all: older ones, unfinished ones, and any past ``saved`` (left by a run that
    resumed before a checkpoint it could not read, and trained those env steps again)."""
    kept = [path.name for path in checkpoint_folders(directory) if path.name <= saved][:KEPT_CHECKPOINTS]
    for child in directory.iterdir():
        if child.is_dir() and child.name not in kept:
            shutil.rmtree(child, ignore_errors=True)
