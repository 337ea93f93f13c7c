"""Residual environments on several worker processes, as one Stable-Baselines3 ``VecEnv``.

Each worker process (spawn-started, one per core) steps a :class:`krl.agent.env.ResidualVecEnv` of
``num_envs`` robots; the parent sends every worker its slice of the actions and gathers the results, so
the workers' physics runs in parallel while the parent waits. Worker ``k``'s environments are seeded
``seed + k * num_envs + i``: the same environments, in the same order, as one ``ResidualVecEnv`` of
``workers * num_envs`` robots seeded ``seed``. Workers limit their BLAS to one thread (the batch's small
matrix products are slower when threads fight over the cores) and die with the parent
(:mod:`krl.util.parallel`).

Where the scheduler puts the workers matters (``benchmarks/README.md``, "Where the workers run"). Each
worker runs as ``SCHED_BATCH``, so waking it with its actions does not preempt the parent, which still
has the other workers' actions to send; and when there are at least as many workers as usable cores,
worker ``k`` is pinned to the ``k``-th core (round robin), so that workers stay on their cores instead of
taking the parent's. With fewer workers than cores the operating system places them. Neither changes
what the workers compute, only where and when they run.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
from typing import Any

import numpy as np

from krl.agent.config import AgentConfig
from krl.agent.vec_env import BatchVecEnv


def worker_cores(workers: int) -> list[int] | None:
    """The core each of ``workers`` worker processes is pinned to, or None (the operating system places
    them): pinned when they are at least as many as the cores this process may use, round robin."""
    if not hasattr(os, "sched_getaffinity"):
        return None
    cores = sorted(os.sched_getaffinity(0))
    if workers < len(cores):
        return None
    return [cores[k % len(cores)] for k in range(workers)]


def _schedule_worker(core: int | None) -> None:
    """Run this process as ``SCHED_BATCH``, on ``core`` if given (Linux; elsewhere, or where the system
    refuses either, it runs as it is: placement changes the speed, not the results)."""
    if hasattr(os, "SCHED_BATCH"):
        with contextlib.suppress(OSError):
            os.sched_setscheduler(0, os.SCHED_BATCH, os.sched_param(0))
    if core is not None:
        with contextlib.suppress(OSError):
            os.sched_setaffinity(0, {core})


def _worker(
    connection,
    parent: int,
    config_json: dict,
    num_envs: int,
    seed: int,
    kernel_path: str | None,
    core: int | None,
    rowwise: bool,
):
    from krl.util.parallel import die_with_parent

    die_with_parent(parent)
    _schedule_worker(core)
    from threadpoolctl import threadpool_limits

    limits = threadpool_limits(1)  # held for the worker's life
    from krl.agent.env import ResidualVecEnv

    env = ResidualVecEnv(AgentConfig.from_json(config_json), num_envs, seed, kernel_path, rowwise)
    try:
        while True:
            command, payload = connection.recv()
            if command == "step":
                env.step_async(payload)
                connection.send(env.step_wait())
            elif command == "reset":
                connection.send(env.reset())
            elif command == "seed":
                connection.send(env.seed(payload))
            elif command == "push_ceiling":
                connection.send(env.set_push_ceiling(payload))
            elif command == "terrain_levels":
                connection.send(env.terrain_levels())
            elif command == "set_terrain_levels":
                connection.send(env.set_terrain_levels(payload))
            elif command == "close":
                break
    except (EOFError, KeyboardInterrupt):
        pass
    except Exception as error:  # the parent re-raises it with the worker's message
        connection.send(("error", f"{type(error).__name__}: {error}"))
    finally:
        limits.restore_original_limits()
        connection.close()


class WorkerError(RuntimeError):
    """An environment worker failed; the message is the worker's error."""


class ProcessVecEnv(BatchVecEnv):
    """``workers`` processes of ``num_envs`` residual environments each.

    Args:
        config: the agent's configuration.
        workers: worker processes.
        num_envs: environments per worker.
        seed: seed of environment 0.
        kernel_path: the kernel file (default: the config's).
        rowwise: each environment's kernel run on its row alone (:class:`krl.agent.env.ResidualEnvBatch`),
            so its transitions do not depend on ``workers`` or ``num_envs``.
    """

    def __init__(
        self,
        config: AgentConfig,
        workers: int,
        num_envs: int,
        seed: int = 0,
        kernel_path: str | None = None,
        rowwise: bool = False,
    ) -> None:
        from krl.agent.env import ResidualVecEnv

        probe = ResidualVecEnv(config, 1, seed, kernel_path)
        super().__init__(workers * num_envs, probe.observation_space, probe.action_space)
        self.per_worker = num_envs
        context = multiprocessing.get_context("spawn")
        self._connections = []
        self._processes = []
        cores = worker_cores(workers)
        for worker in range(workers):
            parent_end, child_end = context.Pipe()
            process = context.Process(
                target=_worker,
                args=(
                    child_end,
                    os.getpid(),
                    config.to_json(),
                    num_envs,
                    seed + worker * num_envs,
                    kernel_path,
                    None if cores is None else cores[worker],
                    rowwise,
                ),
                daemon=True,
            )
            process.start()
            child_end.close()
            self._connections.append(parent_end)
            self._processes.append(process)
        self._closed = False

    def _lost(self, worker: int) -> WorkerError:
        process = self._processes[worker]
        process.join(timeout=1.0)
        code = process.exitcode
        if code is None:
            return WorkerError(f"environment worker {worker} stopped answering (its process still runs)")
        how = f"exit code {code}"
        if code < 0:
            try:
                how = f"killed by {signal.Signals(-code).name}"
            except ValueError:
                how = f"killed by signal {-code}"
        return WorkerError(f"environment worker {worker} exited unexpectedly ({how})")

    def _send(self, worker: int, message: tuple[str, Any]) -> None:
        try:
            self._connections[worker].send(message)
        except OSError:  # BrokenPipeError, ConnectionResetError: the worker is gone
            raise self._lost(worker) from None

    def _gather(self) -> list[Any]:
        results = []
        for worker, connection in enumerate(self._connections):
            try:
                result = connection.recv()
            except (EOFError, OSError):
                raise self._lost(worker) from None
            if isinstance(result, tuple) and len(result) == 2 and result[0] == "error":
                raise WorkerError(f"environment worker {worker} failed: {result[1]}")
            results.append(result)
        return results

    def reset(self) -> np.ndarray:
        for worker in range(len(self._connections)):
            self._send(worker, ("reset", None))
        return np.concatenate(self._gather())

    def step_async(self, actions: np.ndarray) -> None:
        actions = np.asarray(actions)
        for k in range(len(self._connections)):
            self._send(k, ("step", actions[k * self.per_worker : (k + 1) * self.per_worker]))

    def step_wait(self):
        results = self._gather()
        observations = np.concatenate([r[0] for r in results])
        rewards = np.concatenate([r[1] for r in results])
        dones = np.concatenate([r[2] for r in results])
        infos = [info for r in results for info in r[3]]
        return observations, rewards, dones, infos

    def set_push_ceiling(self, newtons: float) -> None:
        """Every worker's pushes from now on up to ``newtons`` [N] (a push curriculum's ceiling)."""
        for k in range(len(self._connections)):
            self._send(k, ("push_ceiling", float(newtons)))
        self._gather()

    def terrain_levels(self) -> np.ndarray:
        """Every environment's terrain curriculum level, worker by worker. Shape: (workers * num_envs,)."""
        for k in range(len(self._connections)):
            self._send(k, ("terrain_levels", None))
        return np.concatenate(self._gather())

    def set_terrain_levels(self, levels) -> None:
        """Put every environment on its level of ``levels`` (shape (workers * num_envs,))."""
        levels = np.asarray(levels, dtype=np.int64)
        if levels.shape != (self.num_envs,):
            raise ValueError(f"terrain levels must have shape ({self.num_envs},), got {levels.shape}")
        for k in range(len(self._connections)):
            self._send(k, ("set_terrain_levels", levels[k * self.per_worker : (k + 1) * self.per_worker]))
        self._gather()

    def seed(self, seed: int | None = None):
        base = 0 if seed is None else seed
        for k in range(len(self._connections)):
            self._send(k, ("seed", base + k * self.per_worker))
        return [s for seeds in self._gather() for s in seeds]

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        for connection in self._connections:
            try:
                connection.send(("close", None))
            except (BrokenPipeError, OSError):
                pass
        for process in self._processes:
            process.join(timeout=5)
            if process.is_alive():
                process.terminate()
                process.join(timeout=2)
