"""The residual agent's environments: N robots walking to random waypoints on rough terrain, with pushes.

:class:`ResidualEnvBatch` is the core: N environments stepped together in one process through the one
episode loop (:class:`krl.task.episode.EpisodeBatch`: pushes, physics, task, reward terms, termination;
the loop evaluation walks its runs through), the physics one robot after the other
(:class:`krl.sim.backend.SimBackend`), everything else (kernel, filter, IK, observation, reward) batched
over N.
Two faces use it:

* :class:`ResidualVecEnv`, a Stable-Baselines3 ``VecEnv`` of N robots with automatic resets (training);
* :class:`krl.envs.residual.A1ResidualEnv`, the Gymnasium environment ``krl/A1Residual-v0`` (one robot),
  which lives with the other Gymnasium environment in :mod:`krl.envs` (docs/envs.md).

An episode (Section 4.2.9): the robot starts at the terrain's spawn point facing a random direction and
walks to consecutive random waypoints (2.5-3.5 m apart, inside the field) through the command generator
of Algorithm 2, D_min 0.5 m; a fall terminates it, the 60 s limit truncates it. Terrains: a random height
field (perturbation ~ U(3, 4.5) cm) with probability 0.75, else Perlin hills, kept for 5 consecutive
episodes of that environment. Pushes of U(100, 350) N for 0.3 s every U(5, 8) s at a random trunk point,
slightly upwards (:mod:`krl.sim.pushes`). The reward is :func:`krl.task.reward.reward_terms` (agent-rp by
default), the one the evaluation tables use; every term is summed per episode and reported in the info
of the episode's last step. The evaluation courses are never used here: they are unseen terrain.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import gymnasium as gym
import numpy as np

from krl.agent.config import AgentConfig
from krl.agent.observation import observation_size, observe
from krl.agent.residual import ResidualController
from krl.agent.sensing import Sensing
from krl.agent.terrain_curriculum import difficulty, first_level, next_level, tile_terrain
from krl.agent.vec_env import BatchVecEnv
from krl.control.commands import CommandParams
from krl.kernel.model import load_kernel
from krl.kernel.registry import resolve_model
from krl.sim.backend import SimBackend, make_backend
from krl.sim.model import build_model
from krl.sim.pushes import PushDistribution, PushSchedule
from krl.sim.state import StateBatch
from krl.task.episode import EpisodeBatch
from krl.task.record import EpisodeRecords
from krl.task.waypoints import TaskStatus, WaypointTask, random_targets

EPISODE_INFO_KEYS: tuple[str, ...] = (
    "r",
    "l",
    "t",
    "targets_reached",
    "fell",
    "unstable",
    "terrain",
    "terms",
)
"""Keys of ``info["episode"]`` on an episode's last step (``r``, ``l``, ``t`` as SB3's Monitor), and with a
terrain curriculum ``terrain_level``, the level the episode walked on."""

SCAN_NOISE_STREAM: int = 0x5CA9
"""Second word of the seed of the height scan's noise generator (``[seed of environment 0, this]``), so its
draws never share a stream with the environments' own."""


class ResidualEnvBatch:
    """N residual environments without automatic resets.

    Args:
        config: the agent's configuration.
        num_envs: N.
        kernel_path: the kernel file (default: the one ``config.residual.kernel`` names).
        rowwise: run the kernel on each environment's row alone, so an environment's transitions do not
            depend on how many are batched with it (:class:`krl.agent.residual.ResidualController`; held-out
            episodes); training batches them.
    """

    def __init__(
        self, config: AgentConfig, num_envs: int, kernel_path: str | None = None, rowwise: bool = False
    ) -> None:
        self.config = config
        self.num_envs = num_envs
        self.kernel_path = str(resolve_model(config.residual.kernel) if kernel_path is None else kernel_path)
        kernel = load_kernel(self.kernel_path)
        self.controller = ResidualController(kernel, config.residual, num_envs, rowwise=rowwise)
        self.features = config.observation.all_features
        """The observation's features: the actor's, then the critic's own."""
        self.observation_size = observation_size(self.features, config.observation.scan)
        self.sensing = Sensing(config.observation, np.random.default_rng([0, SCAN_NOISE_STREAM]))
        self.curriculum = config.env.terrain_curriculum
        self.levels = np.full(num_envs, -1, dtype=np.int64)
        """Each environment's terrain curriculum level (-1: not drawn yet, or no curriculum)."""
        self.reward = config.env.reward
        self.command_params = replace(CommandParams(), d_min=config.env.d_min)
        env = config.env
        self.pushes = PushDistribution(
            interval=env.push_interval, magnitude=env.push_magnitude, top_share=env.push_top_share
        )
        self.rngs: list[np.random.Generator] = [np.random.default_rng(index) for index in range(num_envs)]
        self.sims: SimBackend | None = None
        self.episodes: EpisodeBatch | None = None
        """The episode loop over :attr:`sims` (made with the first terrain)."""
        self.push_schedules: list[PushSchedule | None] = [None] * num_envs
        self.episodes_on_terrain = np.zeros(num_envs, dtype=np.int64)
        self.records = EpisodeRecords(num_envs)
        """The episodes' records (:mod:`krl.task.record`), the source of ``info["episode"]``."""
        self.terrain_names = [""] * num_envs
        self.needs_terrain = np.ones(num_envs, dtype=bool)
        self.states: StateBatch | None = None
        self.last_terms: dict[str, np.ndarray] = {}
        """The reward terms of the last step, one array of shape (N,) per term."""

    # --- resets ------------------------------------------------------------------------------------

    def seed(self, index: int, seed: int | None) -> None:
        """Reseed environment ``index``; its next reset draws a new terrain."""
        self.rngs[index] = np.random.default_rng(seed)
        self.needs_terrain[index] = True
        if index == 0:
            self.sensing.noise_rng = np.random.default_rng(
                None if seed is None else [seed, SCAN_NOISE_STREAM]
            )

    def _terrain(self, index: int):
        """A new terrain for environment ``index`` from its rng: a height field, stepped pyramids or Perlin
        hills (one U(0, 1) draw picks, so with no pyramids the draws are those of runs before them), and
        the ground's friction μ ~ U(``config.env.friction``), drawn only when that range is not one value
        (so the default, μ = 1, makes the draws of runs before the option). Its name carries μ where not
        1."""
        rng = self.rngs[index]
        env = self.config.env
        seed = int(rng.integers(2**31))
        curriculum = env.terrain_curriculum
        if curriculum is not None:
            if self.levels[index] < 0:
                self.levels[index] = first_level(curriculum, rng)
            name, params = tile_terrain(curriculum, int(self.levels[index]), rng)
            built, self.terrain_names[index] = _build_terrain(name, params, seed, rng, env.friction)
            return built
        kind = rng.random()
        if kind < env.heightfield_probability:
            low, high = env.heightfield_max_height
            name, params = "heightfield", {"max_height_low": low, "max_height_high": high}
        elif kind < env.heightfield_probability + env.pyramids_probability:
            low, high = env.pyramids_step_height
            name, params = "pyramids", {"step_height_low": low, "step_height_high": high}
        else:
            name, params = "perlin", {}
        built, self.terrain_names[index] = _build_terrain(name, params, seed, rng, env.friction)
        return built

    def reset(self, rows) -> np.ndarray:
        """Start a new episode in each environment of ``rows``; returns their observations, (n, D)."""
        rows = np.atleast_1d(np.asarray(rows, dtype=np.int64))
        env = self.config.env
        tasks: list[WaypointTask] = []
        for index in rows:
            new_terrain = (
                self.needs_terrain[index] or self.episodes_on_terrain[index] >= env.episodes_per_terrain
            )
            if new_terrain:
                built = self._terrain(index)
                if self.sims is None:
                    self.sims = make_backend([built] * self.num_envs)
                    self.episodes = EpisodeBatch(self.sims, self.reward)
                self.sims.replace(index, built)
                self.needs_terrain[index] = False
                self.episodes_on_terrain[index] = 0
            self.episodes_on_terrain[index] += 1
            rng = self.rngs[index]
            state = self.sims.reset(index, yaw=float(rng.uniform(-np.pi, np.pi)))
            landmarks = self.sims.terrain(index).landmarks
            low, high = landmarks["field_min"], landmarks["field_max"]
            margin = env.field_margin
            bounds = (low[0] + margin, low[1] + margin, high[0] - margin, high[1] - margin)
            count = math.ceil(env.episode_time * self.command_params.max_speed / env.target_distance[0]) + 2
            targets = random_targets(rng, count, tuple(state.base_pos[:2]), env.target_distance, bounds)
            task = WaypointTask(
                targets, self.command_params, target_time_limit=None, time_limit=env.episode_time
            )
            task.reset(state.base_pos[:2])
            tasks.append(task)
            self.push_schedules[index] = PushSchedule(self.pushes, rng) if env.pushes else None
        self.records.begin(rows)
        self.episodes.start(rows, tasks, [self.push_schedules[index] for index in rows])
        self.controller.reset(rows)
        self.states = self.sims.states
        self.controller.prepare(self.states.rows(rows), self.episodes.commands[rows], rows)
        return self._observe(rows)

    def set_push_ceiling(self, newtons: float) -> None:
        """Draw every push from now on with a magnitude ~ U(``push_magnitude``'s low, ``newtons``) [N]
        (a push curriculum's ceiling, :mod:`krl.agent.curriculum`), the episodes under way included."""
        self.pushes = replace(self.pushes, magnitude=(self.pushes.magnitude[0], float(newtons)))
        for schedule in self.push_schedules:
            if schedule is not None:
                schedule.distribution = self.pushes

    # --- stepping ----------------------------------------------------------------------------------

    def _observe(self, rows: np.ndarray) -> np.ndarray:
        sensed = None
        if self.sensing.needed:
            shares = np.zeros(self.num_envs)
            if self.curriculum is not None and "terrain_level" in self.sensing.names:
                shares = np.array([difficulty(self.curriculum, max(int(level), 0)) for level in self.levels])
            sensed = self.sensing.measure(self.sims, self.states, shares)
        inputs = self.controller.observation_inputs(self.states, sensed)
        return observe(self.features, inputs)[rows]

    def terrain_levels(self) -> np.ndarray:
        """Each environment's terrain curriculum level (-1: none yet). Shape: (N,), int."""
        return self.levels.copy()

    def set_terrain_levels(self, levels) -> None:
        """Put the environments on these curriculum levels (a resumed run's,
        :mod:`krl.agent.terrain_curriculum`); each walks its next episode on a new terrain of its level."""
        levels = np.asarray(levels, dtype=np.int64)
        if levels.shape != (self.num_envs,):
            raise ValueError(f"terrain levels must have shape ({self.num_envs},), got {levels.shape}")
        self.levels[:] = levels
        self.needs_terrain[:] = True

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, list[dict]]:
        """One control step of every environment.

        Returns ``(observations (N, D), rewards (N,), terminated (N,), truncated (N,), infos)``; an ended
        episode's info holds ``info["episode"]`` (:data:`EPISODE_INFO_KEYS`). Ended environments must be
        reset before the next step.
        """
        q_target = self.controller.joint_targets(actions)
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        step = self.episodes.step(q_target)
        self.states = states = step.states
        terminated, truncated, terms = step.fell, step.ended & ~step.fell, step.terms
        rewards = np.sum(list(terms.values()), axis=0)
        self.last_terms = terms
        self.controller.prepare(states, self.episodes.commands)
        observations = self._observe(np.arange(self.num_envs))
        self.records.add(step, np.arange(self.num_envs), self.sims.step_counts)
        for index, survived in self.records.judge_pushes(step).items():
            infos[index]["push_survived"] = survived
        for index in np.flatnonzero(terminated | truncated):
            task = self.episodes.tasks[index]
            record = self.records.finish(index, task.reached_count, task.status is TaskStatus.TIMED_OUT)
            infos[index]["episode"] = {
                "r": record.reward,
                "l": record.steps,
                "t": round(record.wall_seconds, 6),
                "targets_reached": record.targets_reached,
                "fell": record.fell,
                "unstable": record.unstable,
                "terrain": self.terrain_names[index],
                "terms": record.terms,
            }
            if self.curriculum is not None:
                self._promote(index, infos[index]["episode"], infos[index].get("push_survived") is False)
        return observations, rewards, terminated, truncated, infos

    def _promote(self, index: int, episode: dict[str, Any], pushed_off: bool) -> None:
        """Record the level environment ``index``'s episode was on, and move the level by its outcome
        (``pushed_off``: it ended in a fall a push caused); a changed level brings a new terrain at the next
        reset."""
        level = int(self.levels[index])
        episode["terrain_level"] = level
        new = next_level(self.curriculum, level, episode["targets_reached"], pushed_off, self.rngs[index])
        if new != level:
            self.levels[index] = new
            self.needs_terrain[index] = True


def _build_terrain(
    name: str, params: dict, seed: int, rng: np.random.Generator, friction: tuple[float, float]
):
    """Terrain ``name`` with ``params`` built from ``seed``, its ground friction μ ~ U(``friction``) drawn
    from ``rng`` where that range is not one value; returns the built model and the terrain's name (with
    μ where not 1)."""
    low, high = friction
    params["friction"] = float(rng.uniform(low, high)) if low < high else low
    built = build_model(name, params, seed)
    mu = built.terrain.params.get("friction")
    return built, f"{name}-{seed}" + ("" if mu is None else f"-mu{mu:.3f}")


class ResidualVecEnv(BatchVecEnv):
    """N residual environments as a Stable-Baselines3 ``VecEnv`` (one process), with automatic resets.

    Environment ``i`` is seeded with ``seed + i``, so it makes the same transitions as an
    :class:`A1ResidualEnv` reset with ``seed=seed + i``. An ended episode's info carries
    ``terminal_observation``, ``TimeLimit.truncated`` and ``episode`` (:data:`EPISODE_INFO_KEYS`).

    Args:
        config: the agent's configuration.
        num_envs: N.
        seed: seed of environment 0.
        kernel_path: the kernel file (default: the config's).
        rowwise: the kernel run row by row (:class:`ResidualEnvBatch`).
    """

    def __init__(
        self,
        config: AgentConfig,
        num_envs: int,
        seed: int = 0,
        kernel_path: str | None = None,
        rowwise: bool = False,
    ) -> None:
        self.batch = ResidualEnvBatch(config, num_envs, kernel_path, rowwise)
        action_space = gym.spaces.Box(-1.0, 1.0, shape=(config.residual.action_size,), dtype=np.float32)
        observation_space = gym.spaces.Box(
            -np.inf, np.inf, shape=(self.batch.observation_size,), dtype=np.float32
        )
        super().__init__(num_envs, observation_space, action_space)
        self._seed = seed
        self._actions: np.ndarray | None = None
        self.seed(seed)

    def reset(self) -> np.ndarray:
        return self.batch.reset(np.arange(self.num_envs))

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self):
        observations, rewards, terminated, truncated, infos = self.batch.step(self._actions)
        dones = terminated | truncated
        ended = np.flatnonzero(dones)
        for index in ended:
            infos[index]["terminal_observation"] = observations[index]
            infos[index]["TimeLimit.truncated"] = bool(truncated[index])
        if len(ended):
            observations = observations.copy()
            observations[ended] = self.batch.reset(ended)
        return observations, rewards.astype(np.float32), dones, infos

    def close(self) -> None:
        pass

    def set_push_ceiling(self, newtons: float) -> None:
        """:meth:`ResidualEnvBatch.set_push_ceiling` of the batch."""
        self.batch.set_push_ceiling(newtons)

    def terrain_levels(self) -> np.ndarray:
        """:meth:`ResidualEnvBatch.terrain_levels` of the batch."""
        return self.batch.terrain_levels()

    def set_terrain_levels(self, levels) -> None:
        """:meth:`ResidualEnvBatch.set_terrain_levels` of the batch."""
        self.batch.set_terrain_levels(levels)

    def seed(self, seed: int | None = None):
        base = self._seed if seed is None else seed
        for index in range(self.num_envs):
            self.batch.seed(index, base + index)
        return [base + index for index in range(self.num_envs)]
