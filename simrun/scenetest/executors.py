"""Where ``simrun test`` runs happen: this process, a pool of worker processes, or a Dask cluster.

- In this process (``jobs`` == 1, local executor).
- In worker processes (``jobs`` > 1): started with ``spawn`` (MuJoCo and GL contexts are not fork-safe),
  each dies with this process (``PR_SET_PDEATHSIG`` and a watchdog:
  :func:`meshtool.lifeline.die_with_parent`). A worker takes one run at a time; a scene's bundle is
  sent to a worker once, with its first run there. A worker that dies (a native crash) gives an internal
  error for its run and is replaced; a run past ``timeout`` seconds is killed the same way.
- On Dask (``dask.distributed``): a client of ``scheduler``, or of a LocalCluster of ``jobs`` workers; each
  bundle is scattered once, the runs are submitted with it, and results are collected as they come.

Whatever the executor, results are plain data and the report orders them by run, so it is identical.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import time
from collections import deque
from collections.abc import Iterator
from multiprocessing.connection import Connection, wait
from typing import Any

from simrun.scenetest.bundle import Bundle
from simrun.scenetest.task import RunResult, RunTask, run_task

READY = "ready"
HERE = "this process"


def run_here(tasks: list[RunTask], bundles: dict[str, Bundle]) -> Iterator[tuple[RunResult, str]]:
    """Run the tasks one after the other in this process."""
    for task in tasks:
        yield run_task(task, bundles[task.digest]), HERE


def _worker(conn: Connection, parent_pid: int) -> None:
    from meshtool.lifeline import die_with_parent

    die_with_parent(parent_pid)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle; it stops the workers
    import simrun.play  # noqa: F401  (imported before the first run: loading MuJoCo is not a run's time)

    conn.send(READY)
    bundles: dict[str, Bundle] = {}
    while True:
        try:
            message = conn.recv()
        except (EOFError, OSError):
            return
        if message is None:
            return
        task, bundle = message
        if bundle is not None:
            bundles[bundle.digest] = bundle
        conn.send(run_task(task, bundles[task.digest]))


class _Worker:
    def __init__(self, context: Any, number: int) -> None:
        self.conn, child = context.Pipe()
        self.process = context.Process(target=_worker, args=(child, os.getpid()), daemon=True)
        self.process.start()
        child.close()
        self.name = f"worker {number}"
        self.ready = False
        self.has: set[str] = set()
        self.task: RunTask | None = None
        self.started = 0.0

    def give(self, task: RunTask, bundles: dict[str, Bundle]) -> None:
        self.task = task
        if self.ready:
            bundle = None if task.digest in self.has else bundles[task.digest]
            self.has.add(task.digest)
            self.started = time.monotonic()
            self.conn.send((task, bundle))

    def stop(self, kill: bool) -> None:
        if not kill:
            with contextlib.suppress(OSError, ValueError):
                self.conn.send(None)
            self.process.join(5)
        if self.process.is_alive():
            self.process.kill()
        self.process.join()
        self.conn.close()


def run_pool(
    tasks: list[RunTask], bundles: dict[str, Bundle], jobs: int, timeout: float | None
) -> Iterator[tuple[RunResult, str]]:
    """Run the tasks in ``jobs`` worker processes, yielding (result, worker) as they finish."""
    context = multiprocessing.get_context("spawn")
    pending = deque(tasks)
    started = 0

    def new_worker() -> _Worker:
        nonlocal started
        started += 1
        return _Worker(context, started)

    workers = [new_worker() for _ in range(min(jobs, len(tasks)))]
    try:
        for worker in workers:
            worker.give(pending.popleft(), bundles)
        while any(w.task is not None for w in workers):
            busy = [w for w in workers if w.task is not None]
            deadlines = [w.started + timeout for w in busy if w.ready and timeout is not None]
            ready = wait([w.conn for w in busy], max(0.0, min(deadlines) - time.monotonic()) if deadlines else None)
            for k, worker in enumerate(workers):
                task = worker.task
                if task is None:
                    continue
                result: RunResult | None = None
                if worker.conn in ready:
                    try:
                        message = worker.conn.recv()
                    except (EOFError, OSError):
                        message = None
                    if message == READY:
                        worker.ready = True
                        worker.give(task, bundles)
                        continue
                    if isinstance(message, RunResult):
                        result = message
                    else:
                        worker.process.join()
                        code = worker.process.exitcode
                        how = f"signal {-code}" if code is not None and code < 0 else f"exit code {code}"
                        result = _lost(task, f"the worker process running it died ({how})")
                        worker.stop(kill=True)
                        workers[k] = worker = new_worker()
                elif worker.ready and timeout is not None and time.monotonic() - worker.started >= timeout:
                    worker.stop(kill=True)
                    result = RunResult(
                        task.index,
                        "error",
                        error=f"the run did not finish within {timeout:g} s and was stopped (--timeout)",
                    )
                    workers[k] = worker = new_worker()
                if result is None:
                    continue
                name = worker.name
                worker.task = None
                if pending:
                    worker.give(pending.popleft(), bundles)
                yield result, name
    finally:
        for worker in workers:
            worker.stop(kill=worker.task is not None)


def _lost(task: RunTask, why: str) -> RunResult:
    return RunResult(task.index, "error", error=f"internal error: {why}", internal=True)


def _run_remote(task: RunTask, bundle: Bundle) -> tuple[RunResult, str]:
    """What a Dask worker runs: one task; returns the result and the worker's address."""
    import importlib

    distributed: Any = importlib.import_module("distributed")
    try:
        where = str(distributed.get_worker().address)
    except ValueError:  # not inside a worker
        where = "dask"
    return run_task(task, bundle), where


def run_dask(
    tasks: list[RunTask], bundles: dict[str, Bundle], scheduler: str | None, jobs: int, connect_timeout: float
) -> Iterator[tuple[RunResult, str]]:
    """Run the tasks on a Dask cluster (``scheduler``, or a LocalCluster of ``jobs`` workers).

    Raises:
        ImportError: dask.distributed is not installed.
        meshtool.validate.remote.SchedulerError: The scheduler cannot be reached.
    """
    from meshtool.validate.remote import connect

    if not tasks:
        return
    distributed, client, cluster = connect(scheduler, jobs, connect_timeout)
    try:
        scattered = {d: client.scatter(b, hash=False) for d, b in bundles.items() if any(t.digest == d for t in tasks)}
        futures = {client.submit(_run_remote, t, scattered[t.digest], pure=False): t for t in tasks}
        for future in distributed.as_completed(list(futures)):
            task = futures[future]
            try:
                yield future.result()
            except Exception as exc:  # the worker died or the task was lost
                yield _lost(task, f"the Dask worker running it failed ({type(exc).__name__}: {exc})"), "dask"
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
