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
import logging
from collections.abc import Iterator
from typing import Any

from meshtool.validate.pool import judge_in_thread, read_with_deadline
from meshtool.validate.rules import hit
from meshtool.validate.task import AssetResult, AssetTask, ReadAsset, judge_asset

#: Label of results finished while reading (the file could not be read, or the read timed out).
HERE = "this process"


#: The hint when something answers at the address but it is not a Dask scheduler.
NOT_DASK_HINT = (
    "check the address of --scheduler: a Dask scheduler listens on port 8786 by default, its dashboard on 8787"
)
#: A scheduler's greeting is a few hundred bytes; a first length past this is not Dask.
_GREETING_LIMIT = 1 << 20


class SchedulerError(Exception):
    """The scheduler could not be reached (the runner turns it into a one-line error, exit 1).

    Attributes:
        hint: How to fix it, when more precise than the runner's general hint.
    """

    def __init__(self, message: str, hint: str | None = None) -> None:
        super().__init__(message)
        self.hint = hint


def probe(scheduler: str, seconds: float) -> None:
    """Check that a Dask scheduler answers at a ``tcp://`` address, before ``distributed`` is handed it.

    A Dask scheduler greets every new connection at once with its handshake: an 8-byte little-endian length,
    then that many bytes (the message's frames). A service that sends something else (an HTTP server's
    ``400 Bad Request``: ``distributed`` would read ``HTTP/1.1`` as a length of 3.5e18 bytes and try to
    allocate it) or nothing at all (``distributed`` would wait far past its timeout) is refused here, within
    ``seconds`` in all. Other schemes (``tls://``, ``inproc://``) are left to ``distributed``.

    Raises:
        SchedulerError: Nothing listens there, the connection fails, or what answers is not Dask.
    """
    import socket
    import struct
    import time

    from distributed.comm.addressing import parse_address, parse_host_port

    try:
        scheme, location = parse_address(scheduler)
        if scheme != "tcp":
            return
        host, port = parse_host_port(location, 8786)
    except ValueError as exc:
        raise SchedulerError(f"not a Dask address ({exc})", hint="use tcp://HOST:PORT") from None
    deadline = time.monotonic() + seconds

    def receive(sock: socket.socket, n: int, what: str) -> bytes:
        data = b""
        while len(data) < n:
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError
            sock.settimeout(left)
            chunk = sock.recv(n - len(data))
            if not chunk:
                shown = f" after {data[:40]!r}" if data else ""
                raise SchedulerError(f"the service there closed the connection{shown} ({what})", NOT_DASK_HINT)
            data += chunk
        return data

    try:
        with socket.create_connection((host, port), timeout=seconds) as sock:
            head = receive(sock, 8, "a Dask scheduler greets each connection")
            (length,) = struct.unpack("<Q", head)
            if not 0 < length <= _GREETING_LIMIT:
                try:
                    sock.settimeout(0.2)
                    head += sock.recv(64)
                except OSError:
                    pass
                first = head.split(b"\r\n", 1)[0][:60]
                raise SchedulerError(f"the service there is not Dask (it sent {first!r})", NOT_DASK_HINT)
            receive(sock, int(length), "in the middle of its greeting")
    except TimeoutError:
        raise SchedulerError(
            f"no Dask greeting within {seconds:g} s (a scheduler greets each connection at once)",
            hint=f"{NOT_DASK_HINT}, or raise --scheduler-timeout for a slow network",
        ) from None
    except OSError as exc:
        raise SchedulerError((exc.strerror or type(exc).__name__).lower()) from None


def judge_remote(read: ReadAsset, timeout: float | None) -> tuple[AssetResult, str]:
    """What a Dask worker runs: judge one read asset; returns the result and the worker's address."""
    distributed: Any = importlib.import_module("distributed")
    try:
        where = str(distributed.get_worker().address)
    except ValueError:  # not inside a worker (a synchronous scheduler)
        where = "dask"
    return judge_in_thread(read, timeout), where


def connect(scheduler: str | None, jobs: int, connect_timeout: float) -> tuple[Any, Any, Any]:
    """``(distributed, client, cluster)``: a client of ``scheduler``, or of a new LocalCluster of ``jobs`` workers.

    Raises:
        ImportError: dask.distributed is not installed.
        SchedulerError: The scheduler cannot be reached.
    """
    distributed: Any = importlib.import_module("distributed")
    cluster = None
    try:
        if scheduler:
            probe(scheduler, connect_timeout)
            client = _client(distributed, scheduler, connect_timeout)
        else:
            cluster = distributed.LocalCluster(
                n_workers=jobs,
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                silence_logs=logging.ERROR,
            )
            client = distributed.Client(cluster)
    except (OSError, TimeoutError, ValueError) as exc:
        if cluster is not None:
            cluster.close()
        raise SchedulerError(" ".join(str(exc).split()) or type(exc).__name__) from None
    return distributed, client, cluster


def _client(distributed: Any, scheduler: str, connect_timeout: float) -> Any:
    """A client of ``scheduler``; whatever goes wrong while connecting is the scheduler's side, not a bug."""
    try:
        return distributed.Client(scheduler, timeout=f"{connect_timeout:g}s")
    except (OSError, TimeoutError, ValueError):
        raise
    except Exception as exc:  # a garbled answer (MemoryError, a decoding error) from a service past the probe
        raise SchedulerError(f"the service there is not Dask ({type(exc).__name__}: {exc})", NOT_DASK_HINT) from None


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
