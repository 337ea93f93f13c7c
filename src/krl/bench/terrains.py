"""``krl bench terrains``: what each terrain costs to build and to simulate (docs/terrains.md, "Cost").

For each terrain, with its default parameters and seed 0:

* ``add_terrain_ms``: :func:`krl.sim.terrains.add_terrain` on a fresh spec that holds the robot, and
  ``compile_ms``: ``spec.compile()`` after it [ms], each the minimum over ``repeats`` builds;
* ``step_us``: one 1 ms physics step (``mj_step``) of the A1 standing at the terrain's spawn under
  constant controls that hold the standing pose [µs], the minimum over ``repeats`` timed loops of
  ``steps`` steps (the robot settles in the first loop and stands through the others);
* ``contacts``: the contacts at the end (a foot on a height field touches up to three prisms);
* ``step_vs_flat``: ``step_us`` over the flat ground's in the same run, which travels between machines
  where the absolute times do not.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import mujoco
import numpy as np

from krl.robots.a1 import MJCF_PATH
from krl.sim.batch import BarePhysics
from krl.sim.model import BuiltModel
from krl.sim.terrains import TERRAIN_NAMES, add_terrain

BASELINE = "flat"
"""The terrain every step cost is compared with."""


def _built(terrain: str) -> tuple[BuiltModel, float, float]:
    """The robot compiled on ``terrain`` (defaults, seed 0) and the seconds add_terrain and compile took."""
    spec = mujoco.MjSpec.from_file(str(MJCF_PATH))
    start = time.perf_counter()
    built_terrain = add_terrain(spec, terrain, None, np.random.default_rng(0))
    added = time.perf_counter()
    model = spec.compile()
    return BuiltModel(model=model, terrain=built_terrain), added - start, time.perf_counter() - added


def bench_one_terrain(terrain: str, steps: int, repeats: int) -> dict[str, float | int]:
    """One terrain's figures (module docstring) but ``step_vs_flat``."""
    built, add_s, compile_s = _built(terrain)
    add_times, compile_times = [add_s], [compile_s]
    for _ in range(repeats - 1):  # the other builds are timed only, their models dropped
        _, add_s, compile_s = _built(terrain)
        add_times.append(add_s)
        compile_times.append(compile_s)
    bare = BarePhysics(built)
    loops = [bare.seconds(steps, nstep=1) / steps for _ in range(repeats)]
    return {
        "add_terrain_ms": 1e3 * min(add_times),
        "compile_ms": 1e3 * min(compile_times),
        "step_us": 1e6 * min(loops),
        "contacts": bare.contacts,
    }


def bench_terrains(
    terrains: Sequence[str] = TERRAIN_NAMES, steps: int = 2000, repeats: int = 7
) -> dict[str, object]:
    """:func:`bench_one_terrain` on each of ``terrains`` (and on flat ground, the baseline); raises
    ValueError for a name that is not a terrain or fewer than one step or repeat."""
    if steps < 1 or repeats < 1:
        raise ValueError(f"bench terrains needs at least one step and one repeat, not {steps} and {repeats}")
    unknown = [name for name in terrains if name not in TERRAIN_NAMES]
    if unknown:
        raise ValueError(f"unknown terrain {unknown[0]!r}; known: {', '.join(TERRAIN_NAMES)}")
    names = [BASELINE, *(name for name in terrains if name != BASELINE)]
    figures = {name: bench_one_terrain(name, steps, repeats) for name in names}
    for row in figures.values():
        row["step_vs_flat"] = row["step_us"] / figures[BASELINE]["step_us"]
    return {
        "benchmark": "terrains",
        "baseline": BASELINE,
        "steps": steps,
        "repeats": repeats,
        "terrains": figures,
        "mujoco": mujoco.__version__,
    }
