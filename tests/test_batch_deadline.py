"""The batch layer's deadline on Dask (meshtool/work/batch.py): a task past it is lost, and its thread stops.

A Dask worker's thread cannot be killed; before, a task past its deadline went on running there forever,
taking the worker's CPU from every later task. Ground truth: a file the spinning task appends to in its loop
(a process fact outside the batch code): after the deadline it must stop growing, watched by a later task on
the same (single) worker.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import pytest

from meshtool.work.batch import Executor, run_batch

pytest.importorskip("distributed")


class Spinner:
    """Tasks: ``("spin", path)`` appends to ``path`` forever; ``("watch", path)`` returns how much it grew in 1 s."""

    def prepare(self) -> None:
        pass

    def __call__(self, task: tuple[str, str]) -> Any:
        kind, path = task
        if kind == "spin":
            with open(path, "ab", buffering=0) as out:
                while True:
                    out.write(b".")
                    time.sleep(0.001)
        time.sleep(0.5)  # the abandoned thread gets its exception at its next instruction
        before = Path(path).stat().st_size
        time.sleep(1.0)
        return Path(path).stat().st_size - before

    def lost(self, task: tuple[str, str], why: str) -> Any:
        return ("lost", str(why))


def test_a_task_past_its_deadline_on_dask_is_lost_and_its_thread_stops(tmp_path: Path) -> None:
    beat = str(tmp_path / "beat")
    results = dict(
        (i, r) for i, r, _ in run_batch([("spin", beat), ("watch", beat)], Spinner(), Executor("dask", timeout=2.0))
    )
    assert results[0][0] == "lost" and "timed out after 2 s" in results[0][1]
    assert Path(beat).stat().st_size > 0  # it did spin before its deadline
    assert results[1] == 0  # and stopped after it
