"""Compare QP solvers on the expert's own MPC problems (the measurement behind docs/mpc.md).

Run: python benchmarks/qp_solvers.py   (needs `pip install -e ".[bench]"`; prints JSON)

The expert walks 10 s on flat ground with the benchmark's command schedule; every MPC problem is
recorded; each solver then solves the same problems in the same process, and the median and 95th
percentile solve times (QP data already built) are reported with the largest force difference to DAQP.
"""

import json
import time

import numpy as np
import osqp
import proxsuite
import scipy.sparse

from krl.bench.mpc import COMMAND_SCHEDULE, _RecordingMPC
from krl.control.expert import MPCExpert
from krl.robots.a1.constants import NUM_LEGS
from krl.sim.model import build_model
from krl.sim.robot import A1Sim
from krl.util.timing import CONTROL_DT


def record(seconds=10.0):
    sim, expert = A1Sim(build_model("flat")), MPCExpert()
    expert.mpc = _RecordingMPC(expert.params.mpc)
    state = sim.reset()
    expert.reset(state)
    command = np.zeros(3)
    for k in range(round(seconds / CONTROL_DT)):
        goal = np.array(COMMAND_SCHEDULE[(k // 800) % len(COMMAND_SCHEDULE)])
        command += np.clip(goal - command, -0.002, 0.002)
        state = sim.step(*expert.act(state, command))
    return expert.mpc


def qp_data(mpc, problem):
    """The reduced QP exactly as ConvexMPC.solve builds it (swing feet eliminated)."""
    x0, reference, feet, rotation, contacts = problem
    p, h, nw = mpc.params, mpc.params.horizon, mpc._nw
    b = mpc.input_matrix(feet, rotation)
    blocks = np.concatenate((mpc._p_stack @ b, np.zeros((1, nw, 12))))
    b_qp = blocks[mpc._toeplitz].transpose(0, 2, 1, 3).reshape(h * nw, h * 12)
    keep_feet = contacts.reshape(h * NUM_LEGS)
    b_w = b_qp[:, np.repeat(keep_feet, 3)] * mpc._sqrt_w[:, None]
    error = mpc._a_qp @ x0 - reference[:, mpc._rows].reshape(-1) * mpc._sqrt_w
    hessian = b_w.T @ b_w + p.force_weight * np.eye(b_w.shape[1])
    n_feet = int(keep_feet.sum())
    n = 3 * n_feet
    a = mpc._pyramids[: 4 * n_feet, :n]
    return (
        hessian,
        b_w.T @ error,
        a,
        mpc._lower_bounds[:n],
        mpc._upper_bounds[:n],
        mpc._lower_general[: 4 * n_feet],
        mpc._upper_general[: 4 * n_feet],
    )


def solve_daqp(data):
    import daqp

    hessian, g, a, lb, ub, lg, ug = data
    x, *_ = daqp.solve(
        hessian,
        g,
        a,
        np.concatenate((ub, ug)),
        np.concatenate((lb, lg)),
        np.zeros(len(ub) + len(ug), dtype=np.int32),
    )
    return np.asarray(x)


def solve_proxsuite(data):
    hessian, g, a, lb, ub, lg, ug = data
    n = len(g)
    qp = proxsuite.proxqp.dense.QP(n, 0, len(lg), box_constraints=True)
    qp.settings.eps_abs = 1e-6
    qp.init(
        hessian,
        g,
        None,
        None,
        a,
        np.maximum(lg, -1e20),
        np.minimum(ug, 1e20),
        np.maximum(lb, -1e20),
        np.minimum(ub, 1e20),
    )
    qp.solve()
    return np.asarray(qp.results.x)


def solve_osqp(data):
    hessian, g, a, lb, ub, lg, ug = data
    n = len(g)
    big = scipy.sparse.vstack([scipy.sparse.eye(n), scipy.sparse.csc_matrix(a)]).tocsc()
    solver = osqp.OSQP()
    solver.setup(
        scipy.sparse.csc_matrix(np.triu(hessian)),
        g,
        big,
        np.concatenate((np.maximum(lb, -1e20), np.maximum(lg, -1e20))),
        np.concatenate((np.minimum(ub, 1e20), np.minimum(ug, 1e20))),
        verbose=False,
        eps_abs=1e-6,
        eps_rel=1e-6,
        polishing=False,
    )
    return np.asarray(solver.solve().x)


def main():
    mpc = record()
    rng = np.random.default_rng(0)
    picks = rng.choice(len(mpc.problems), size=300, replace=False)
    problems = [qp_data(mpc, mpc.problems[i]) for i in picks]
    reference = [solve_daqp(d) for d in problems]
    report = {}
    for name, solve in (("daqp", solve_daqp), ("proxsuite_dense", solve_proxsuite), ("osqp", solve_osqp)):
        times, errors = [], []
        for data, ref in zip(problems, reference, strict=True):
            t0 = time.perf_counter()
            x = solve(data)
            times.append(time.perf_counter() - t0)
            errors.append(float(np.max(np.abs(x - ref))))
        report[name] = {
            "median_ms": 1e3 * float(np.median(times)),
            "p95_ms": 1e3 * float(np.percentile(times, 95)),
            "max_force_difference_N": max(errors),
        }
    report["variables_median"] = float(np.median([len(d[1]) for d in problems]))
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
