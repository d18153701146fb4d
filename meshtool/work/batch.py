"""The one batch layer: many independent tasks run in this process, in local worker processes, or on Dask.

Every command that runs many items (``obj2bin DIR``, ``meshtool validate``, ``simrun test``) hands its tasks
and a :class:`Work` to :func:`run_batch` with an :class:`Executor` saying where they run:

- ``local`` with one job and no timeout (or ``alarm``): in this process, one task after another (with
  ``alarm``, each under a ``SIGALRM`` deadline: it stops Python code and blocking system calls, not one long
  native call, and needs the main thread);
- ``local`` otherwise: ``jobs`` worker processes (:mod:`meshtool.work.workpool`: spawned, dying with this process,
  killed and replaced at the deadline or when they crash);
- ``dask``: a Dask cluster (``scheduler`` address, or a local cluster of ``jobs`` single-threaded worker
  processes). A task past its deadline on a worker is answered as lost at the deadline and its thread is
  stopped by an exception raised in it at its next Python instruction (a sleep or one native call in progress
  ends first), so an abandoned task does not go on taking the worker's CPU; the worker goes on with the next
  task.

Results come as tasks finish, each with the index of its task, so a caller that needs the input order sorts by
it: what a task computes never depends on where it ran, so outputs are byte-identical whatever the executor
and the number of workers.

A :class:`ReadHere` splits a task in two for Dask: a step run in this process (reading files, so that workers
need no access to them), and a :class:`Work` on what it returns, shipped to the workers.

A ``shared`` payload (``simrun test``'s scene bundles: every file the scenes read) reaches every worker once,
not once per task, and a :class:`SharedWork` gets it with each task: in this process it is the object
itself; a local worker process receives it when it is started (a replacement worker too); on Dask it is
scattered to every worker once (``broadcast``) and each task names it.

Progress: with a ``progress`` callback, :func:`run_batch` counts the finished tasks with a
:class:`meshtool.work.progress.Meter` and calls it with a :class:`~meshtool.work.progress.Tick` after each
(the library never prints; the command line draws :meth:`~meshtool.work.progress.Tick.line`).
"""

from __future__ import annotations

import importlib
import logging
import signal
import threading
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any, Generic, Protocol, TypeVar, overload

from meshtool.errors import MeshtoolError
from meshtool.work import workpool
from meshtool.work.progress import Meter, TickSink

Task = TypeVar("Task")
Result = TypeVar("Result")
Shared = TypeVar("Shared")
Task_contra = TypeVar("Task_contra", contravariant=True)
Shared_contra = TypeVar("Shared_contra", contravariant=True)

#: Where a task ran in this process (the ``where`` of :func:`run_batch`).
HERE = "this process"

EXECUTORS = ("local", "dask")


class BatchError(MeshtoolError):
    """The executor cannot run the batch: dask is not installed, or its scheduler cannot be reached (exit 1).

    ``code`` says which: ``dask-missing`` or ``scheduler-unreachable``.
    """


@dataclass(frozen=True, slots=True)
class Executor:
    """Where a batch runs.

    Attributes:
        kind: ``local`` (this process or worker processes) or ``dask``.
        jobs: Worker processes (local), or workers of the local Dask cluster when no ``scheduler`` is given.
        timeout: Seconds one task may take (``None``: no limit). A local task past it is killed.
        scheduler: Address of a running Dask scheduler (``tcp://host:8786``); ``None`` starts a local cluster.
        connect_timeout: Seconds to try reaching ``scheduler``.
        alarm: One local job with a ``timeout`` runs in this process under a ``SIGALRM`` deadline instead of
            in one worker process (soft: a single long native call is not stopped).
    """

    kind: str = "local"
    jobs: int = 1
    timeout: float | None = None
    scheduler: str | None = None
    connect_timeout: float = 30.0
    alarm: bool = False

    def __post_init__(self) -> None:
        if self.kind not in EXECUTORS:
            raise ValueError(f"executor {self.kind!r}: expected one of {', '.join(EXECUTORS)}")
        if self.jobs < 1:
            raise ValueError(f"jobs {self.jobs}: expected at least 1")
        if self.scheduler and self.kind != "dask":
            raise ValueError("a scheduler address needs the dask executor")

    @property
    def in_process(self) -> bool:
        """Whether tasks run in this process (one local job, no deadline to enforce)."""
        return self.kind == "local" and self.jobs <= 1 and (self.timeout is None or self.alarm)


class Lost(str):
    """Why a task did not finish (one line, the ``why`` of :meth:`Work.lost`), and what happened.

    Attributes:
        timeout: The deadline in seconds, when the task was stopped at it (else ``None``).
        exitcode: The exit code of the local worker process that died running it (``None``: none died, or
            killed by a signal and reaped without one).
        failure: ``Type: message`` of what a Dask worker raised or how it was lost (else ``None``).
    """

    timeout: float | None
    exitcode: int | None
    failure: str | None

    def __new__(
        cls, text: str, *, timeout: float | None = None, exitcode: int | None = None, failure: str | None = None
    ) -> Lost:
        """A reason ``text`` with what happened (keywords as the attributes)."""
        lost = super().__new__(cls, text)
        lost.timeout, lost.exitcode, lost.failure = timeout, exitcode, failure
        return lost


@dataclass(frozen=True, slots=True)
class ReadHere(Generic[Task]):
    """A task split for Dask: ``read`` runs in this process, ``work`` on the workers with what it returned.

    Attributes:
        read: ``(finished, value)`` for a task: ``finished`` means ``value`` is already the task's result
            (nothing to ship); otherwise ``value`` is shipped to a worker (it must pickle). Runs under the
            executor's deadline (``SIGALRM`` where possible); past it the task is lost.
        work: What a worker runs on a shipped value.
    """

    read: Callable[[Task], tuple[bool, Any]]
    work: Work[Any]


class Work(Protocol[Task_contra]):
    """What a batch runs for each task; pickled to worker processes (a module-level class instance)."""

    def prepare(self) -> None:
        """Run once per worker before its first task (imports that must not count against a deadline)."""

    def __call__(self, task: Task_contra, /) -> Any:
        """The result of one task."""

    def lost(self, task: Task_contra, why: str, /) -> Any:
        """The result for a task that did not finish: ``why`` says what happened (one line)."""


class SharedWork(Protocol[Task_contra, Shared_contra]):
    """A :class:`Work` that also gets the batch's ``shared`` payload with every task (see the module)."""

    def prepare(self) -> None:
        """Run once per worker before its first task (imports that must not count against a deadline)."""

    def __call__(self, task: Task_contra, shared: Shared_contra, /) -> Any:
        """The result of one task, given the payload every worker received once."""

    def lost(self, task: Task_contra, why: str, /) -> Any:
        """The result for a task that did not finish: ``why`` says what happened (one line)."""


class _NotShared:
    """The ``shared`` of a batch without a payload (a plain :class:`Work`)."""

    def __repr__(self) -> str:
        return "NOT_SHARED"


NOT_SHARED: Any = _NotShared()


def _call(work: Any, task: Any, shared: Any) -> Any:
    """``work(task)``, or ``work(task, shared)`` when the batch has a payload."""
    return work(task) if isinstance(shared, _NotShared) else work(task, shared)


@dataclass(frozen=True, slots=True)
class _Payload:
    """The shared payload as Dask scatters it: one object (a bare dict or list would be scattered item by item)."""

    value: Any


class _Handler(Generic[Task]):
    """Adapts a work to :class:`meshtool.work.workpool.Handler` (tasks travel with their index).

    The shared payload is an attribute: pickled into each worker process once, when it is started.
    """

    def __init__(self, work: Any, shared: Any) -> None:
        self.work = work
        self.shared = shared

    def prepare(self) -> None:
        self.work.prepare()

    def __call__(self, message: tuple[int, Task], /) -> _Done:
        index, task = message
        return _Done(index, _call(self.work, task, self.shared))


@dataclass(frozen=True, slots=True)
class _Done:
    index: int
    result: Any


@overload
def run_batch(
    tasks: Sequence[Task],
    work: Work[Task],
    executor: Executor,
    here: ReadHere[Task] | None = None,
    *,
    progress: TickSink | None = None,
    label: Callable[[Task], str] | None = None,
) -> Iterator[tuple[int, Any, str]]: ...


@overload
def run_batch(
    tasks: Sequence[Task],
    work: SharedWork[Task, Shared],
    executor: Executor,
    here: None = None,
    *,
    shared: Shared,
    progress: TickSink | None = None,
    label: Callable[[Task], str] | None = None,
) -> Iterator[tuple[int, Any, str]]: ...


def run_batch(
    tasks: Sequence[Task],
    work: Any,
    executor: Executor,
    here: ReadHere[Task] | None = None,
    *,
    shared: Any = NOT_SHARED,
    progress: TickSink | None = None,
    label: Callable[[Task], str] | None = None,
) -> Iterator[tuple[int, Any, str]]:
    """Run every task, yielding ``(index of the task, result, where it ran)`` as tasks finish.

    ``where`` is :data:`HERE`, ``worker N`` (a local worker process) or a Dask worker's address.

    Args:
        tasks: The tasks.
        work: What runs per task (locally; on Dask too unless ``here`` is given): a :class:`Work`, or with
            ``shared`` a :class:`SharedWork`.
        executor: Where they run.
        here: For Dask: a step run in this process per task whose value the workers get (see :class:`ReadHere`).
        shared: A payload every worker gets once and the work with every task (see the module); it must pickle.
        progress: Called with a :class:`~meshtool.work.progress.Tick` after each finished task.
        label: The name of a task in a tick's ``last`` (default: ``#N``, its position from 1).

    Raises:
        BatchError: The dask executor without dask.distributed installed, or its scheduler cannot be reached.
        ValueError: Both ``here`` and ``shared`` given.
    """
    if here is not None and not isinstance(shared, _NotShared):
        raise ValueError("a batch takes a ReadHere step or a shared payload, not both")
    if not tasks:
        return
    if progress is None:
        yield from _dispatch(tasks, work, executor, here, shared)
        return
    meter = Meter(len(tasks), progress)
    for index, result, where in _dispatch(tasks, work, executor, here, shared):
        meter.advance(label(tasks[index]) if label is not None else f"#{index + 1}")
        yield index, result, where


def _dispatch(
    tasks: Sequence[Task], work: Any, executor: Executor, here: ReadHere[Task] | None, shared: Any
) -> Iterator[tuple[int, Any, str]]:
    if executor.in_process:
        work.prepare()
        for index, task in enumerate(tasks):
            finished, result = alarmed(
                lambda t: _call(work, t, shared), task, executor.timeout if executor.alarm else None
            )
            yield index, result if finished else work.lost(task, _late_here(executor.timeout)), HERE
    elif executor.kind == "local":
        yield from _run_local(tasks, work, executor, shared)
    else:
        yield from _run_dask(tasks, work, executor, here, shared)


class _Alarm(BaseException):
    """Raised by the SIGALRM handler (a BaseException: code that catches ``Exception`` must not absorb it)."""


def alarmed(call: Callable[[Task], Result], task: Task, timeout: float | None) -> tuple[bool, Result | None]:
    """``(True, call(task))``, or ``(False, None)`` when a ``SIGALRM`` deadline of ``timeout`` s stopped it.

    Without a timeout, outside the main thread or without ``SIGALRM`` the call runs without a deadline.
    """
    if timeout is None or threading.current_thread() is not threading.main_thread() or not hasattr(signal, "SIGALRM"):
        return True, call(task)

    armed = [True]

    def on_alarm(_signum: int, _frame: Any) -> None:
        if armed[0]:
            raise _Alarm

    # The signal is sent to the main thread itself (pthread_kill from a timer thread), not to the process
    # (setitimer): a process-directed SIGALRM may be delivered to any thread that does not block it (a C
    # library's, a renderer's), and then a main thread blocked in a system call (sleep, a read) never wakes.
    main = threading.main_thread().ident
    assert main is not None
    timer = threading.Timer(timeout, signal.pthread_kill, (main, signal.SIGALRM))
    timer.daemon = True
    previous = signal.signal(signal.SIGALRM, on_alarm)
    try:
        timer.start()
        result = call(task)
        armed[0] = False
        return True, result
    except _Alarm:
        return False, None
    finally:
        armed[0] = False
        timer.cancel()
        timer.join()  # a signal it sent is handled (as a no-op, disarmed) before the previous handler is back
        signal.signal(signal.SIGALRM, previous)


def _late_here(timeout: float | None) -> Lost:
    return Lost(f"timed out after {timeout or 0:g} s (stopped in this process)", timeout=timeout or 0.0)


def _run_local(tasks: Sequence[Task], work: Any, executor: Executor, shared: Any) -> Iterator[tuple[int, Any, str]]:
    indexed = list(enumerate(tasks))

    def died(message: tuple[int, Task], exitcode: int | None) -> _Done:
        why = Lost(f"the worker process running it died ({workpool.exit_description(exitcode)})", exitcode=exitcode)
        return _Done(message[0], work.lost(message[1], why))

    def late(message: tuple[int, Task], timeout: float) -> _Done:
        why = Lost(f"timed out after {timeout:g} s (the worker was stopped)", timeout=timeout)
        return _Done(message[0], work.lost(message[1], why))

    for done, number in workpool.run_workers(
        indexed, executor.jobs, executor.timeout, _Handler(work, shared), _Done, died, late
    ):
        yield done.index, done.result, f"worker {number}"


#: The works a Dask worker process has prepared (by type), so ``prepare`` runs once per worker.
_PREPARED: set[str] = set()
_PREPARING = threading.Lock()


def _remote(work: Any, task: Task, timeout: float | None, shared: Any = NOT_SHARED) -> tuple[bool, Any, str]:
    """What a Dask worker runs for one task: ``(finished, result or None at the deadline, worker's address)``.

    ``shared`` is the scattered payload (Dask hands the worker's copy in), or :data:`NOT_SHARED`.
    """
    distributed: Any = importlib.import_module("distributed")
    try:
        where = str(distributed.get_worker().address)
    except ValueError:  # not inside a worker (a synchronous scheduler)
        where = "dask"
    key = f"{type(work).__module__}.{type(work).__qualname__}"
    with _PREPARING:
        if key not in _PREPARED:
            work.prepare()
            _PREPARED.add(key)
    box: list[Any] = []
    failure: list[BaseException] = []

    value = shared.value if isinstance(shared, _Payload) else shared

    def run() -> None:
        try:
            box.append(_call(work, task, value))
        except BaseException as exc:  # re-raised below, in the task's own thread
            failure.append(exc)

    thread = threading.Thread(target=run, daemon=True, name="meshtool-batch-task")
    thread.start()
    thread.join(timeout)
    if thread.is_alive():  # past the deadline: answered as lost, and the thread stopped (see the module)
        _abandon(thread)
        return False, None, where
    if failure:
        raise failure[0]
    if not box:
        return False, None, where
    return True, box[0], where


class Abandoned(BaseException):
    """Raised in a Dask task's thread once its deadline has passed.

    A BaseException: ``except Exception`` in the task's code does not absorb it; ``finally`` clauses run.
    """


def _abandon(thread: threading.Thread) -> None:
    """Raise :class:`Abandoned` in ``thread`` at its next Python instruction (nothing if it has just ended)."""
    import ctypes

    if thread.ident is not None:
        ctypes.pythonapi.PyThreadState_SetAsyncExc(ctypes.c_ulong(thread.ident), ctypes.py_object(Abandoned))


def _run_dask(
    tasks: Sequence[Task], work: Any, executor: Executor, here: ReadHere[Task] | None, shared: Any
) -> Iterator[tuple[int, Any, str]]:
    try:
        distributed, client, cluster = connect(executor.scheduler, executor.jobs, executor.connect_timeout)
    except ImportError:
        raise BatchError(
            "the Dask executor needs dask.distributed", hint="pip install 'meshtool-simrun[dask]'", code="dask-missing"
        ) from None
    except SchedulerError as exc:
        raise BatchError(
            f"cannot reach the Dask scheduler at {executor.scheduler or 'a new local cluster'}: {exc}",
            hint=exc.hint
            or "start one (dask scheduler) with workers (dask worker ADDRESS), check --scheduler, "
            "or run without --executor dask",
            code="scheduler-unreachable",
        ) from None
    remote: Any = here.work if here is not None else work
    timeout = executor.timeout
    try:
        # once to every worker (a worker that joins later fetches it once from a peer), named by each task
        payload = (
            shared if isinstance(shared, _NotShared) else client.scatter(_Payload(shared), broadcast=True, hash=False)
        )
        running = distributed.as_completed()
        shipped: dict[Any, int] = {}

        def collect(futures: list[Any]) -> Iterator[tuple[int, Any, str]]:
            for future in futures:
                index = shipped.pop(future)
                try:
                    finished, result, where = future.result()
                except Exception as exc:  # the worker died, or the task raised or was lost
                    failure = f"{type(exc).__name__}: {exc}"
                    why = Lost(f"the Dask worker failed ({failure})", failure=failure)
                    finished, result, where = True, work.lost(tasks[index], why), "dask"
                if not finished:
                    late = Lost(f"timed out after {timeout or 0:g} s on Dask worker {where}", timeout=timeout or 0.0)
                    result = work.lost(tasks[index], late)
                yield index, result, where

        for index, task in enumerate(tasks):
            value: Any = task
            if here is not None:  # read in this process (under the deadline); only what it read travels
                read, answer = alarmed(here.read, task, timeout)
                if not read or answer is None:
                    yield index, work.lost(task, _late_here(timeout)), HERE
                    continue
                finished, value = answer
                if finished:
                    yield index, value, HERE
                    continue
            future = client.submit(_remote, remote, value, timeout, payload, pure=False)
            shipped[future] = index
            running.add(future)
            if running.has_ready():
                yield from collect(running.next_batch(block=False))
        for future in running:
            yield from collect([future])
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


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
