"""``krl/A1Residual-v0``: the residual agent's Gymnasium environment, one robot of
:class:`krl.agent.env.ResidualEnvBatch` (the N-robot core training steps through the one episode loop).

It lives here, with ``krl/A1-v0`` (:mod:`krl.envs.a1`), because :mod:`krl.envs` is the package of the
Gymnasium environments and sits above :mod:`krl.agent` (packages import only downward), so it imports the
batch it wraps; training's vectorised face (:class:`krl.agent.env.ResidualVecEnv`) stays in the agent.
"""

from __future__ import annotations

from typing import Any, ClassVar

import gymnasium as gym
import numpy as np

from krl.agent.config import AgentConfig
from krl.agent.env import ResidualEnvBatch
from krl.agent.observation import observation_table
from krl.util.timing import CONTROL_DT


class A1ResidualEnv(gym.Env):
    """``krl/A1Residual-v0``: one A1 on rough terrain; the kernel walks, the agent adds foot residuals.

    The kernel (shipped kernel-base by default) maps the velocity command of Algorithm 2 and the gait's
    phases to the four feet's targets; the action corrects them (thesis Fig. 4.1, Sections 4.2.8-4.2.9).
    One step is one 200 Hz control step: five 1 ms physics steps of the Table 4.2 PD inside MuJoCo.

    ## Action space
    ``Box(-1, 1, (12,), float32)`` by default: per foot (FR, FL, RR, RL) an (x, y, z) residual in the base
    frame, scaled by ``config.residual.residual_bound`` [m], low-pass filtered (Eq. 4.4, α =
    ``config.residual.residual_alpha``), added to the kernel's targets, then IK and PD
    (:class:`krl.agent.residual.ResidualController`). The ``drive_*`` switches of ``config.residual``
    append the kernel's command (3), kernel-ext's step and ride heights (2) and the gait clock's rate (1),
    each mapped onto its range and filtered (:mod:`krl.agent.action`); ``residuals=False`` drops the 12
    residuals. Any other shape raises ValueError.

    ## Observation space
    ``Box(-inf, inf, (D,), float32)``: the features of ``config.observation.features``, concatenated in that
    order (the default, the thesis's final set, gives D = 54), then those of
    ``config.observation.critic_features``, which only the critic reads (a privileged critic; the exported
    policy takes the first part alone). Every feature (a height scan's size is its grid's,
    ``config.observation.scan``):

    {observation_table}

    ## Rewards
    :func:`krl.task.reward.reward_terms` with ``config.env.reward`` (a :class:`krl.task.reward.RewardConfig`;
    agent-rp's by default: Table 4.8 plus roll/pitch): one RBF term per entry of ``reward.terms``
    (``weight * exp(-q * ||target - measured||^2)``), ``fall`` on the step the robot falls and
    ``target_reached`` on the step it comes within D_min of its waypoint. ``info["reward_terms"]`` holds every
    term of the step, and they sum to the reward.

    ## Starting state
    The robot stands at the terrain's spawn point facing a random direction; waypoints are drawn
    ``config.env.target_distance`` m apart, ``config.env.field_margin`` m inside the field. The terrain is a
    random height field with probability ``config.env.heightfield_probability``, stepped pyramids with
    ``config.env.pyramids_probability`` (0, the thesis's, by default), else Perlin hills, kept for
    ``config.env.episodes_per_terrain`` episodes, its ground friction μ ~ U(``config.env.friction``) (1, the
    thesis's, by default). Pushes (``config.env.pushes``) come every ``push_interval`` s with a force of
    ``push_magnitude`` N. ``reset(seed=s)`` seeds all of these.

    ## Episode end
    Terminates when the robot falls (``docs/sim.md``); truncates after ``config.env.episode_time`` s (60 s:
    the thesis counts the targets reached in 60 s). The last step's ``info["episode"]`` holds the episode's
    sums (:data:`krl.agent.env.EPISODE_INFO_KEYS`).

    ## Arguments
    - ``config``: the agent's configuration (default :class:`krl.agent.config.AgentConfig`).
    - ``kernel_path``: the kernel file (default: the one ``config.residual.kernel`` names).
    - ``render_mode``: None or ``"rgb_array"`` (frames from a camera tracking the trunk).
    """

    metadata: ClassVar[dict[str, Any]] = {
        "render_modes": ["rgb_array"],
        "render_fps": round(1.0 / CONTROL_DT),
    }

    def __init__(
        self,
        config: AgentConfig | None = None,
        kernel_path: str | None = None,
        render_mode: str | None = None,
    ) -> None:
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"unknown render_mode {render_mode!r}; supported: rgb_array")
        self.batch = ResidualEnvBatch(config or AgentConfig(), 1, kernel_path)
        self.render_mode = render_mode
        self._renderer = None
        self.action_size = self.batch.config.residual.action_size
        self.action_space = gym.spaces.Box(-1.0, 1.0, shape=(self.action_size,), dtype=np.float32)
        self.observation_space = gym.spaces.Box(
            -np.inf, np.inf, shape=(self.batch.observation_size,), dtype=np.float32
        )
        self._last_terms: dict[str, float] = {}

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        if seed is not None:
            self.batch.seed(0, seed)
        observation = self.batch.reset([0])[0]
        return observation, {"terrain": self.batch.terrain_names[0]}

    def step(self, action):
        """One 200 Hz control step: Gymnasium's ``(observation, reward, terminated, truncated, info)``."""
        action = np.asarray(action, dtype=float)
        if action.shape != (self.action_size,):
            raise ValueError(
                f"an action has shape ({self.action_size},) (krl.agent.action lists its parts), "
                f"got {action.shape}"
            )
        action = action[None, :]
        observations, rewards, terminated, truncated, infos = self.batch.step(action)
        info = infos[0]
        info["reward_terms"] = {name: float(values[0]) for name, values in self.batch.last_terms.items()}
        return observations[0], float(rewards[0]), bool(terminated[0]), bool(truncated[0]), info

    def render(self):
        if self.render_mode != "rgb_array":
            return None
        if self._renderer is None:
            from krl.sim.render import FrameRenderer

            self._renderer = FrameRenderer(self.batch.sims.model(0), 640, 480)
        return self._renderer.render(self.batch.sims.data(0))

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


if A1ResidualEnv.__doc__:  # None under python -OO
    A1ResidualEnv.__doc__ = A1ResidualEnv.__doc__.replace(
        "{observation_table}", observation_table().replace("\n", "\n    ")
    )
