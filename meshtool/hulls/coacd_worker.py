"""Child process that runs CoACD once and dies with its parent.

``python -m meshtool.hulls.coacd_worker PARENT_PID FOLDER IN.npz OUT.npz``

Kept apart from the caller because CoACD can abort the process on bad input and writes to C stdout.
The process is a small supervisor: it forks the CoACD run into a grandchild and watches two things, the
grandchild and its own parent. When the parent goes away (killed by SIGTERM or SIGKILL, a crash; the
kernel's parent-death signal and a re-parenting check both tell) or the supervisor itself is asked to stop
(SIGTERM, SIGINT, SIGHUP), it kills the grandchild and removes FOLDER (the job's temporary folder), so
nothing is left running or on disk. The grandchild has SIGKILL as its parent-death signal, so it cannot
outlive the supervisor either. Writes the hulls' vertices as ``hull_0``, ``hull_1``... in OUT.npz.
"""

from __future__ import annotations

import contextlib
import json
import os
import select
import shutil
import signal
import sys
import time
import traceback
from collections.abc import Callable
from types import FrameType

import numpy as np

from meshtool.work.lifeline import set_parent_death_signal

#: Seconds between checks of the parent and the grandchild.
POLL_S = 0.05
_stop = False


def run(job: str, out: str) -> None:
    """Read the job, run CoACD, write the hull vertices."""
    import coacd

    coacd.set_log_level("error")
    with np.load(job) as archive:
        points = np.asarray(archive["points"], dtype=np.float64)
        faces = np.asarray(archive["faces"], dtype=np.int64)
        params = json.loads(bytes(archive["params"]).decode())
    delay = float(os.environ.get("MESHTOOL_TEST_COACD_DELAY_S", "0") or 0)
    if delay > 0:  # test hook: keeps the worker busy so that tests can kill its parent mid-run
        time.sleep(delay)
    parts = coacd.run_coacd(coacd.Mesh(points, faces), **params)
    np.savez(out, **{f"hull_{k}": np.asarray(v, dtype=np.float64) for k, (v, _) in enumerate(parts)})  # type: ignore[arg-type]


def _request_stop(_signum: int, _frame: FrameType | None) -> None:
    global _stop
    _stop = True


def _cleanup(child: int | None, folder: str) -> None:
    if child is not None:
        with contextlib.suppress(ProcessLookupError, ChildProcessError):
            os.kill(child, signal.SIGKILL)
            os.waitpid(child, 0)
    shutil.rmtree(folder, ignore_errors=True)


def supervise(parent: int, folder: str, job: str, out: str) -> int:
    """Fork the CoACD run and wait for it while the parent lives.

    Args:
        parent: PID of the process that started this one.
        folder: The job's temporary folder, removed when the parent dies.
        job: IN.npz path.
        out: OUT.npz path.

    Returns:
        The exit status: the grandchild's, or 1 when stopped.
    """
    for sig in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP):
        signal.signal(sig, _request_stop)
    set_parent_death_signal(signal.SIGTERM)
    if os.getppid() != parent:  # the parent died before the death signal was armed
        _cleanup(None, folder)
        return 1
    supervisor = os.getpid()
    child = os.fork()
    if child == 0:  # the grandchild: CoACD
        set_parent_death_signal(signal.SIGKILL)
        if os.getppid() != supervisor:
            os._exit(1)
        for sig in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP):
            signal.signal(sig, signal.SIG_DFL)
        status = 1
        try:
            run(job, out)
            status = 0
        except Exception:  # CoACD's own failure: the supervisor reads it from stderr
            traceback.print_exc()
        finally:  # a forked child never unwinds into its parent's stack, whatever was raised
            sys.stderr.flush()
            os._exit(status)
    exited = _exit_waiter(child)
    try:
        while True:
            done, status = os.waitpid(child, os.WNOHANG)
            if done:
                return os.waitstatus_to_exitcode(status) if os.WIFEXITED(status) else 1
            if _stop or os.getppid() != parent:
                _cleanup(child, folder)
                return 1
            exited(POLL_S)
    finally:
        exited(None)


def _exit_waiter(child: int) -> Callable[[float | None], None]:
    """A function that waits up to ``timeout`` s for ``child`` to exit, returning at once when it does.

    Uses a pidfd (Linux 5.3+) so that the result is read the moment CoACD finishes, instead of up to one
    poll period later; elsewhere it sleeps. Called with ``None`` it releases the pidfd.
    """
    try:
        fd: int | None = os.pidfd_open(child)
    except (AttributeError, OSError):
        fd = None

    def wait(timeout: float | None) -> None:
        nonlocal fd
        if timeout is None:
            if fd is not None:
                os.close(fd)
                fd = None
        elif fd is None:
            time.sleep(timeout)
        else:
            select.select([fd], [], [], timeout)

    return wait


def main(argv: list[str]) -> int:
    """Entry point; see the module docstring for the arguments."""
    parent, folder, job, out = int(argv[0]), argv[1], argv[2], argv[3]
    return supervise(parent, folder, job, out)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
