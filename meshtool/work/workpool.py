"""A pool of worker processes, each taking one task at a time, replaced when it crashes or runs too long.

The pool behind ``meshtool validate -j N`` and ``simrun test -j N``.

- Workers are started with ``spawn`` (MuJoCo and GL contexts are not fork-safe) and die with this process
  (:func:`meshtool.work.lifeline.die_with_parent`); Ctrl-C is the parent's to handle.
- A worker first runs its handler's ``prepare`` (imports that must not count against a task's deadline),
  then says it is ready; a task's deadline starts when the task is sent to a ready worker.
- A worker past the deadline is killed (whatever it is stuck in: a loop, native code, a blocking read) and
  replaced; so is one that dies on its own (a native crash). Each gives the caller's result for that case.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import time
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from multiprocessing.connection import Connection, wait
from typing import Any, Generic, Protocol, TypeVar

from meshtool.work.lifeline import die_with_parent

#: What a worker sends once its handler is prepared.
READY = "ready"

Task = TypeVar("Task")
Result = TypeVar("Result")


class Handler(Protocol):
    """What a worker runs; pickled into the spawned process (a module-level class or function object)."""

    def prepare(self) -> None:
        """Run once in the worker before it takes tasks."""

    def __call__(self, message: Any, /) -> Any:
        """The result for one message (whatever :func:`run_workers`' ``encode`` made of a task)."""


def _worker(conn: Connection, parent_pid: int, handler: Handler) -> None:
    """A worker's life: take a message, send its result, until told to stop (``None``) or the pipe closes."""
    die_with_parent(parent_pid)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    handler.prepare()
    conn.send(READY)
    while True:
        try:
            message = conn.recv()
        except (EOFError, OSError):
            return
        if message is None:
            return
        conn.send(handler(message))


class _Worker(Generic[Task]):
    def __init__(self, context: Any, handler: Handler, number: int) -> None:
        self.conn, child = context.Pipe()
        self.process = context.Process(target=_worker, args=(child, os.getpid(), handler), daemon=True)
        self.process.start()
        child.close()
        self.number = number
        self.ready = False
        self.sent: set[Any] = set()  # what encode chose to send this worker once (a scene's bundle)
        self.task: Task | None = None
        self.started = 0.0

    def give(self, task: Task, encode: Callable[[Task, set[Any]], Any]) -> None:
        """Hand over a task; it is sent (and its deadline starts) once the worker is ready."""
        self.task = task
        if self.ready:
            self.started = time.monotonic()
            self.conn.send(encode(task, self.sent))

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
    tasks: Sequence[Task],
    jobs: int,
    timeout: float | None,
    handler: Handler,
    result_type: type[Result],
    died: Callable[[Task, int | None], Result],
    late: Callable[[Task, float], Result],
    encode: Callable[[Task, set[Any]], Any] = lambda task, _sent: task,
) -> Iterator[tuple[Result, int]]:
    """Run ``tasks`` in ``jobs`` worker processes, yielding (result, worker number) as they finish.

    Args:
        tasks: The tasks, handed out in order.
        jobs: Worker processes (at most one per task).
        timeout: Seconds one task may take (``None``: no limit).
        handler: What each worker runs per message.
        result_type: What a worker's answer is; anything else means the worker died.
        died: The result for a task whose worker died (its exit code: negative for a signal).
        late: The result for a task stopped at the deadline (``timeout`` seconds).
        encode: The message for a task, given the set of what this worker was sent before (add to it).

    Worker numbers count from 1; a replacement gets the next number.
    """
    context = multiprocessing.get_context("spawn")
    pending = deque(tasks)
    started = 0

    def new_worker() -> _Worker[Task]:
        nonlocal started
        started += 1
        return _Worker(context, handler, started)

    workers = [new_worker() for _ in range(min(jobs, len(tasks)))]
    try:
        for worker in workers:
            worker.give(pending.popleft(), encode)
        while any(w.task is not None for w in workers):
            busy = [w for w in workers if w.task is not None]
            deadlines = [w.started + timeout for w in busy if w.ready and timeout is not None]
            ready = wait([w.conn for w in busy], max(0.0, min(deadlines) - time.monotonic()) if deadlines else None)
            for k, worker in enumerate(workers):
                task = worker.task
                if task is None:
                    continue
                result: Result | None = None
                number = worker.number  # the worker that ran the task, also where it died
                if worker.conn in ready:
                    try:
                        message = worker.conn.recv()
                    except (EOFError, OSError):  # the worker died without answering
                        message = None
                    if message == READY:
                        worker.ready = True
                        worker.give(task, encode)
                        continue
                    if isinstance(message, result_type):
                        result = message
                    else:
                        worker.process.join()
                        result = died(task, worker.process.exitcode)
                        worker.stop(kill=True)
                        workers[k] = worker = new_worker()
                elif worker.ready and timeout is not None and time.monotonic() - worker.started >= timeout:
                    worker.stop(kill=True)
                    result = late(task, timeout)
                    workers[k] = worker = new_worker()
                if result is None:
                    continue
                worker.task = None
                if pending:
                    worker.give(pending.popleft(), encode)
                yield result, number
    finally:
        for worker in workers:
            worker.stop(kill=worker.task is not None)


def exit_description(exitcode: int | None) -> str:
    """``signal 9`` or ``exit code 3``: how a worker process ended."""
    return f"signal {-exitcode}" if exitcode is not None and exitcode < 0 else f"exit code {exitcode}"
