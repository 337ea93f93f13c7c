"""`ProcessVecEnv` (`krl.agent.process_vec_env`): the environments of one process, over worker processes."""

import os
import signal

import numpy as np
import pytest

from krl.agent.config import AgentConfig, EnvConfig
from krl.agent.env import ResidualVecEnv
from krl.agent.process_vec_env import ProcessVecEnv, WorkerError, worker_cores


def test_workers_make_the_transitions_of_one_process():
    config = AgentConfig(env=EnvConfig(push_interval=(0.05, 0.1)))  # pushes within the test's steps
    workers, per_worker, seed = 2, 2, 5
    spread = ProcessVecEnv(config, workers, per_worker, seed)
    try:
        one = ResidualVecEnv(config, workers * per_worker, seed)
        np.testing.assert_array_equal(spread.reset(), one.reset())
        rng = np.random.default_rng(2)
        for _ in range(30):
            actions = rng.uniform(-1, 1, (workers * per_worker, 12))
            spread.step_async(actions)
            one.step_async(actions)
            for got, want in zip(spread.step_wait()[:3], one.step_wait()[:3], strict=True):
                np.testing.assert_array_equal(got, want)
    finally:
        spread.close()


def test_a_killed_worker_is_a_one_line_error():
    venv = ProcessVecEnv(AgentConfig(), 2, 1, seed=0)
    try:
        venv.reset()
        os.kill(venv._processes[1].pid, signal.SIGKILL)
        venv._processes[1].join(timeout=10)
        lost = r"^environment worker 1 exited unexpectedly \(killed by SIGKILL\)$"
        with pytest.raises(WorkerError, match=lost):
            venv.step_async(np.zeros((2, 12)))
            venv.step_wait()
    finally:
        venv.close()


def test_workers_run_as_batch_processes_one_per_core():
    cores = sorted(os.sched_getaffinity(0))
    assert worker_cores(len(cores)) == cores
    assert worker_cores(len(cores) + 1) == [*cores, cores[0]]
    assert worker_cores(len(cores) - 1) is None  # fewer workers than cores: the OS places them
    venv = ProcessVecEnv(AgentConfig(), len(cores), 1, seed=0)
    try:
        venv.reset()  # the workers are up and have placed themselves
        for process, core in zip(venv._processes, cores, strict=True):
            assert os.sched_getscheduler(process.pid) == os.SCHED_BATCH
            assert os.sched_getaffinity(process.pid) == {core}
    finally:
        venv.close()
