"""The Dask executor: files are read here, the computing is done by the cluster's workers.

Workers need no access to the asset folders and no shared working folder: this process resolves every
path and reads every file an asset needs (:func:`meshtool.validate.task.read_asset`: the OBJ, its MTLs and
textures, or a pack and its sources for K003), and ships what it read; a worker runs the geometry,
collision and physics rules on it (:func:`meshtool.validate.task.judge_asset`) and sends back the result
with its own address, so that the report can say how many assets were checked where.

Reading happens one asset at a time while the workers judge the ones already shipped. A check past the
per-asset deadline gives X002 (reading: stopped by SIGALRM here; judging: the run stops waiting and the
worker's thread is abandoned). A worker lost while judging gives X001 for its asset.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterator
from typing import Any

from meshtool.validate.pool import judge_in_thread, read_with_deadline
from meshtool.validate.rules import hit
from meshtool.validate.task import AssetResult, AssetTask, ReadAsset, judge_asset
from meshtool.work.batch import HERE, connect


def judge_remote(read: ReadAsset, timeout: float | None) -> tuple[AssetResult, str]:
    """What a Dask worker runs: judge one read asset; returns the result and the worker's address."""
    distributed: Any = importlib.import_module("distributed")
    try:
        where = str(distributed.get_worker().address)
    except ValueError:  # not inside a worker (a synchronous scheduler)
        where = "dask"
    return judge_in_thread(read, timeout), where


def run_dask(
    tasks: list[AssetTask], scheduler: str | None, jobs: int, timeout: float | None, connect_timeout: float = 30.0
) -> Iterator[tuple[AssetResult, str]]:
    """Check ``tasks`` on a Dask cluster, yielding (result, where it was checked) as results come.

    Raises:
        ImportError: dask.distributed is not installed.
        SchedulerError: The scheduler cannot be reached.
    """
    if not tasks:  # everything came from the cache: no cluster to start or reach
        return
    distributed, client, cluster = connect(scheduler, jobs, connect_timeout)
    try:
        running = distributed.as_completed()
        shipped: dict[Any, AssetTask] = {}

        def collect(futures: list[Any]) -> Iterator[tuple[AssetResult, str]]:
            for future in futures:
                task = shipped.pop(future)
                try:
                    result, where = future.result()
                except Exception as exc:  # the worker died or the task was lost
                    message = f"the Dask worker checking it failed ({type(exc).__name__}: {exc})"
                    result, where = AssetResult(task.display, task.kind, [hit("X001", message, task.path.name)]), "dask"
                yield result, where

        for task in tasks:
            read = read_with_deadline(task, timeout)
            if read.done:  # unreadable, refused or timed out while reading: nothing to ship
                yield judge_asset(read), HERE
            else:
                future = client.submit(judge_remote, read, timeout, pure=False)
                shipped[future] = task
                running.add(future)
            if running.has_ready():
                yield from collect(running.next_batch(block=False))
        for future in running:
            yield from collect([future])
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
