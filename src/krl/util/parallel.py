"""One process pool for krl's long commands: :func:`run_jobs` runs picklable jobs on spawn-started workers.

Used by ``krl evaluate`` (:mod:`krl.eval.evaluate`) and the figure drivers of :mod:`krl.analysis`.

- **Deterministic.** Results come back in job order, and ``on_result`` receives each one with its job's
  index, so what a caller stores never depends on the number of workers or on which job finishes first
  (each job must carry its own seed).
- **No worker outlives the call.** Ctrl-C (SIGINT) or SIGTERM of the parent terminates the workers and
  raises :class:`Interrupted`, which names the jobs whose results were delivered; an error in a job
  terminates the workers and re-raises that error. If the parent dies without cleaning up (``kill -9``),
  each worker is sent SIGTERM by the kernel (Linux ``prctl(PR_SET_PDEATHSIG)``); elsewhere, or should that
  fail, a watchdog thread in the worker sees its parent change within :data:`PARENT_POLL` seconds and
  exits.
- **Spawn start.** Workers start a fresh interpreter (no forked copy of the parent's threads, MuJoCo or
  torch state); a job's function must be importable at module level.

``workers=1`` (or a single job) runs in this process, with the same signal handling.
"""

from __future__ import annotations

import ctypes
import multiprocessing
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from contextlib import contextmanager
from typing import Any, TypeVar

from krl.util.progress import progress_bar

__all__ = [
    "PARENT_POLL",
    "STOP_GRACE",
    "Interrupted",
    "die_with_parent",
    "raise_if_interrupted",
    "run_jobs",
    "signals_raise",
    "usable_cores",
    "worker_processes",
]

J = TypeVar("J")
R = TypeVar("R")

PARENT_POLL: float = 1.0
"""How often a worker's watchdog checks that its parent is alive [s]."""
STOP_GRACE: float = 3.0
"""How long terminated workers get to exit before they are killed [s]."""

_STOP_SIGNALS: tuple[signal.Signals, ...] = (signal.SIGINT, signal.SIGTERM)
_PR_SET_PDEATHSIG = 1
"""``PR_SET_PDEATHSIG`` of ``<linux/prctl.h>``."""


class Interrupted(KeyboardInterrupt):
    """SIGINT or SIGTERM stopped :func:`run_jobs`; its workers are gone.

    A ``KeyboardInterrupt``, so code that already handles Ctrl-C handles SIGTERM the same way.
    """

    def __init__(self, signum: int, finished: Sequence[int] = ()) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = int(signum)
        """The signal that stopped the run (``signal.SIGINT`` or ``signal.SIGTERM``)."""
        self.finished: tuple[int, ...] = tuple(sorted(finished))
        """Indices (into the ``jobs`` given) of the jobs whose results were delivered, ascending."""


def usable_cores() -> int:
    """The cores this process may run on (its CPU affinity where the system has one, else all)."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def worker_processes(asked: int, note: Callable[[str], None]) -> int:
    """How many worker processes to start when ``asked`` for: ``asked``, at most :func:`usable_cores` (each
    process holds ~75 MB, and one past the cores only waits for one), with ``note`` told so in one line
    where it caps. ValueError (one line) for fewer than one. The rule of every ``--workers`` and ``--jobs``
    option of ``krl`` (:func:`krl.cli.common.process_count`)."""
    if asked < 1:
        raise ValueError(f"a number of processes must be at least 1, got {asked}")
    cores = usable_cores()
    if asked > cores:
        note(f"{asked} processes asked for: capped at the {cores} usable cores")
        return cores
    return asked


def run_jobs(
    function: Callable[[J], R],
    jobs: Sequence[J],
    workers: int = 1,
    *,
    on_result: Callable[[int, R], None] | None = None,
    progress: str | None = None,
) -> list[R]:
    """``[function(job) for job in jobs]``, on up to ``workers`` processes.

    Args:
        function: a module-level function (pickled by name to the workers).
        jobs: picklable arguments, one call each; submitted in this order (put the longest first).
        workers: processes; ``1`` (or a single job) runs in this process.
        on_result: called in this process with ``(index, result)`` as each job finishes (in completion
            order); a job counts as delivered once this returns.
        progress: description of a transient progress bar on stderr (drawn only on a terminal); ``None``
            for no bar.

    Returns:
        The results in job order.

    Raises:
        Interrupted: SIGINT or SIGTERM arrived (the workers are stopped first).
        ValueError: ``workers < 1``.
        Exception: whatever a job raised (the other workers are stopped first).
    """
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    jobs = list(jobs)
    results: dict[int, R] = {}

    def deliver(index: int, result: R) -> None:
        if on_result is not None:
            on_result(index, result)
        results[index] = result
        bar.advance(task)

    with signals_raise(), progress_bar(progress is not None, transient=True) as bar:
        task = bar.add_task(progress or "", total=len(jobs))
        try:
            if workers == 1 or len(jobs) <= 1:
                for index, job in enumerate(jobs):
                    deliver(index, function(job))
                    raise_if_interrupted()
            else:
                _run_pool(function, jobs, min(workers, len(jobs)), deliver)
        except Interrupted as stop:
            raise Interrupted(stop.signum, list(results)) from None
        except KeyboardInterrupt:  # SIGINT before our handler was in place, or its handler was not ours
            raise Interrupted(signal.SIGINT, list(results)) from None
    return [results[index] for index in range(len(jobs))]


def _run_pool(
    function: Callable[[J], R], jobs: list[J], workers: int, deliver: Callable[[int, R], None]
) -> None:
    """Run every job on ``workers`` spawn-started processes; on any exception stop them, then re-raise."""
    before = set(multiprocessing.active_children())
    pool = ProcessPoolExecutor(
        workers,
        mp_context=multiprocessing.get_context("spawn"),
        initializer=die_with_parent,
        initargs=(os.getpid(),),
    )
    try:
        futures = {pool.submit(function, job): index for index, job in enumerate(jobs)}
        while futures:
            done, _ = wait(futures, return_when=FIRST_COMPLETED)
            for future in sorted(done, key=futures.__getitem__):
                deliver(futures.pop(future), future.result())
            raise_if_interrupted()
    except BaseException:
        with _signals_ignored():
            pool.shutdown(wait=False, cancel_futures=True)
            stop_processes([child for child in multiprocessing.active_children() if child not in before])
        raise
    pool.shutdown()


def stop_processes(processes: Sequence[Any], grace: float = STOP_GRACE) -> None:
    """SIGTERM each ``multiprocessing`` process, SIGKILL what is left after ``grace`` seconds; reap all."""
    for process in processes:
        process.terminate()
    deadline = time.monotonic() + grace
    for process in processes:
        process.join(max(0.0, deadline - time.monotonic()))
    for process in processes:
        if process.is_alive():
            process.kill()
            process.join()
    # A pool's manager thread reaps its workers too: one it reaped first looks alive here (our waitpid
    # finds no child) until that thread records the exit status, a moment later. Wait for it, bounded,
    # rather than join that thread, which could block with the stop signals ignored.
    deadline = time.monotonic() + STOP_GRACE
    while any(process.exitcode is None for process in processes) and time.monotonic() < deadline:
        time.sleep(0.01)


_received: list[int] = []
"""The stop signals that arrived inside the open :func:`signals_raise` scopes, oldest first (main thread)."""


def _raise_interrupted(signum: int, frame: object) -> None:
    _received.append(signum)  # kept, in case Python swallows the exception (raise_if_interrupted)
    raise Interrupted(signum)


def raise_if_interrupted() -> None:
    """Raise :class:`Interrupted` if a stop signal arrived inside an open :func:`signals_raise` scope.

    A handler's exception is raised in whatever Python code runs when the signal arrives; if that is a
    finaliser or a weakref callback (SQLAlchemy's, say, during a garbage collection), Python prints
    "Exception ignored in ..." and goes on, and the stop would be lost. Long loops call this once per step,
    so they stop at the next one; a scope that ends without an exception raises it at the latest."""
    if _received:
        raise Interrupted(_received[-1])


@contextmanager
def signals_raise(signums: Sequence[signal.Signals] = _STOP_SIGNALS) -> Iterator[None]:
    """Inside: ``signums`` (SIGINT and SIGTERM) raise :class:`Interrupted` (main thread only; an ignored
    signal stays ignored). The previous handlers come back on exit; a signal whose exception was
    swallowed (:func:`raise_if_interrupted`) raises :class:`Interrupted` there. Swallowed where Python
    reports it (``sys.unraisablehook``: "Exception ignored in ..." and a traceback on stderr), it is not
    reported: it is kept and raised later, so nothing was lost (:func:`_quiet_about_interrupted`)."""
    mark = len(_received)
    previous_hook = sys.unraisablehook
    sys.unraisablehook = _quiet_about_interrupted(previous_hook)
    try:
        with _handlers(_raise_interrupted, signums):
            yield
        swallowed = _received[mark:]
    finally:
        del _received[mark:]
        sys.unraisablehook = previous_hook
    if swallowed:
        raise Interrupted(swallowed[-1])


def _quiet_about_interrupted(previous: Callable[[Any], None]) -> Callable[[Any], None]:
    """A ``sys.unraisablehook`` that says nothing of an :class:`Interrupted` a finaliser swallowed (the
    handler kept its signal, which :func:`signals_raise` raises at a safe point) and passes anything else
    on to ``previous``."""

    def hook(unraisable: Any) -> None:
        if not isinstance(unraisable.exc_value, Interrupted):
            previous(unraisable)

    return hook


@contextmanager
def _signals_ignored() -> Iterator[None]:
    """Inside: SIGINT and SIGTERM are ignored, so a second Ctrl-C cannot cut the workers' clean-up short."""
    with _handlers(signal.SIG_IGN):
        yield


@contextmanager
def _handlers(handler: Any, signums: Sequence[signal.Signals] = _STOP_SIGNALS) -> Iterator[None]:
    if threading.current_thread() is not threading.main_thread():
        yield  # signal handlers can only be set from the main thread
        return
    previous = {}
    for signum in signums:
        if signal.getsignal(signum) is not signal.SIG_IGN:
            previous[signum] = signal.signal(signum, handler)
    try:
        yield
    finally:
        for signum, old in previous.items():
            signal.signal(signum, old)


def die_with_parent(parent: int) -> None:
    """Runs first in every worker: leave Ctrl-C to the parent, and die with the parent.

    Ctrl-C on a terminal reaches the whole process group; the parent stops the workers itself, so a
    worker ignores SIGINT (no traceback per worker).
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if sys.platform.startswith("linux"):
        try:
            ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, int(signal.SIGTERM))
        except (OSError, AttributeError):
            pass  # the watchdog below still covers it
    if os.getppid() != parent:  # the parent died before the prctl took effect
        os._exit(1)
    threading.Thread(target=_watch_parent, args=(parent,), name="krl-parent-watchdog", daemon=True).start()


def _watch_parent(parent: int) -> None:
    """Exit this worker as soon as its parent process is no longer ``parent`` (it died; init adopted us)."""
    while os.getppid() == parent:
        time.sleep(PARENT_POLL)
    os._exit(1)
