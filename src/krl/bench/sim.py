"""``krl bench sim``: cost of krl's control step against bare MuJoCo stepping of the same model.

Baseline (raw): ``mj_step(model, data, nstep=5)`` with constant controls holding the standing pose.
Measured (env): :meth:`krl.sim.robot.A1Sim.step` with the standing targets: PD commands written, motor
envelope updated, 5 physics steps, kinematics refresh, state readout and fall check. Both start from
the same reset state, alternate ``repeats`` times, and the median rate of each is reported; the ratio
env/raw is what the target (>= 0.6) is about, because absolute rates vary from machine to machine.
"""

from __future__ import annotations

import statistics
import time

import mujoco

from krl.robots.a1.constants import STANDING_JOINT_ANGLES
from krl.sim.batch import BarePhysics
from krl.sim.model import BuiltModel, build_model
from krl.sim.robot import A1Sim

TARGET_RATIO = 0.6
"""Required env/raw throughput ratio (issue #2)."""


def _rate(step, steps: int) -> float:
    start = time.perf_counter()
    for _ in range(steps):
        step()
    return steps / (time.perf_counter() - start)


def bare_seconds(built: BuiltModel, steps: int) -> float:
    """Seconds ``steps`` bare control steps (``mj_step(nstep=5)``, constant controls holding the standing
    pose) of the robot on ``built`` take, from its standing reset state: the floor a benchmark's rate is
    set against (:class:`krl.sim.batch.BarePhysics`)."""
    return BarePhysics(built).seconds(steps)


def bench_terrain(terrain: str, steps: int, repeats: int, seed: int = 0) -> dict[str, float]:
    """Median control steps per second, raw and env, on one terrain."""
    built = build_model(terrain, seed=seed)
    sim, bare = A1Sim(built), BarePhysics(built)
    targets = STANDING_JOINT_ANGLES.copy()
    raw_rates, env_rates = [], []
    for _ in range(repeats):
        sim.reset()
        bare.reset()
        raw_rates.append(steps / bare.seconds(steps))
        env_rates.append(_rate(lambda: sim.step(targets), steps))
    raw = statistics.median(raw_rates)
    env = statistics.median(env_rates)
    return {"raw_steps_per_s": raw, "env_steps_per_s": env, "ratio": env / raw}


def bench_sim(
    terrains: tuple[str, ...] = ("flat", "heightfield"), steps: int = 1000, repeats: int = 7
) -> dict[str, object]:
    """Run :func:`bench_terrain` on each terrain. The top-level figures are the worst terrain's."""
    per_terrain = {name: bench_terrain(name, steps, repeats) for name in terrains}
    worst = min(per_terrain, key=lambda name: per_terrain[name]["ratio"])
    return {
        "benchmark": "sim",
        **per_terrain[worst],
        "worst_terrain": worst,
        "target_ratio": TARGET_RATIO,
        "meets_target": per_terrain[worst]["ratio"] >= TARGET_RATIO,
        "steps": steps,
        "repeats": repeats,
        "terrains": per_terrain,
        "mujoco": mujoco.__version__,
    }
