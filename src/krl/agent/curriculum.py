"""A push curriculum for training (ours, docs/agent-robust.md): the pushes grow as the agent survives them.

With ``config.env.push_curriculum`` the training pushes' magnitude is drawn ~ U(``push_magnitude``'s
low, the *ceiling*) [N]. The ceiling starts at ``push_magnitude``'s high; after each rollout
:func:`next_ceiling` moves it by ``push_curriculum_step`` from the fraction of the rollout's pushes that
were survived (``info["push_survived"]`` of :class:`krl.agent.env.ResidualEnvBatch`: no fall within
:data:`krl.task.record.PUSH_VERDICT_TIME` of the push's start), kept within [``push_magnitude``'s high,
``push_curriculum_max``]. Directions and points are drawn as every push's (:mod:`krl.sim.pushes`).

The ceiling in force is saved in every checkpoint's ``state.json`` (``push_ceiling``), read back by a
resumed run (:func:`saved_ceiling`), and logged in progress.csv: ``curriculum/push_ceiling`` (the
rollout's), ``curriculum/push_survival`` and ``curriculum/pushes`` (its verdicts).
"""

from __future__ import annotations

import json
from pathlib import Path

from stable_baselines3.common.callbacks import BaseCallback

from krl.agent.config import EnvConfig
from krl.agent.sb3_adapter import step_infos


def next_ceiling(env: EnvConfig, ceiling: float, survival: float | None) -> float:
    """The ceiling [N] after a rollout under ``ceiling`` whose pushes were survived at ``survival`` (None:
    no push was judged, so the ceiling stays)."""
    if survival is None:
        return ceiling
    if survival >= env.push_curriculum_raise:
        ceiling += env.push_curriculum_step
    elif survival < env.push_curriculum_lower:
        ceiling -= env.push_curriculum_step
    return float(min(max(ceiling, env.push_magnitude[1]), env.push_curriculum_max))


def saved_ceiling(checkpoint: Path | None, env: EnvConfig) -> float:
    """The ceiling [N] a run resumed from ``checkpoint`` continues with (its ``state.json``'s), or, for a
    new run or a checkpoint from before the curriculum, ``push_magnitude``'s high."""
    if checkpoint is not None:
        state = json.loads((checkpoint / "state.json").read_text())
        if "push_ceiling" in state:
            return float(state["push_ceiling"])
    return float(env.push_magnitude[1])


class PushCurriculum(BaseCallback):
    """Counts the rollout's push verdicts and sets the next rollout's ceiling in every environment.

    Must come before :class:`krl.agent.callbacks.Checkpointer` in the callback list, so that a checkpoint
    saved at a rollout's end holds the ceiling the next rollout (and a resumption) trains with.

    Args:
        env: the run's environment config (its curriculum settings).
        ceiling: the ceiling of the first rollout [N] (:func:`saved_ceiling`).
    """

    def __init__(self, env: EnvConfig, ceiling: float) -> None:
        super().__init__()
        self.env, self.ceiling = env, float(ceiling)
        self.survived = self.judged = 0

    def state(self) -> dict[str, float]:
        """What a checkpoint saves of the curriculum."""
        return {"push_ceiling": self.ceiling}

    def _on_rollout_start(self) -> None:
        self.survived = self.judged = 0

    def _on_step(self) -> bool:
        for info in step_infos(self):
            verdict = info.get("push_survived")
            if verdict is not None:
                self.judged += 1
                self.survived += bool(verdict)
        return True

    def _on_rollout_end(self) -> None:
        survival = self.survived / self.judged if self.judged else None
        self.logger.record("curriculum/push_ceiling", self.ceiling)
        self.logger.record("curriculum/pushes", self.judged)
        if survival is not None:
            self.logger.record("curriculum/push_survival", survival)
        ceiling = next_ceiling(self.env, self.ceiling, survival)
        if ceiling != self.ceiling:
            self.training_env.unwrapped.set_push_ceiling(ceiling)
            self.ceiling = ceiling
