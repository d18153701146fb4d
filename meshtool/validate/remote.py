"""The Dask executor: files are read here, the computing is done by the cluster's workers.

Workers need no access to the asset folders and no shared working folder: this process resolves every
path and reads every file an asset needs (:func:`meshtool.validate.task.read_asset`: the OBJ, its MTLs and
textures, or a pack and its sources for K003), and ships what it read; a worker runs the geometry,
collision and physics rules on it (:func:`meshtool.validate.task.judge_asset`) and sends back the result
with its own address, so that the report can say how many assets were checked where.

This is the batch layer's :class:`~meshtool.work.batch.ReadHere` step (:data:`meshtool.validate.pool.READ_HERE`)
run by :func:`meshtool.work.batch.run_batch`: reading happens one asset at a time while the workers judge the
ones already shipped. A check past the per-asset deadline gives X002 (reading: stopped by SIGALRM here;
judging: the run stops waiting and the worker's thread is abandoned). A worker lost while judging gives X001.
"""

from __future__ import annotations

from collections.abc import Iterator

from meshtool.validate.pool import READ_HERE, Checker
from meshtool.validate.task import AssetResult, AssetTask
from meshtool.work.batch import Executor, run_batch


def run_dask(
    tasks: list[AssetTask], scheduler: str | None, jobs: int, timeout: float | None, connect_timeout: float = 30.0
) -> Iterator[tuple[AssetResult, str]]:
    """Check ``tasks`` on a Dask cluster, yielding (result, where it was checked) as results come.

    Raises:
        meshtool.work.batch.BatchError: dask.distributed is not installed, or the scheduler cannot be reached.
    """
    executor = Executor("dask", jobs=jobs, timeout=timeout, scheduler=scheduler, connect_timeout=connect_timeout)
    for _, result, where in run_batch(tasks, Checker(), executor, READ_HERE):
        yield result, where
