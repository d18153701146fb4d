"""Where ``simrun test`` runs happen: this process, a pool of worker processes, or a Dask cluster.

- In this process (``jobs`` == 1, local executor).
- In worker processes (``jobs`` > 1, :mod:`meshtool.work.workpool`: spawned, dying with this process). A
  worker takes one run at a time; a scene's bundle is sent to a worker once, with its first run there. A
  worker that dies (a native crash) gives an internal error for its run and is replaced; a run past
  ``timeout`` seconds is killed the same way.
- On Dask (``dask.distributed``): a client of ``scheduler``, or of a LocalCluster of ``jobs`` workers; each
  bundle is scattered once, the runs are submitted with it, and results are collected as they come.

Whatever the executor, results are plain data and the report orders them by run, so it is identical.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from meshtool.work import workpool
from simrun.scenetest.bundle import Bundle
from simrun.scenetest.task import RunResult, RunTask, run_task

HERE = "this process"


def run_here(tasks: list[RunTask], bundles: dict[str, Bundle]) -> Iterator[tuple[RunResult, str]]:
    """Run the tasks one after the other in this process."""
    for task in tasks:
        yield run_task(task, bundles[task.digest]), HERE


class _Runner:
    """What a pool worker runs (pickled into it): each scene's bundle arrives once, with its first run there."""

    def __init__(self) -> None:
        self.bundles: dict[str, Bundle] = {}

    def prepare(self) -> None:
        import simrun.run.play  # noqa: F401  (imported before the first run: loading MuJoCo is not a run's time)

    def __call__(self, message: tuple[RunTask, Bundle | None]) -> RunResult:
        task, bundle = message
        if bundle is not None:
            self.bundles[bundle.digest] = bundle
        return run_task(task, self.bundles[task.digest])


def run_pool(
    tasks: list[RunTask], bundles: dict[str, Bundle], jobs: int, timeout: float | None
) -> Iterator[tuple[RunResult, str]]:
    """Run the tasks in ``jobs`` worker processes (:mod:`meshtool.work.workpool`), yielding (result, worker)."""

    def encode(task: RunTask, sent: set[Any]) -> tuple[RunTask, Bundle | None]:
        bundle = None if task.digest in sent else bundles[task.digest]
        sent.add(task.digest)
        return task, bundle

    def died(task: RunTask, exitcode: int | None) -> RunResult:
        return _lost(task, f"the worker process running it died ({workpool.exit_description(exitcode)})")

    def late(task: RunTask, timeout: float) -> RunResult:
        message = f"the run did not finish within {timeout:g} s and was stopped (--timeout)"
        return RunResult(task.index, "error", error=message)

    for result, number in workpool.run_workers(tasks, jobs, timeout, _Runner(), RunResult, died, late, encode):
        yield result, f"worker {number}"


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
        meshtool.work.batch.SchedulerError: The scheduler cannot be reached.
    """
    from meshtool.work.batch import connect

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
