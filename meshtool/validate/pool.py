"""Where checks run locally: in this process, or in worker processes that are killed at the per-asset timeout.

One stuck asset must not block a run of hundreds: every check has a deadline (``timeout`` seconds, see
:data:`meshtool.validate.config.DEFAULT_TIMEOUT`). A check past it gives an X002 finding and the run goes on.

- In worker processes (``jobs`` > 1, :mod:`meshtool.work.workpool`) each worker takes one asset at a time; a
  worker past the deadline is killed (whatever it is stuck in: a loop, native code, a blocking read) and
  replaced, giving an X002 finding. A worker that dies on its own (a native crash) gives an X001 finding for
  its asset. Workers are spawned and die with this process (:mod:`meshtool.work.lifeline`).
- In this process (``jobs`` == 1) the deadline is a ``SIGALRM`` timer, which interrupts Python code and
  blocking system calls but not a single long native call; it needs the main thread (elsewhere checks run
  without a deadline). Use two or more workers for a hard limit.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

from meshtool.validate.physics import physics_plugin
from meshtool.validate.rules import hit
from meshtool.validate.task import AssetResult, AssetTask, ReadAsset, check_asset, judge_asset, read_asset
from meshtool.work import workpool

Check = Callable[[AssetTask], AssetResult]


def timed_out(task: AssetTask, timeout: float) -> AssetResult:
    """The result of a check stopped at its deadline: an X002 finding, nothing else checked."""
    message = f"the check did not finish within {timeout:g} s and was stopped; the asset was not checked"
    result = AssetResult(task.display, task.kind, [hit("X002", message, task.path.name)])
    result.notes.append(f"stopped after {timeout:g} s (timeout)")
    return result


def died(task: AssetTask, exitcode: int | None) -> AssetResult:
    """The result of a check whose worker process died (a native crash): an X001 finding."""
    message = f"the worker process checking it died ({workpool.exit_description(exitcode)}); the asset was not checked"
    return AssetResult(task.display, task.kind, [hit("X001", message, task.path.name)])


@dataclass(frozen=True)
class _Checker:
    """What a validate worker runs (pickled into it): ``check`` per task."""

    check: Check

    def prepare(self) -> None:
        with contextlib.suppress(Exception):  # a broken plugin is reported by the check itself
            physics_plugin()  # imported before the first deadline starts: loading MuJoCo is not the asset's time

    def __call__(self, task: AssetTask) -> AssetResult:
        return self.check(task)


def run_workers(
    tasks: list[AssetTask], jobs: int, timeout: float | None, check: Check = check_asset
) -> Iterator[AssetResult]:
    """Check ``tasks`` in ``jobs`` worker processes (:mod:`meshtool.work.workpool`), yielding results as they come.

    Args:
        tasks: The assets.
        jobs: Worker processes (at most one per task).
        timeout: Seconds one check may take (``None``: no limit).
        check: The function a worker runs per task (importable: workers are spawned).
    """
    for result, _ in workpool.run_workers(tasks, jobs, timeout, _Checker(check), AssetResult, died, timed_out):
        yield result


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
