"""``krl/A1-v0``: the A1 on any terrain, driven by 12 joint-angle targets through the 1 kHz PD.

This is the joint-space base environment; like the residual environment (:mod:`krl.envs.residual`) it
steps its robot through the one episode loop (:class:`krl.task.episode.EpisodeBatch`), here with a task that
holds a zero command and never ends, so only a fall ends its episode. ``docs/envs.md`` documents the spaces
and the episode rules.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np

from krl.robots.a1.constants import JOINT_LOWER, JOINT_UPPER, NUM_JOINTS, STANDING_JOINT_ANGLES
from krl.sim.batch import joint_vector
from krl.sim.model import build_model
from krl.sim.robot import A1Sim, RobotState
from krl.task.episode import EpisodeBatch
from krl.task.reward import EVALUATION_REWARD
from krl.task.runner import HoldTask
from krl.util.timing import CONTROL_DT

OBSERVATION_LAYOUT: tuple[tuple[str, int], ...] = (
    ("base_height", 1),  # trunk height above the terrain's rest surface under it [m]
    ("projected_gravity", 3),  # gravity direction in the base frame (unit vector)
    ("lin_vel_base", 3),  # trunk linear velocity in the base frame [m/s]
    ("ang_vel_base", 3),  # trunk angular velocity in the base frame [rad/s]
    ("joint_pos", 12),  # joint angles [rad], FR FL RR RL x (abduction, hip, knee)
    ("joint_vel", 12),  # joint velocities [rad/s]
    ("foot_pos_base", 12),  # foot-sphere centres in the base frame [m], leg-major (x, y, z)
    ("foot_contact", 4),  # 1.0 where the foot touched something in the last physics step
)
"""Names and sizes of the observation vector's blocks, in order."""

OBSERVATION_SLICES: dict[str, slice] = {}
_start = 0
for _name, _size in OBSERVATION_LAYOUT:
    OBSERVATION_SLICES[_name] = slice(_start, _start + _size)
    _start += _size
OBSERVATION_SIZE: int = _start
"""Length of the observation vector (50)."""

INITIAL_JOINT_NOISE: float = 0.05
"""Half-width of the uniform noise added to the standing pose at reset [rad]."""

_ENDLESS = np.iinfo(np.int64).max
"""Control steps of the zero-command task: more than any episode takes (the registered id truncates)."""


def observation_vector(state: RobotState, ground_height: float) -> np.ndarray:
    """Flatten a state into the documented observation vector. Shape: (OBSERVATION_SIZE,), float32."""
    return np.concatenate(
        (
            [state.base_pos[2] - ground_height],
            state.projected_gravity,
            state.lin_vel_base,
            state.ang_vel_base,
            state.joint_pos,
            state.joint_vel,
            state.foot_pos_base.ravel(),
            state.foot_contact,
        )
    ).astype(np.float32)


class A1Env(gym.Env):
    """The A1 standing on a terrain; each step is one 200 Hz control step.

    Action: 12 joint-angle targets [rad] within the joint limits, tracked by the Table 4.2 PD.
    Observation: :data:`OBSERVATION_LAYOUT`. Reward: 1 per step survived, 0 on the step that falls
    (task rewards belong to the task environments built on this one). Terminates when the robot falls
    (:attr:`RobotState.fallen`); the registered id truncates after 2000 steps (10 s).

    Args:
        terrain: a name from ``krl.sim.terrains.TERRAIN_NAMES``.
        terrain_params: overrides of the terrain's parameters.
        terrain_seed: seed of the terrain's random draws (the terrain is built once, here).
        render_mode: ``None`` or ``"rgb_array"``.
        width, height: size of rendered frames [px].
    """

    metadata: ClassVar[dict[str, Any]] = {
        "render_modes": ["rgb_array"],
        "render_fps": round(1.0 / CONTROL_DT),
    }

    def __init__(
        self,
        terrain: str = "flat",
        terrain_params: Mapping[str, Any] | None = None,
        terrain_seed: int = 0,
        render_mode: str | None = None,
        width: int = 640,
        height: int = 480,
    ) -> None:
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"unknown render_mode {render_mode!r}; supported: rgb_array")
        self.sim = A1Sim(build_model(terrain, terrain_params, terrain_seed))
        self.episodes = EpisodeBatch(self.sim.backend, EVALUATION_REWARD)
        """The episode loop over the simulator's batch of one (its reward terms are not this env's)."""
        self.render_mode = render_mode
        self._size = (width, height)
        self._renderer = None
        self.action_space = gym.spaces.Box(
            JOINT_LOWER.astype(np.float32), JOINT_UPPER.astype(np.float32), dtype=np.float32
        )
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, shape=(OBSERVATION_SIZE,), dtype=np.float32)

    @property
    def terrain(self):
        """The terrain the robot stands on (:class:`krl.sim.terrains.Terrain`)."""
        return self.sim.terrain

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        noise = self.np_random.uniform(-INITIAL_JOINT_NOISE, INITIAL_JOINT_NOISE, NUM_JOINTS)
        angles = np.clip(STANDING_JOINT_ANGLES + noise, JOINT_LOWER, JOINT_UPPER)
        state = self.sim.reset(joint_angles=angles)
        self._start_episode()
        return self._observation(state), self._info(state)

    def _start_episode(self) -> None:
        """Begin the loop's episode from the current state: a zero command, no pushes."""
        self.episodes.start([0], [HoldTask(np.zeros(3), _ENDLESS, 1)], [None])

    def step(self, action):
        """One 200 Hz control step: Gymnasium's ``(observation, reward, terminated, truncated, info)``."""
        action = np.asarray(action, dtype=float)
        if action.shape != (NUM_JOINTS,):
            raise ValueError(f"action must have shape (12,), got {action.shape}")
        q_target = joint_vector(np.clip(action, JOINT_LOWER, JOINT_UPPER), "q_target")
        if not self.episodes.active[0]:  # stepped on after a fall: the simulation goes on
            self._start_episode()
        step = self.episodes.step(q_target[None])
        if step.unstable[0]:
            raise self.sim.backend.divergence(0)
        state = self.sim.state
        terminated = bool(step.fell[0])
        reward = 0.0 if terminated else 1.0
        return self._observation(state), reward, terminated, False, self._info(state)

    def render(self):
        if self.render_mode != "rgb_array":
            return None
        if self._renderer is None:
            from krl.sim.render import FrameRenderer

            self._renderer = FrameRenderer(self.sim.model, *self._size)
        return self._renderer.render(self.sim.data)

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def _observation(self, state: RobotState) -> np.ndarray:
        x, y = state.base_pos[0], state.base_pos[1]
        ground = float(self.sim.terrain.height(np.array([x]), np.array([y]))[0])
        return observation_vector(state, ground)

    def _info(self, state: RobotState) -> dict[str, Any]:
        return {"time": state.time, "fallen": state.fallen, "base_pos": state.base_pos.copy()}
