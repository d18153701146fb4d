"""Worker processes that end with their parent.

A worker pool whose parent is killed (``kill -9`` of ``obj2bin -j 2``, a CI job timeout) must not leave
its workers behind. Two mechanisms, both armed by :func:`die_with_parent` as the first thing a worker does:

- on Linux, ``prctl(PR_SET_PDEATHSIG, sig)`` asks the kernel to signal the worker when its parent exits;
- everywhere (and for a parent that died before the call), a daemon thread polls ``os.getppid()`` and
  exits the process once it has been re-parented.

Used by ``obj2bin``'s pool (:mod:`meshtool.pipeline`), the worker pool of ``meshtool validate`` and
``simrun test`` (:mod:`meshtool.work.workpool`) and the CoACD worker (:mod:`meshtool.hulls.coacd_worker`).
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import signal
import sys
import threading
import time

#: Linux ``prctl`` option: the signal a process gets when its parent thread exits.
PR_SET_PDEATHSIG = 1
#: Seconds between the watchdog's looks at the parent process id.
WATCH_PERIOD_S = 0.5


def set_parent_death_signal(sig: int) -> bool:
    """Ask the kernel to send ``sig`` to this process when its parent dies (Linux ``prctl``).

    Args:
        sig: The signal number, e.g. ``signal.SIGKILL``.

    Returns:
        Whether the call succeeded (``False`` on other systems; the watchdog of :func:`die_with_parent`
        still works there).
    """
    if not sys.platform.startswith("linux"):
        return False
    with contextlib.suppress(OSError, AttributeError):
        libc = ctypes.CDLL(None, use_errno=True)
        return int(libc.prctl(PR_SET_PDEATHSIG, sig, 0, 0, 0)) == 0
    return False


def die_with_parent(parent_pid: int, period_s: float = WATCH_PERIOD_S) -> None:
    """Make this process exit (status 1) when ``parent_pid`` dies; call it first thing in a worker.

    Args:
        parent_pid: The process id of the parent as the parent saw it (``os.getpid()`` there).
        period_s: Seconds between two looks of the watchdog thread at ``os.getppid()``.
    """
    set_parent_death_signal(int(signal.SIGKILL))
    if os.getppid() != parent_pid:  # the parent went before the signal was armed
        os._exit(1)

    def watch() -> None:
        while os.getppid() == parent_pid:
            time.sleep(period_s)
        os._exit(1)

    threading.Thread(target=watch, name="meshtool-parent-watch", daemon=True).start()
