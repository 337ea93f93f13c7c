"""What :func:`krl.agent.train.train` logs and saves while PPO learns: the training log, checkpoints and
the exported policy."""

from __future__ import annotations

import json
import os
import shutil
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch
from stable_baselines3.common.callbacks import BaseCallback

from krl.agent.config import AgentConfig
from krl.agent.policy import Policy
from krl.util.output import write_atomic
from krl.util.progress import progress_bar


class TrainingCallback(BaseCallback):
    """Logs episode metrics and reward terms after every rollout; checkpoints every ``checkpoint_every``.

    Logged (TensorBoard and ``progress.csv``), as means over the episodes that ended in the rollout:
    ``episode/reward``, ``episode/targets_reached``, ``episode/fall_rate``, ``episode/length_s``,
    ``reward_terms/<term>`` (per-episode sums); and ``time/env_steps_per_s`` (the rollout's and the
    update's wall time together), ``time/wall_seconds``. SB3 adds ``train/approx_kl``,
    ``train/clip_fraction``, ``train/learning_rate`` and the losses.

    PyTorch runs on one thread while the environment workers step (more would only fight them for the
    cores) and on ``config.workers`` threads during PPO's update, when the workers wait: measured on the
    2-core machine, a minibatch of 4 000 took 28.5 ms on one thread and 16.6 ms on two, with the same
    loss to the last bit (``benchmarks/README.md``).
    """

    def __init__(
        self,
        out: Path,
        config: AgentConfig,
        run: dict[str, Any],
        wall_before: float,
        software: dict[str, str],
        progress: bool = False,
    ) -> None:
        super().__init__()
        self.bar = progress_bar(progress)
        self.bar_task = None
        self.out = out
        self.config = config
        self.run = run
        self.software = software
        self.wall_before = wall_before
        self.started = time.perf_counter()
        self.episodes: list[dict[str, Any]] = []
        self.last_time = self.started
        self.last_steps = 0
        self.last_checkpoint = -1

    def wall_seconds(self) -> float:
        return self.wall_before + time.perf_counter() - self.started

    def _on_training_start(self) -> None:
        self.last_steps = self.num_timesteps
        self.last_checkpoint = self.num_timesteps // self.config.checkpoint_every
        # PPO stops at the end of the rollout that reaches the goal, so the bar counts whole rollouts
        rollout = self.model.n_steps * self.model.n_envs
        remaining = max(0, self.locals["total_timesteps"] - self.num_timesteps)
        goal = self.num_timesteps + -(-remaining // rollout) * rollout
        self.bar.start()
        self.bar_task = self.bar.add_task("env steps", total=goal, completed=self.num_timesteps)

    def _on_training_end(self) -> None:
        self.close_progress()

    def close_progress(self) -> None:
        """Take the progress bar off the terminal (also after an interruption)."""
        self.bar.stop()

    def _on_rollout_start(self) -> None:
        torch.set_num_threads(1)

    def _on_step(self) -> bool:
        self.bar.update(self.bar_task, completed=self.num_timesteps)
        for info in self.locals["infos"]:
            episode = info.get("episode")
            if episode is not None:
                self.episodes.append(episode)
        return True

    def _on_rollout_end(self) -> None:
        now = time.perf_counter()
        steps = self.num_timesteps - self.last_steps
        record = self.logger.record
        record("time/env_steps_per_s", steps / max(now - self.last_time, 1e-9))
        record("time/wall_seconds", self.wall_seconds())
        self.last_time, self.last_steps = now, self.num_timesteps
        if self.episodes:
            record("episode/reward", float(np.mean([e["r"] for e in self.episodes])))
            record("episode/targets_reached", float(np.mean([e["targets_reached"] for e in self.episodes])))
            record("episode/fall_rate", float(np.mean([e["fell"] for e in self.episodes])))
            record("episode/length_s", float(np.mean([e["l"] for e in self.episodes])) * 0.005)
            record("episode/count", len(self.episodes))
            for name in self.episodes[0]["terms"]:
                record(
                    f"reward_terms/{name}", float(np.mean([e["terms"].get(name, 0.0) for e in self.episodes]))
                )
            self.episodes = []
        if self.num_timesteps // self.config.checkpoint_every > self.last_checkpoint:
            self.last_checkpoint = self.num_timesteps // self.config.checkpoint_every
            self.save_checkpoint(self.model)
        torch.set_num_threads(self.config.workers)  # PPO's update follows; the workers wait for it

    def save_checkpoint(self, model, final: bool = False) -> Path:
        """Save the model, its normaliser and the exported policy; the newest checkpoint is named in
        ``checkpoints/latest`` only once all of it is written."""
        steps = int(model.num_timesteps)
        directory = self.out / "checkpoints"
        directory.mkdir(parents=True, exist_ok=True)
        name = f"{steps:011d}"
        temporary = directory / f".{name}.tmp"
        temporary.mkdir(exist_ok=True)
        model.save(str(temporary / "model.zip"))
        normaliser = model.get_vec_normalize_env()
        if normaliser is not None:
            normaliser.save(str(temporary / "normaliser.pkl"))
        state = {"num_timesteps": steps, "wall_seconds": round(self.wall_seconds(), 3), "final": final}
        (temporary / "state.json").write_text(json.dumps(state) + "\n")
        final_dir = directory / name
        if final_dir.exists():
            shutil.rmtree(final_dir)
        os.replace(temporary, final_dir)
        training = {
            "env_steps": steps,
            "wall_seconds": state["wall_seconds"],
            "seed": self.run["seed"],
            "workers": self.config.workers,
            "num_envs": self.config.num_envs,
        }
        if "initialized_from" in self.run:
            training["initialized_from"] = self.run["initialized_from"]
        metadata = {
            "kernel_sha256": self.run["kernel_sha256"],
            "training": training,
            "software": self.software,
        }
        export_policy(model, normaliser, self.config, metadata).save(self.out / "policy.npz")
        write_atomic(directory / "latest", (name + "\n").encode())
        remove_old_checkpoints(directory, name)
        return final_dir


def export_policy(model, normaliser, config: AgentConfig, metadata: dict[str, Any]) -> Policy:
    """The actor of a trained SB3 PPO model (+ its observation normaliser) as a :class:`Policy`."""
    import torch

    policy = model.policy
    modules = [
        *policy.features_extractor.net,
        *policy.mlp_extractor.policy_net,
        policy.action_net,
    ]
    layers = [
        (m.weight.detach().cpu().double().numpy(), m.bias.detach().cpu().double().numpy())
        for m in modules
        if isinstance(m, torch.nn.Linear)
    ]
    size = layers[0][0].shape[1]
    if normaliser is not None and config.ppo.normalize_observations:
        mean, var = normaliser.obs_rms.mean.astype(np.float64), normaliser.obs_rms.var.astype(np.float64)
        clip, epsilon = float(normaliser.clip_obs), float(normaliser.epsilon)
    else:
        mean, var, clip, epsilon = np.zeros(size), np.ones(size), 1e9, 0.0
    return Policy(config, layers, mean, var, clip, epsilon, metadata)


def remove_old_checkpoints(directory: Path, keep: str) -> None:
    """Delete every checkpoint folder in ``directory`` but ``keep``."""
    for child in directory.iterdir():
        if child.is_dir() and child.name != keep:
            shutil.rmtree(child, ignore_errors=True)
