"""What validate hands the one batch layer (:mod:`meshtool.work.batch`): the per-asset check and its lost results.

One stuck asset must not block a run of hundreds: every check has a deadline (``timeout`` seconds, see
:data:`meshtool.validate.config.DEFAULT_TIMEOUT`). A check past it gives an X002 finding and the run goes on.

- In worker processes (``jobs`` > 1) each worker takes one asset at a time; a worker past the deadline is
  killed (whatever it is stuck in: a loop, native code, a blocking read) and replaced, giving an X002 finding.
  A worker that dies on its own (a native crash) gives an X001 finding for its asset.
- In this process (``jobs`` == 1) the deadline is the batch layer's ``SIGALRM`` timer, which interrupts Python
  code and blocking system calls but not a single long native call; it needs the main thread (elsewhere checks
  run without a deadline). Use two or more workers for a hard limit.
- On Dask (:mod:`meshtool.validate.remote`) files are read here and only what was read is shipped.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from dataclasses import dataclass

from meshtool.validate.physics import physics_plugin
from meshtool.validate.rules import hit
from meshtool.validate.task import AssetResult, AssetTask, ReadAsset, check_asset, judge_asset, read_asset
from meshtool.work import workpool
from meshtool.work.batch import Lost, ReadHere

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


def lost(task: AssetTask, why: str) -> AssetResult:
    """The result of a check that did not finish (``why`` from the batch layer): X002 at the deadline, else X001."""
    if isinstance(why, Lost) and why.timeout is not None:
        return timed_out(task, why.timeout)
    if isinstance(why, Lost) and why.failure is not None:
        message = f"the Dask worker checking it failed ({why.failure})"
        return AssetResult(task.display, task.kind, [hit("X001", message, task.path.name)])
    return died(task, why.exitcode if isinstance(why, Lost) else None)


def _prepare() -> None:
    with contextlib.suppress(Exception):  # a broken plugin is reported by the check itself
        physics_plugin()  # imported before the first deadline starts: loading MuJoCo is not the asset's time


@dataclass(frozen=True)
class Checker:
    """The batch :class:`~meshtool.work.batch.Work` of validate (pickled into workers): ``check`` per asset."""

    check: Check = check_asset

    def prepare(self) -> None:
        """Load the physics plugin before the first deadline starts."""
        _prepare()

    def __call__(self, task: AssetTask, /) -> AssetResult:
        """The asset's result."""
        return self.check(task)

    def lost(self, task: AssetTask, why: str, /) -> AssetResult:
        """X002 (deadline) or X001 (its worker died or failed)."""
        return lost(task, why)


@dataclass(frozen=True)
class Judge:
    """What a Dask worker runs on an asset read in this process (:func:`judge_asset`)."""

    def prepare(self) -> None:
        """Load the physics plugin before the first deadline starts."""
        _prepare()

    def __call__(self, read: ReadAsset, /) -> AssetResult:
        """The read asset's result."""
        return judge_asset(read)

    def lost(self, read: ReadAsset, why: str, /) -> AssetResult:
        """X002 (deadline) or X001 (the worker failed)."""
        return lost(read.task, why)


def _read(task: AssetTask) -> tuple[bool, AssetResult | ReadAsset]:
    read = read_asset(task)
    if read.done:  # unreadable, refused or failed while reading: nothing to ship
        return True, judge_asset(read)
    return False, read


#: Validate's split for Dask: read every file here, judge on the workers.
READ_HERE: ReadHere[AssetTask] = ReadHere(_read, Judge())
