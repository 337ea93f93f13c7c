"""`krl.util.parallel.run_jobs`: results independent of the worker count, errors and signals stop every
worker.

The signal tests start a parent process running a pool of sleeping jobs, signal the parent, and read
``/proc`` to check that none of its children (the workers, the stdlib's resource tracker) survives.
"""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from krl.util.parallel import Interrupted, raise_if_interrupted, run_jobs, signals_raise

SPAWN_TIMEOUT = 30.0
"""How long the parent may take to start its workers on a loaded machine [s]."""
GONE_WITHIN = 15.0
"""How soon after the parent is signalled its children must be gone [s] (5 s was too short with two
trainings on both cores: the dying workers wait for CPU time; the check returns as soon as they are gone)."""


def _job(job: tuple[str, float, int]) -> int:
    """``("square", seconds, n)``: sleep, return n²; ``("fail", ...)``: raise; ``("term", ...)``: SIGTERM
    this process."""
    kind, seconds, value = job
    time.sleep(seconds)
    if kind == "fail":
        raise ValueError(f"job {value} failed")
    if kind == "term":
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(5.0)  # the handler raises at once; never reached
    return value * value


def test_results_are_in_job_order_whatever_the_worker_count():
    # the first job is the slowest, so with two workers it finishes after the others
    jobs = [("square", 0.6, 3), ("square", 0.0, 4), ("square", 0.1, 5), ("square", 0.0, 6)]
    seen = {1: [], 2: []}
    results = {
        workers: run_jobs(_job, jobs, workers, on_result=lambda i, r, w=workers: seen[w].append((i, r)))
        for workers in (1, 2)
    }
    assert results[1] == results[2] == [9, 16, 25, 36]
    assert seen[1] == [(0, 9), (1, 16), (2, 25), (3, 36)]  # in process: job order
    assert sorted(seen[2]) == seen[1]


def test_a_failing_job_raises_and_leaves_no_worker():
    import multiprocessing

    before = set(multiprocessing.active_children())  # other tests' children, if any
    with pytest.raises(ValueError, match="job 1 failed"):
        run_jobs(_job, [("square", 2.0, 0), ("fail", 0.0, 1), ("square", 2.0, 2)], workers=2)
    assert set(multiprocessing.active_children()) <= before


def test_sigterm_in_process_raises_interrupted_naming_the_finished_jobs():
    before = signal.getsignal(signal.SIGTERM)
    with pytest.raises(Interrupted) as caught:
        run_jobs(_job, [("square", 0.0, 2), ("term", 0.0, 0), ("square", 0.0, 3)], workers=1)
    assert caught.value.signum == signal.SIGTERM and caught.value.finished == (0,)
    assert isinstance(caught.value, KeyboardInterrupt)  # Ctrl-C handlers catch it too
    assert signal.getsignal(signal.SIGTERM) is before


class SignalledWhileCollected:
    """An object that SIGTERMs this process from its finaliser: the handler's exception is raised inside the
    finaliser, where Python swallows it ("Exception ignored in ...", ``sys.unraisablehook``)."""

    def __del__(self) -> None:
        os.kill(os.getpid(), signal.SIGTERM)


class FailsWhileCollected:
    """An object whose finaliser fails: Python reports it through ``sys.unraisablehook``."""

    def __del__(self) -> None:
        raise RuntimeError("a finaliser's own error")


def test_a_stop_signal_whose_exception_a_finaliser_swallowed_still_stops_and_says_nothing(monkeypatch):
    reported = []
    monkeypatch.setattr(sys, "unraisablehook", lambda unraisable: reported.append(unraisable.exc_type))
    went_on = False
    with pytest.raises(Interrupted) as caught:
        with signals_raise():
            SignalledWhileCollected()  # collected at once
            went_on = True  # as a training would: the stop was lost here
            FailsWhileCollected()  # any other error a finaliser swallows is reported as before
            raise_if_interrupted()
    # the swallowed stop is not reported ("Exception ignored in ..." and a traceback on stderr): it stops
    assert reported == [RuntimeError] and went_on and caught.value.signum == signal.SIGTERM
    FailsWhileCollected()  # outside the scope the hook is the one before it
    assert reported == [RuntimeError, RuntimeError]
    with pytest.raises(Interrupted):  # a scope that ends without looking raises it on exit
        with signals_raise():
            SignalledWhileCollected()
    raise_if_interrupted()  # the scopes are closed: nothing is pending


def test_bad_worker_count():
    with pytest.raises(ValueError, match="workers must be >= 1"):
        run_jobs(_job, [], workers=0)


# --- signals to a parent process ---------------------------------------------------------------------

# The parent restores Python's SIGINT handler first: started from a background shell job or nohup (as some
# CI runners do) it would inherit SIGINT ignored, which run_jobs rightly leaves ignored.
PARENT = """
import signal, sys, time
signal.signal(signal.SIGINT, signal.default_int_handler)
from krl.util.parallel import Interrupted, raise_if_interrupted, run_jobs, signals_raise
try:
    run_jobs(time.sleep, [60.0] * 4, workers=2)
except Interrupted as stop:
    print(f"stopped by {stop.signum}, finished {list(stop.finished)}", flush=True)
    sys.exit(128 + stop.signum)
"""


def _stat(pid: int) -> tuple[str, int] | None:
    """(state, parent pid) of a live process from ``/proc/PID/stat``; None when it is gone or a zombie."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None
    return None if fields[0] in ("Z", "X") else (fields[0], int(fields[1]))


def _children(parent: int) -> list[int]:
    """Live processes whose parent is ``parent``."""
    pids = [int(entry.name) for entry in Path("/proc").iterdir() if entry.name.isdigit()]
    return [pid for pid in pids if (stat := _stat(pid)) is not None and stat[1] == parent]


def _workers(parent: int) -> list[int]:
    """``parent``'s children that are spawn-started pool workers."""
    found = []
    for pid in _children(parent):
        try:
            if b"spawn_main" in Path(f"/proc/{pid}/cmdline").read_bytes():
                found.append(pid)
        except OSError:
            pass
    return found


def _start_parent(code: str, count: int, argv: list[str] = ()) -> tuple[subprocess.Popen, list[int]]:
    """Start ``python -c code *argv``; wait until it has ``count`` pool workers; return it and all its
    children."""
    parent = subprocess.Popen(
        [sys.executable, "-c", code, *argv], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    deadline = time.monotonic() + SPAWN_TIMEOUT
    while len(_workers(parent.pid)) < count:
        if parent.poll() is not None or time.monotonic() > deadline:
            parent.kill()
            out, err = parent.communicate()
            pytest.fail(f"the parent did not start {count} workers: rc {parent.returncode}\n{out}\n{err}")
        time.sleep(0.05)
    return parent, _children(parent.pid)


def _assert_gone(pids: list[int]) -> None:
    deadline = time.monotonic() + GONE_WITHIN
    while (alive := [pid for pid in pids if _stat(pid) is not None]) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert alive == [], f"still running {GONE_WITHIN:g} s after the parent was signalled: {alive}"


needs_proc = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc")


@needs_proc
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_a_signalled_parent_stops_its_workers_and_says_so(signum):
    parent, children = _start_parent(PARENT, count=2)
    parent.send_signal(signum)
    out, err = parent.communicate(timeout=GONE_WITHIN + 10)
    assert parent.returncode == 128 + signum, err
    assert out.strip() == f"stopped by {int(signum)}, finished []"
    _assert_gone(children)


@needs_proc
def test_workers_exit_when_their_parent_is_killed():
    parent, children = _start_parent(PARENT, count=2)
    parent.kill()  # SIGKILL: no clean-up in the parent
    parent.wait()
    _assert_gone(children)


SLOW_COURSE = """
format = 1
name = "slow"
time_limit = 300.0
d_min = 0.5
waypoints = [[40.0, 0.0]]
starts = [[0.0, 0.0, 0.0], [0.0, 0.2, 0.3]]

[terrain]
name = "flat"
"""


@needs_proc
def test_sigterm_stops_krl_evaluate_and_it_says_what_was_kept(tmp_path):
    """Issue 12: ``krl evaluate``'s workers outlived a SIGTERM of the parent and kept running."""
    course = tmp_path / "slow.toml"
    course.write_text(SLOW_COURSE)
    code = "import sys; from krl.cli import main; sys.exit(main())"
    argv = ["evaluate", "--controller", "kernel", "--course", str(course), "--workers", "2"]
    argv += ["--out", str(tmp_path / "out"), "--quiet"]
    parent, children = _start_parent(code, count=2, argv=argv)
    parent.terminate()
    _, err = parent.communicate(timeout=GONE_WITHIN + 10)
    assert parent.returncode == 143 and "interrupted after 0 of 2 runs" in err, err  # 128 + SIGTERM
    _assert_gone(children)
    assert list((tmp_path / "out").rglob("*.parquet")) == []
