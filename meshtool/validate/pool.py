"""Where checks run locally: in this process, or in worker processes that are killed at the per-asset timeout.

One stuck asset must not block a run of hundreds: every check has a deadline (``timeout`` seconds, see
:data:`meshtool.validate.config.DEFAULT_TIMEOUT`). A check past it gives an X002 finding and the run goes on.

- In worker processes (``jobs`` > 1) each worker takes one asset at a time; a worker past the deadline is
  killed (whatever it is stuck in: a loop, native code, a blocking read) and replaced. A worker that dies on
  its own (a native crash) gives an X001 finding for its asset. Workers are started with ``spawn`` (MuJoCo
  and GL contexts are not fork-safe) and die with this process: the kernel kills them when it goes
  (``PR_SET_PDEATHSIG`` on Linux) and a watchdog thread ends them when their parent changes (other
  systems, or a parent gone before the signal was armed).
- In this process (``jobs`` == 1) the deadline is a ``SIGALRM`` timer, which interrupts Python code and
  blocking system calls but not a single long native call; it needs the main thread (elsewhere checks run
  without a deadline). Use two or more workers for a hard limit.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator
from multiprocessing.connection import Connection, wait
from typing import Any

from meshtool.lifeline import die_with_parent
from meshtool.validate.plugins import physics_plugin
from meshtool.validate.rules import hit
from meshtool.validate.task import AssetResult, AssetTask, ReadAsset, check_asset, judge_asset, read_asset

Check = Callable[[AssetTask], AssetResult]
#: What a worker sends once it has started and imported what checks need.
READY = "ready"


def timed_out(task: AssetTask, timeout: float) -> AssetResult:
    """The result of a check stopped at its deadline: an X002 finding, nothing else checked."""
    message = f"the check did not finish within {timeout:g} s and was stopped; the asset was not checked"
    result = AssetResult(task.display, task.kind, [hit("X002", message, task.path.name)])
    result.notes.append(f"stopped after {timeout:g} s (timeout)")
    return result


def died(task: AssetTask, exitcode: int | None) -> AssetResult:
    """The result of a check whose worker process died (a native crash): an X001 finding."""
    how = f"signal {-exitcode}" if exitcode is not None and exitcode < 0 else f"exit code {exitcode}"
    message = f"the worker process checking it died ({how}); the asset was not checked"
    return AssetResult(task.display, task.kind, [hit("X001", message, task.path.name)])


def _worker(conn: Connection, parent_pid: int, check: Check) -> None:
    """A worker's life: take a task, send its result, until told to stop (``None``) or the pipe closes."""
    die_with_parent(parent_pid)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle; it stops the workers
    with contextlib.suppress(Exception):  # a broken plugin is reported by the check itself
        physics_plugin()  # imported before the first deadline starts: loading MuJoCo is not the asset's time
    conn.send(READY)
    while True:
        try:
            task = conn.recv()
        except (EOFError, OSError):
            return
        if task is None:
            return
        conn.send(check(task))


class _Worker:
    def __init__(self, context: Any, check: Check) -> None:
        self.conn, child = context.Pipe()
        self.process = context.Process(target=_worker, args=(child, os.getpid(), check), daemon=True)
        self.process.start()
        child.close()
        self.ready = False
        self.task: AssetTask | None = None
        self.started = 0.0

    def give(self, task: AssetTask) -> None:
        """Hand over a task; it is sent (and its deadline starts) once the worker is ready."""
        self.task = task
        if self.ready:
            self.started = time.monotonic()
            self.conn.send(task)

    def became_ready(self) -> None:
        self.ready = True
        if self.task is not None:
            self.give(self.task)

    def stop(self, kill: bool) -> None:
        if not kill:
            with contextlib.suppress(OSError, ValueError):
                self.conn.send(None)
            self.process.join(5)
        if self.process.is_alive():
            self.process.kill()
        self.process.join()
        self.conn.close()


def run_workers(
    tasks: list[AssetTask], jobs: int, timeout: float | None, check: Check = check_asset
) -> Iterator[AssetResult]:
    """Check ``tasks`` in ``jobs`` worker processes, yielding results as they come.

    Args:
        tasks: The assets.
        jobs: Worker processes (at most one per task).
        timeout: Seconds one check may take (``None``: no limit).
        check: The function a worker runs per task (importable: workers are spawned).
    """
    context = multiprocessing.get_context("spawn")
    pending = deque(tasks)
    workers = [_Worker(context, check) for _ in range(min(jobs, len(tasks)))]
    try:
        for worker in workers:
            if pending:
                worker.give(pending.popleft())
        while any(w.task is not None for w in workers):
            busy = [w for w in workers if w.task is not None]
            running = [w.started + timeout for w in busy if w.ready and timeout is not None]
            wait_for = max(0.0, min(running) - time.monotonic()) if running else None
            ready = wait([w.conn for w in busy], wait_for)
            for k, worker in enumerate(workers):
                task = worker.task
                if task is None:
                    continue
                result: AssetResult | None = None
                if worker.conn in ready:
                    try:
                        message = worker.conn.recv()
                    except (EOFError, OSError):  # the worker died without answering
                        message = None
                    if message == READY:
                        worker.became_ready()
                        continue
                    if isinstance(message, AssetResult):
                        result = message
                    else:
                        worker.process.join()
                        result = died(task, worker.process.exitcode)
                        worker.stop(kill=True)
                        workers[k] = worker = _Worker(context, check)
                elif worker.ready and timeout is not None and time.monotonic() - worker.started >= timeout:
                    worker.stop(kill=True)
                    result = timed_out(task, timeout)
                    workers[k] = worker = _Worker(context, check)
                if result is None:
                    continue
                worker.task = None
                if pending:
                    worker.give(pending.popleft())
                yield result
    finally:
        for worker in workers:
            worker.stop(kill=worker.task is not None)


class _Alarm(BaseException):
    """Raised by the SIGALRM handler (a BaseException: rules catch ``Exception`` and must not absorb it)."""


def run_here(tasks: list[AssetTask], timeout: float | None, check: Check = check_asset) -> Iterator[AssetResult]:
    """Check ``tasks`` one by one in this process, each under a SIGALRM deadline where possible."""
    armed = timeout is not None and threading.current_thread() is threading.main_thread() and hasattr(signal, "SIGALRM")
    for task in tasks:
        if not armed or timeout is None:
            yield check(task)
            continue

        def on_alarm(_signum: int, _frame: Any) -> None:
            raise _Alarm

        previous = signal.signal(signal.SIGALRM, on_alarm)
        try:
            signal.setitimer(signal.ITIMER_REAL, timeout)
            result = check(task)
        except _Alarm:
            result = timed_out(task, timeout)
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, previous)
        yield result


def read_with_deadline(task: AssetTask, timeout: float | None) -> ReadAsset:
    """:func:`read_asset` under a SIGALRM deadline where possible (a read past it is an X002 result)."""
    box: list[ReadAsset] = []
    for result in run_here([task], timeout, lambda t: _keep(box, read_asset(t))):
        if not box:  # stopped at the deadline
            return ReadAsset(task, result, done=True)
    return box[0]


def _keep(box: list[ReadAsset], read: ReadAsset) -> AssetResult:
    box.append(read)
    return read.result


def judge_in_thread(read: ReadAsset, timeout: float | None) -> AssetResult:
    """:func:`judge_asset` in a daemon thread, waiting at most ``timeout`` (for executors that own the process).

    A check past the deadline is abandoned, not stopped: its thread runs on until the process ends (a
    Dask LocalCluster's workers end with the run).
    """
    box: list[AssetResult] = []
    thread = threading.Thread(target=lambda: box.append(judge_asset(read)), name="check", daemon=True)
    thread.start()
    thread.join(timeout)
    return box[0] if box else timed_out(read.task, timeout or 0.0)
