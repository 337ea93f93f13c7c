"""``krl bench evaluate``: ``krl evaluate``'s throughput against bare MuJoCo on the same terrains.

Measured in one run:

* ``eval_steps_per_s``: control steps per second of :func:`krl.eval.evaluate.execute` in one process (one
  core, ``workers=1``) walking ``controller`` on ``courses`` with ``seeds``: controller, simulation,
  scoring and the records written, everything a run costs but the process start.
* ``bare_steps_per_s``: ``mj_step(nstep=5)`` (one 200 Hz control step) of each course's model with
  constant controls holding the standing pose, for as many control steps as the evaluation walked on that
  course: the floor of the same physics on one core.
* ``eval_ratio`` = eval / bare (target >= :data:`TARGET_RATIO`).
* ``network_us_per_step``: the controller's networks for one robot's control step as batched evaluation
  runs them, row by row (:mod:`krl.util.affine`: the kernel's forward pass, and an agent's policy), on one
  core; 0 for a controller without a batched form (the expert).
* ``ratio_ceiling`` = bare step / (bare step + networks): the ratio evaluation would reach if everything
  else in a step (IK, readout, task, reward, scoring) cost nothing; what the target can be at most with
  records that do not depend on the batch.
* ``push_sweep_seconds``: wall time of a push sweep of ``push_attempts`` attempts per force (every
  force of the default sweep; none with 0) on every core: what a sweep costs on this machine, to compare
  engines side by side in one session.
"""

from __future__ import annotations

import os
import statistics
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import mujoco
from threadpoolctl import threadpool_limits

from krl.bench.sim import bare_seconds

TARGET_RATIO = 0.6
"""Required evaluation/bare ratio per core (issue 46)."""


def _evaluation(spec, courses, seeds, folder: Path) -> tuple[float, dict[str, int]]:
    """Wall seconds of one ``execute`` of every course run in one process, and its steps per course."""
    from krl.eval.evaluate import course_runs, execute

    runs = course_runs(spec, courses, seeds)
    start = time.perf_counter()
    records = execute(runs, folder, workers=1)
    seconds = time.perf_counter() - start
    steps: dict[str, int] = {}
    for run, record in zip(runs, records, strict=True):
        steps[run.course.name] = steps.get(run.course.name, 0) + record["metrics"]["steps"]
    return seconds, steps


def _network_seconds(spec, seed: int, repeats: int = 2000) -> float:
    """Seconds of one robot-step of ``spec``'s networks, row by row (module docstring); best of three."""
    import numpy as np

    if not spec.batched:
        return 0.0
    controller = spec.build_batch(seed, 2)
    kernel = controller.residual.kernel
    policy = getattr(controller, "policy", None)
    features = np.zeros((2, kernel.input_size))
    observation = None if policy is None else np.zeros((2, policy.observation_size))

    def one_step() -> None:
        kernel.predict(features, rowwise=True)
        if policy is not None:
            policy.act(observation, rowwise=True)

    best = min(_timed(one_step, repeats) for _ in range(3))
    return best / 2  # two robots per call


def _timed(function, repeats: int) -> float:
    start = time.perf_counter()
    for _ in range(repeats):
        function()
    return (time.perf_counter() - start) / repeats


def bench_evaluate(
    controller: str = "agent",
    courses: Sequence[str] = ("flat", "stairs"),
    seeds: Sequence[int] = (150,),
    repeats: int = 1,
    push_attempts: int = 2,
) -> dict:
    """Run the measurements (module docstring); medians over ``repeats`` alternating loops of the
    evaluation and its bare counterpart."""
    from krl.eval.controllers import parse_controller
    from krl.eval.courses import courses_named
    from krl.eval.episodes import PushSweep
    from krl.eval.evaluate import execute, push_runs

    spec = parse_controller(controller)
    loaded = courses_named(list(courses))
    models = {course.name: course.build() for course in loaded}
    eval_rates, bare_rates, walked = [], [], {}
    with threadpool_limits(1), tempfile.TemporaryDirectory() as folder:
        for repeat in range(repeats):
            seconds, walked = _evaluation(spec, loaded, list(seeds), Path(folder) / f"courses{repeat}")
            total = sum(walked.values())
            eval_rates.append(total / seconds)
            bare = sum(bare_seconds(models[name], steps) for name, steps in walked.items())
            bare_rates.append(total / bare)
        cores = os.cpu_count() or 1
        runs = push_runs(spec, PushSweep(attempts=push_attempts), list(seeds)) if push_attempts else []
        start = time.perf_counter()
        pushes = execute(runs, Path(folder) / "push", workers=cores)
        sweep_seconds = time.perf_counter() - start
        network = _network_seconds(spec, seeds[0])
    eval_rate, bare_rate = statistics.median(eval_rates), statistics.median(bare_rates)
    ceiling = (1 / bare_rate) / (1 / bare_rate + network)
    return {
        "benchmark": "evaluate",
        "controller": spec.label,
        "courses": [course.name for course in loaded],
        "seeds": list(seeds),
        "control_steps": walked,
        "eval_steps_per_s": round(eval_rate, 1),
        "bare_steps_per_s": round(bare_rate, 1),
        "eval_ratio": round(eval_rate / bare_rate, 3),
        "target_ratio": TARGET_RATIO,
        "meets_target": eval_rate / bare_rate >= TARGET_RATIO,
        "network_us_per_step": round(network * 1e6, 1),
        "ratio_ceiling": round(ceiling, 3),
        "cores": cores,
        "push_runs": len(runs),
        "push_control_steps": sum(record["metrics"]["steps"] for record in pushes),
        "push_sweep_seconds": round(sweep_seconds, 2) if runs else None,
        "repeats": repeats,
        "mujoco": mujoco.__version__,
    }
