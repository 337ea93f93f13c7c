"""``krl bench mpc``: cost of one MPC update and the expert's real-time factor.

The expert walks on flat ground (a forward, lateral and turning command, changing every few seconds)
for ``seconds`` of simulated time in this process, on one core. Reported:

* ``mpc_ms_median`` / ``mpc_ms_p95``: wall time of one MPC update (input matrix, condensed QP, solve);
* ``real_time_factor``: simulated seconds per wall second of the whole loop (expert + physics);
* ``baseline_ms_median`` and ``speedup``: the same recorded MPC problems solved the naive way, as a
  same-run reference: the QP rebuilt densely with the swing feet as equality constraints (120
  variables) and a fresh OSQP set-up per call (only when the optional ``osqp`` and ``scipy`` packages
  are installed: ``pip install krl[bench]``).
"""

from __future__ import annotations

import time

import numpy as np

from krl.control.expert import MPCExpert
from krl.control.mpc import ConvexMPC
from krl.sim.model import build_model
from krl.sim.robot import A1Sim
from krl.util.timing import CONTROL_DT

TARGET_MEDIAN_MS = 1.0
TARGET_REAL_TIME_FACTOR = 3.0

COMMAND_SCHEDULE: tuple[tuple[float, float, float], ...] = (
    (0.4, 0.0, 0.0),
    (0.3, 0.15, 0.3),
    (-0.3, 0.0, 0.0),
    (0.0, 0.25, -0.3),
    (0.5, 0.0, 0.4),
)
"""Velocity commands (vx, vy, wz) cycled every 4 s of the benchmark walk."""


class _RecordingMPC(ConvexMPC):
    """ConvexMPC that keeps its inputs, for replaying them through the baseline."""

    def __init__(self, params) -> None:
        super().__init__(params)
        self.problems: list[tuple] = []

    def solve(self, x0, reference, foot_rel_com, body_to_heading, contacts):
        self.problems.append(
            (x0.copy(), reference.copy(), foot_rel_com.copy(), body_to_heading.copy(), contacts)
        )
        return super().solve(x0, reference, foot_rel_com, body_to_heading, contacts)


def _naive_solve(mpc: ConvexMPC, problem: tuple) -> None:
    """Dense condensed QP with all 120 variables and a fresh OSQP set-up (the reference to beat)."""
    import osqp
    import scipy.linalg
    import scipy.sparse

    x0, reference, feet, rotation, contacts = problem
    p = mpc.params
    n, m, h = 13, 12, p.horizon
    a = np.zeros((n, n))
    a[0:3, 6:9] = np.eye(3)
    a[3:6, 9:12] = np.eye(3)
    a[11, 12] = 1.0
    b = mpc.input_matrix(feet, rotation)
    block = np.zeros((n + m, n + m))
    block[:n, :n], block[:n, n:] = a, b
    expm = scipy.linalg.expm(block * p.dt)
    a_d, b_d = expm[:n, :n], expm[:n, n:]
    a_qp = np.zeros((h * n, n))
    b_qp = np.zeros((h * n, h * m))
    power = np.eye(n)
    for k in range(h):
        power = a_d @ power
        a_qp[k * n : (k + 1) * n] = power
        for j in range(k + 1):
            b_qp[k * n : (k + 1) * n, j * m : (j + 1) * m] = np.linalg.matrix_power(a_d, k - j) @ b_d
    weights = np.diag(np.tile(p.weights, h))
    hessian = 2 * (b_qp.T @ weights @ b_qp + p.force_weight * np.eye(h * m))
    gradient = 2 * b_qp.T @ weights @ (a_qp @ x0 - reference.reshape(-1))
    rows, lower, upper = [], [], []
    mu = p.friction
    for k in range(h):
        for leg in range(4):
            base = k * m + 3 * leg
            for coefficients, low, high in (
                ((1, 0, -mu), -np.inf, 0),
                ((1, 0, mu), 0, np.inf),
                ((0, 1, -mu), -np.inf, 0),
                ((0, 1, mu), 0, np.inf),
            ):
                row = np.zeros(h * m)
                row[base : base + 3] = coefficients
                rows.append(row)
                lower.append(low)
                upper.append(high)
            row = np.zeros(h * m)
            row[base + 2] = 1.0
            rows.append(row)
            stance = contacts[k, leg]
            lower.append(p.min_normal_force if stance else 0.0)
            upper.append(p.max_normal_force if stance else 0.0)
    solver = osqp.OSQP()
    solver.setup(
        scipy.sparse.csc_matrix(np.triu(hessian)),
        gradient,
        scipy.sparse.csc_matrix(np.array(rows)),
        np.array(lower),
        np.array(upper),
        verbose=False,
    )
    solver.solve()


def bench_mpc(seconds: float = 20.0, baseline_samples: int = 200) -> dict[str, object]:
    """Walk the expert for ``seconds`` of simulated time; time its MPC and the whole loop."""
    if not seconds > 0:
        raise ValueError(f"seconds must be > 0, got {seconds}")
    sim = A1Sim(build_model("flat"))
    expert = MPCExpert()
    recording = _RecordingMPC(expert.params.mpc)
    expert.mpc = recording
    state = sim.reset()
    expert.reset(state)
    times = []
    steps = round(seconds / CONTROL_DT)
    period = round(4.0 / CONTROL_DT)
    command = np.zeros(3)
    start = time.perf_counter()
    for k in range(steps):
        goal = np.array(COMMAND_SCHEDULE[(k // period) % len(COMMAND_SCHEDULE)])
        command += np.clip(goal - command, -0.002, 0.002)  # smooth changes, like the command generator
        state = sim.step(*expert.act(state, command))
        times.append(expert.last.mpc_seconds)
        if state.fallen:
            raise RuntimeError(f"the expert fell at t={state.time:.2f} s during the benchmark walk")
    wall = time.perf_counter() - start
    ms = np.array(times) * 1e3
    result: dict[str, object] = {
        "benchmark": "mpc",
        "mpc_ms_median": float(np.median(ms)),
        "mpc_ms_p95": float(np.percentile(ms, 95)),
        "mpc_updates": len(ms),
        "real_time_factor": seconds / wall,
        "sim_seconds": seconds,
        "wall_seconds": wall,
        "target_mpc_ms_median": TARGET_MEDIAN_MS,
        "target_real_time_factor": TARGET_REAL_TIME_FACTOR,
        "meets_target": bool(np.median(ms) <= TARGET_MEDIAN_MS and seconds / wall >= TARGET_REAL_TIME_FACTOR),
    }
    try:
        import osqp  # noqa: F401
        import scipy  # noqa: F401
    except ImportError:
        result["baseline_ms_median"] = None
        return result
    rng = np.random.default_rng(0)
    picks = rng.choice(
        len(recording.problems), size=min(baseline_samples, len(recording.problems)), replace=False
    )
    baseline = []
    for index in picks:
        t0 = time.perf_counter()
        _naive_solve(recording, recording.problems[index])
        baseline.append(time.perf_counter() - t0)
    result["baseline_ms_median"] = float(np.median(baseline) * 1e3)
    result["speedup"] = result["baseline_ms_median"] / result["mpc_ms_median"]
    return result
