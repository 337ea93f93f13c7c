"""The observation features measured in the scene (:data:`krl.agent.observation.SENSED`), for N robots.

:class:`Sensing` reads what the state does not hold from the simulators (a
:class:`krl.sim.backend.SimBackend`): the height scan (:mod:`krl.sim.scan`, through its ``terrain_heights``),
the ground's friction and the push acting now; and, from the training environment, each robot's terrain
level. Only the features a configuration observes are measured, so an agent without them costs nothing
more.
"""

from __future__ import annotations

import numpy as np

from krl.agent.config import ObservationConfig
from krl.agent.observation import SENSED
from krl.robots.a1.constants import FOOT_FRICTION
from krl.sim.backend import SimBackend
from krl.sim.state import StateBatch


class Sensing:
    """Measures the sensed features of ``observation`` (actor's and critic's) for N robots.

    Args:
        observation: the observation's configuration (its features and the scan's grid).
        noise_rng: the generator of the scan's training noise; None: no noise (evaluation).
    """

    def __init__(self, observation: ObservationConfig, noise_rng: np.random.Generator | None = None) -> None:
        self.names: tuple[str, ...] = tuple(n for n in observation.all_features if n in SENSED)
        self.scan = observation.scan
        self.points = np.array(self.scan.points())
        """The scan's heading-frame points [m]. Shape: (P, 2)."""
        self.noise_rng = noise_rng

    @property
    def needed(self) -> bool:
        """Whether the observation has a sensed feature at all."""
        return bool(self.names)

    def measure(
        self, sims: SimBackend, states: StateBatch, terrain_levels: np.ndarray | None = None
    ) -> dict[str, np.ndarray]:
        """Every sensed feature of the observation for the N robots of ``sims`` in ``states``, by name;
        shapes (N, size). ``terrain_levels``: each robot's curriculum level as a share of the top (N,)."""
        values: dict[str, np.ndarray] = {}
        n = len(sims)
        if "height_scan" in self.names or "height_scan_clean" in self.names:
            clean = self.scan_values(sims.terrain_heights(self.points), states)
            values["height_scan_clean"] = clean
            noisy = clean
            if self.noise_rng is not None and self.scan.noise > 0:
                noisy = clean + self.noise_rng.uniform(-self.scan.noise, self.scan.noise, clean.shape)
            values["height_scan"] = noisy
        if "ground_friction" in self.names:
            values["ground_friction"] = np.array(
                [[sims.terrain(i).params.get("friction", FOOT_FRICTION)] for i in range(n)], dtype=float
            )
        if "push_force" in self.names:
            values["push_force"] = push_forces(sims, states)
        if "terrain_level" in self.names:
            levels = np.zeros(n) if terrain_levels is None else np.asarray(terrain_levels, dtype=float)
            values["terrain_level"] = levels[:, None]
        return {name: values[name] for name in self.names}

    def scan_values(self, heights: np.ndarray, states: StateBatch) -> np.ndarray:
        """The scan's values from the terrain heights under its points (N, P) [m]: trunk height above them
        less the offset, clipped [m]. Shape: (N, P)."""
        relative = states.base_pos[:, 2:3] - heights - self.scan.offset
        return np.clip(relative, -self.scan.clip, self.scan.clip)


def push_forces(sims: SimBackend, states: StateBatch) -> np.ndarray:
    """The push acting on each robot's trunk at its current step, in its base frame [N]; 0 where none.
    Shape: (N, 3)."""
    n = len(sims)
    forces = np.zeros((n, 3))
    steps = sims.step_counts
    for index in range(n):
        push = sims.pending_push(index)
        if push is not None and push.active_at(int(steps[index])):
            forces[index] = states.base_rot[index].T @ push.force
    return forces
