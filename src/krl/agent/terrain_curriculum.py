"""A terrain curriculum for training (ours, docs/agent-perceptive.md): harder ground as a robot crosses it.

With ``config.env.terrain_curriculum`` (:class:`krl.agent.config.TerrainCurriculumConfig`) each training
robot has a *level*, 0 ... levels - 1. Each new terrain it walks on is a tile drawn by :func:`tile_terrain`:
a kind from the curriculum's ``tiles`` (by ``tile_weights``) at the level's difficulty, each kind's
parameter interpolated linearly from its range's low (level 0) to its high (the top level):

=========== ================= ==================================================================
tile        terrain           difficulty
=========== ================= ==================================================================
pyramids    ``pyramids``      riser height [m] (stairs up, then down)
pits        ``pits``          riser height [m] (stairs down, then up)
rough       ``heightfield``   bound of the random blocks' height [m]
slope       ``slope``         angle of the ramps [rad]
=========== ================= ==================================================================

After each episode :func:`next_level` promotes a robot that reached ``promote_targets`` waypoints (from
the top level to a random one, as legged_gym does, so the top levels are not all a robot sees) and demotes
one that reached fewer than ``demote_targets``, unless a push toppled it (a fall within the push verdict's
time says nothing of the ground); a changed level brings a new terrain at the next reset.
The evaluation courses never appear: no stairs course, table-top or seesaw is a tile.

The levels of every robot are saved in each checkpoint's ``state.json`` (``terrain_levels``) and given back
to a resumed run's robots (:func:`saved_levels`); progress.csv and TensorBoard log
``curriculum/terrain_level`` (the robots' mean level after each rollout) and ``curriculum/terrain_level_max``;
each ended episode's ``info["episode"]["terrain_level"]`` holds the level it walked on.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback

from krl.agent.config import TerrainCurriculumConfig

TILE_TERRAINS: dict[str, str] = {
    "pyramids": "pyramids",
    "pits": "pits",
    "rough": "heightfield",
    "slope": "slope",
}
"""The terrain (:data:`krl.sim.terrains.TERRAIN_NAMES`) each tile kind builds."""


def difficulty(curriculum: TerrainCurriculumConfig, level: int) -> float:
    """Where ``level`` lies between the lowest (0) and the top level (1)."""
    return 0.0 if curriculum.levels == 1 else level / (curriculum.levels - 1)


def tile_params(curriculum: TerrainCurriculumConfig, tile: str, level: int) -> dict[str, float]:
    """The terrain parameters of a ``tile`` kind at ``level``."""
    share = difficulty(curriculum, level)

    def between(bounds: tuple[float, float]) -> float:
        return float(bounds[0] + share * (bounds[1] - bounds[0]))

    if tile in ("pyramids", "pits"):
        riser = between(curriculum.riser)
        return {"step_height_low": riser, "step_height_high": riser}
    if tile == "rough":
        height = between(curriculum.roughness)
        return {"max_height_low": height, "max_height_high": height}
    return {"incline": between(curriculum.incline)}


def tile_terrain(
    curriculum: TerrainCurriculumConfig, level: int, rng: np.random.Generator
) -> tuple[str, dict[str, float]]:
    """A tile at ``level``: its terrain name and parameters (one draw from ``rng``: the kind)."""
    weights = np.asarray(curriculum.tile_weights, dtype=float)
    tile = curriculum.tiles[int(rng.choice(len(weights), p=weights / weights.sum()))]
    return TILE_TERRAINS[tile], tile_params(curriculum, tile, level)


def first_level(curriculum: TerrainCurriculumConfig, rng: np.random.Generator) -> int:
    """A robot's starting level, uniform on 0 ... start_levels - 1 (one draw from ``rng``)."""
    return int(rng.integers(curriculum.start_levels))


def next_level(
    curriculum: TerrainCurriculumConfig,
    level: int,
    targets_reached: int,
    pushed_off: bool,
    rng: np.random.Generator,
) -> int:
    """The level after an episode at ``level`` that reached ``targets_reached`` waypoints; ``pushed_off``:
    the episode ended in a fall within :data:`krl.task.record.PUSH_VERDICT_TIME` of a push's start (a draw
    from ``rng`` only for a promotion from the top level).

    A fall a push caused says nothing of the ground, so it never demotes: with agent-robust's pushes (up to
    900 N every 5-8 s) most episodes end that way, and demoting for them held every robot on level 0
    (docs/agent-perceptive.md, "The curriculum's amendment")."""
    if targets_reached >= curriculum.promote_targets:
        if level + 1 < curriculum.levels:
            return level + 1
        return int(rng.integers(curriculum.levels))
    if targets_reached < curriculum.demote_targets and not pushed_off:
        return max(level - 1, 0)
    return level


def saved_levels(checkpoint: Path | None) -> list[int] | None:
    """The levels of every robot a run resumed from ``checkpoint`` continues with, or None (a new run, or a
    checkpoint from before the curriculum)."""
    if checkpoint is None:
        return None
    levels = json.loads((checkpoint / "state.json").read_text()).get("terrain_levels")
    return None if levels is None else [int(level) for level in levels]


class TerrainCurriculumLog(BaseCallback):
    """Logs every robot's level after each rollout and keeps them for the checkpoints.

    The levels are read from the workers at each rollout's end, when every step's answer has been
    gathered, and a checkpoint saves the last levels read: a checkpoint saved on an interruption (SIGTERM
    arrives between a step's actions and its answers) must not ask the workers anything, or it would read a
    step's answer as theirs. Must come before :class:`krl.agent.callbacks.Checkpointer`, so that a checkpoint
    saved at a rollout's end holds the levels the robots are on.
    """

    def __init__(self) -> None:
        super().__init__()
        self.levels: list[int] | None = None
        """Every robot's level at the last rollout's end (None before the first)."""

    def _read_levels(self) -> list[int]:
        self.levels = [int(level) for level in self.training_env.unwrapped.terrain_levels()]
        return self.levels

    def state(self) -> dict[str, Any]:
        """What a checkpoint saves of the curriculum: every robot's level at the last rollout's end."""
        return {"terrain_levels": self._read_levels() if self.levels is None else list(self.levels)}

    def _on_step(self) -> bool:
        return True

    def _on_rollout_end(self) -> None:
        levels = np.maximum(self._read_levels(), 0)
        self.logger.record("curriculum/terrain_level", float(np.mean(levels)))
        self.logger.record("curriculum/terrain_level_max", int(np.max(levels)))
