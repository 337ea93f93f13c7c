"""A hand-written rule in the policy's place: what driving the gait can do after a push, before any training.

:class:`ScriptedGait` drives kernel-ext through the gait-driving action path (:mod:`krl.agent.action`, no
residuals) by a rule of the trunk's measured velocity: while the velocity in the base frame differs from
the command by more than ``threshold`` [m/s] (the robot is being carried), for at most ``hold`` [s]
(then it rests at nominal until the difference falls below ``threshold``: steering towards the
velocity would otherwise feed itself), it steers the kernel's command
by ``capture`` times that difference (the capture step of a Raibert-style foot placement: step where the
trunk is going), runs the gait clock at ``rate``, and sets the ride and step heights to ``ride`` and
``step`` [m]; otherwise everything is nominal (the task's command, the kernel's heights, rate 1). Each
value is bounded as the policy's would be (the kernel's command ranges, kernel-ext's height ranges,
``rhythm_range``) and passes the drive filter (``alpha``).

It is a measurement instrument (``krl agent push --controller gait:capture=1,rate=2,ride=0.18,alpha=1``,
``krl evaluate --controller gait:... --push-sweep``), not a controller krl recommends: it shows which
drives can keep the robot up through a push the residual agent falls to, and so which the gait-driving
agent is given (docs/agent-gait.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from krl.agent.config import ResidualConfig
from krl.agent.residual import ResidualController
from krl.control.types import JointCommand
from krl.kernel.registry import load_model
from krl.sim.state import RobotState, StateBatch


@dataclass(frozen=True)
class GaitRule:
    """The rule's settings; None leaves a drive at its nominal value."""

    capture: float = 0.0
    """Steering gain: the kernel's command is the task's plus ``capture`` × (velocity − command) [1]."""
    rate: float | None = None
    """Gait clock rate while carried (multiples of the kernel's own)."""
    ride: float | None = None
    """Ride height while carried [m]."""
    step: float | None = None
    """Step height while carried [m]."""
    threshold: float = 0.3
    """Carried: the horizontal velocity differs from the command by more than this [m/s]."""
    hold: float = 1.0
    """The longest the rule acts after the robot is first carried [s]."""
    alpha: float = 0.05
    """The drive filter's α (``ResidualConfig.gait_alpha``): 1 applies each value at once."""

    def __post_init__(self) -> None:
        if not (np.isfinite(self.capture) and self.capture >= 0):
            raise ValueError(f"capture must be a number >= 0, got {self.capture}")
        if not (np.isfinite(self.threshold) and self.threshold >= 0):
            raise ValueError(f"threshold must be a number >= 0 m/s, got {self.threshold}")
        if not (np.isfinite(self.hold) and self.hold > 0):
            raise ValueError(f"hold must be a number > 0 s, got {self.hold}")


class ScriptedGait:
    """A :class:`krl.control.types.Controller`: kernel-ext driven by a :class:`GaitRule` (module doc)."""

    def __init__(self, rule: GaitRule) -> None:
        self.rule = rule
        config = ResidualConfig(
            kernel="ext",
            residuals=False,
            drive_steer=True,
            drive_heights=True,
            drive_rhythm=True,
            gait_alpha=rule.alpha,
        )
        self.residual = ResidualController(load_model("ext"), config, 1)
        self.parts = {part.name: part for part in self.residual.parts}
        for name, part, index, value in (
            ("clock_rate", "clock_rate", 0, rule.rate),
            ("step height", "heights", 0, rule.step),
            ("ride height", "heights", 1, rule.ride),
        ):
            low, high = self.parts[part].low[index], self.parts[part].high[index]
            if value is not None and not low <= value <= high:
                raise ValueError(f"{name} value {value} lies outside the drive's range [{low}, {high}]")

        self._since: float | None = None
        """When the robot was first carried [s]; None while the rule is not acting."""
        self._resting = False

    def reset(self, state: RobotState) -> None:
        self.residual.reset()
        self._since, self._resting = None, False

    def _carried(self, time: float, error: float) -> bool:
        """Whether the rule acts at ``time`` [s], given the velocity error [m/s] (the ``hold`` latch)."""
        if error <= self.rule.threshold:
            self._since, self._resting = None, False
        elif self._since is None and not self._resting:
            self._since = time
        elif self._since is not None and time - self._since > self.rule.hold:
            self._since, self._resting = None, True
        return self._since is not None

    def act(self, state: RobotState, command: np.ndarray) -> JointCommand:
        command = np.asarray(command, dtype=float)
        rule, parts = self.rule, self.parts
        error = state.lin_vel_base[:2] - command[:2]
        carried = self._carried(state.time, float(np.linalg.norm(error)))
        offset = np.zeros(3)
        if carried:
            offset[:2] = rule.capture * error
        step, ride = parts["heights"].nominal
        if carried:
            step = rule.step if rule.step is not None else step
            ride = rule.ride if rule.ride is not None else ride
        rate = rule.rate if carried and rule.rate is not None else 1.0
        action = np.concatenate(
            [
                parts["steer"].action(offset[None]),
                parts["heights"].action(np.array([[step, ride]])),
                parts["clock_rate"].action(np.array([[rate]])),
            ],
            axis=1,
        )
        self.residual.prepare(StateBatch.from_states([state]), command[None])
        return JointCommand(self.residual.joint_targets(action)[0])
