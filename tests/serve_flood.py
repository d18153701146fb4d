"""The hostile loads of issue 39's Done-when, against a real ``simrun serve`` (shared by a test and a bench).

:class:`Flood` keeps ``idle`` silent and ``slowloris`` trickling sockets open against the server from source
addresses other than the legitimate client's (127.0.1.1, 127.0.1.2, ...: a few addresses, so the server's
per-client limit does not hide the flood and its whole connection table fills), and opens a new socket for
each one the server closes (evicted to make room, or timed out), at most ``reopen_rate`` a second: the table
stays full for as long as the load runs, not only while the first sockets are accepted.
:class:`GlbLoopers` are threads looping ``GET /api/scene.glb`` (from 127.0.2.1). :class:`StepRequests` loops
``POST /api/step {"steps": 100000}`` (from 127.0.3.1; on a real-time world each is answered 409 at once; the
answers are kept). Each load has addresses of its own: the server's per-client request budget refuses a
client that loops GLBs faster than it allows, and must not refuse the legitimate one, from 127.0.0.1, with it.
:func:`legitimate` is the timed client: a new connection per call, alternating ``GET /api/state`` (its
simulated time, sampled against this process's wall clock) and a drive command, each latency kept.
"""

from __future__ import annotations

import contextlib
import http.client
import json
import resource
import selectors
import socket
import statistics
import threading
import time
import urllib.parse
from dataclasses import dataclass, field

from serve_helpers import Server

#: Slowest state call whose simulated time samples the world's clock, s (its middle is its time: +-25 ms).
PRECISE = 0.05
#: Most sockets the flood opens again per second (its own CPU shares the machine with the server).
REOPEN_RATE = 200.0


def raise_file_limit(needed: int) -> None:
    """Raise this process's soft file-descriptor limit to ``needed`` (within the hard one)."""
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft != resource.RLIM_INFINITY and soft < needed:
        resource.setrlimit(resource.RLIMIT_NOFILE, (min(needed, hard), hard))


def _address(server: Server) -> tuple[str, int]:
    url = urllib.parse.urlsplit(server.url)
    assert url.hostname is not None and url.port is not None
    return url.hostname, url.port


class Flood:
    """``idle`` + ``slowloris`` sockets held open (reopened when closed) until :meth:`close` (see the module)."""

    def __init__(self, server: Server, idle: int, slowloris: int, sources: int = 8, reopen_rate: float = REOPEN_RATE):
        self.address = _address(server)
        self.head = f"GET /api/state HTTP/1.1\r\nHost: {self.address[0]}:{self.address[1]}\r\n".encode()
        self.sources = [f"127.0.1.{k + 1}" for k in range(sources)]
        self.reopen_rate = reopen_rate
        self.opened = self.reopened = self.failed = 0
        self._selector = selectors.DefaultSelector()
        self._slow: set[socket.socket] = set()
        self._stop = threading.Event()
        for k in range(idle + slowloris):
            self._open(slow=k < slowloris)
        self._thread = threading.Thread(target=self._main, daemon=True)
        self._thread.start()

    def __len__(self) -> int:
        return len(self._selector.get_map())

    def _open(self, slow: bool) -> None:
        s = socket.socket()
        s.settimeout(5)
        try:
            s.bind((self.sources[self.opened % len(self.sources)], 0))
            s.connect(self.address)
            if slow:
                s.sendall(self.head)
        except OSError:
            s.close()
            self.failed += 1
            return
        s.setblocking(False)
        self.opened += 1
        if slow:
            self._slow.add(s)
        self._selector.register(s, selectors.EVENT_READ, slow)

    def _main(self) -> None:
        next_trickle = time.monotonic() + 2.0
        budget, last = 0.0, time.monotonic()
        want: list[bool] = []  # sockets to open again (slow or not)
        while not self._stop.is_set():
            for key, _ in self._selector.select(0.05):
                s = key.fileobj
                assert isinstance(s, socket.socket)
                try:
                    gone = s.recv(65536) == b""
                except BlockingIOError:
                    gone = False
                except OSError:
                    gone = True
                if gone:
                    self._selector.unregister(s)
                    self._slow.discard(s)
                    s.close()
                    want.append(bool(key.data))
            now = time.monotonic()
            budget = min(budget + (now - last) * self.reopen_rate, self.reopen_rate)
            last = now
            while want and budget >= 1.0:
                budget -= 1.0
                self._open(want.pop())
                self.reopened += 1
            if now >= next_trickle:
                next_trickle = now + 2.0
                for s in list(self._slow):
                    with contextlib.suppress(OSError):
                        s.send(b"X")

    def close(self) -> None:
        """Stop reopening and close every socket."""
        self._stop.set()
        self._thread.join(30)
        for key in list(self._selector.get_map().values()):
            with contextlib.suppress(OSError):
                key.fileobj.close()  # type: ignore[union-attr]
        self._selector.close()


class _Looper:
    def __init__(self, count: int) -> None:
        self._stop = threading.Event()
        self.answers: list[tuple[int, float]] = []  # (status or 0 for a failed connection, latency s)
        self._threads = [threading.Thread(target=self._loop, daemon=True) for _ in range(count)]
        for thread in self._threads:
            thread.start()

    def _loop(self) -> None:
        while not self._stop.is_set():
            before = time.monotonic()
            try:
                status = self.once()
            except (OSError, http.client.HTTPException):
                status = 0
            self.answers.append((status, time.monotonic() - before))

    def once(self) -> int:
        raise NotImplementedError

    def close(self) -> None:
        self._stop.set()
        for thread in self._threads:
            thread.join(60)


class GlbLoopers(_Looper):
    """``count`` threads looping ``GET /api/scene.glb`` from 127.0.2.1 (the answers: status, latency)."""

    def __init__(self, server: Server, count: int) -> None:
        self.address = _address(server)
        super().__init__(count)

    def once(self) -> int:
        conn = http.client.HTTPConnection(*self.address, timeout=30, source_address=("127.0.2.1", 0))
        try:
            conn.request("GET", "/api/scene.glb")
            response = conn.getresponse()
            response.read()
            return response.status
        finally:
            conn.close()


class StepRequests(_Looper):
    """One client looping ``POST /api/step {"steps": STEPS}`` from 127.0.3.1 (the answers: status, latency)."""

    def __init__(self, server: Server, steps: int = 100_000) -> None:
        self.address, self.body = _address(server), json.dumps({"steps": steps})
        super().__init__(1)

    def once(self) -> int:
        conn = http.client.HTTPConnection(*self.address, timeout=60, source_address=("127.0.3.1", 0))
        try:
            conn.request("POST", "/api/step", self.body, {"Content-Type": "application/json"})
            response = conn.getresponse()
            response.read()
            return response.status
        finally:
            conn.close()
            time.sleep(0.05)  # a new request every 50 ms at most: 20 a second, inside the request budget


@dataclass
class Calls:
    """The legitimate client's calls: (wall s at the call's middle, latency s, status, simulated time or None)."""

    calls: list[tuple[float, float, int, float | None]] = field(default_factory=list)

    def latencies(self) -> list[float]:
        return [c[1] for c in self.calls]

    def statuses(self) -> list[int]:
        return [c[2] for c in self.calls]

    def rtf_windows(self, seconds: float = 3.0, precise: float = PRECISE) -> list[float]:
        """Real-time factors over every window of at least ``seconds`` between two state samples (sliding).

        Only samples answered within ``precise`` s count: the simulated time in an answer was read at some
        instant of the call, taken as its middle, so a call that waited 200 ms for the server to accept its
        connection (behind a flood's) could be off by 100 ms, a 3 % error over 3 s that is no lag of the
        world's clock (a clock that lags stays behind in every later sample).
        """
        samples = [(wall, sim) for wall, late, _, sim in self.calls if sim is not None and late <= precise]
        found = []
        j = 0
        for i in range(len(samples)):
            while j < len(samples) and samples[j][0] - samples[i][0] < seconds:
                j += 1
            if j == len(samples):
                break
            (w0, s0), (w1, s1) = samples[i], samples[j]
            found.append((s1 - s0) / (w1 - w0))
        return found


def legitimate(server: Server, seconds: float, interval: float = 0.1) -> Calls:
    """Call the server for ``seconds``: a new connection each ``interval`` s, state and drive calls alternating."""
    host, port = _address(server)
    calls = Calls()
    end = time.monotonic() + seconds
    k = 0
    while time.monotonic() < end:
        before = time.monotonic()
        sim: float | None = None
        conn = http.client.HTTPConnection(host, port, timeout=30)
        try:
            if k % 2 == 0:
                conn.request("GET", "/api/state")
            else:
                conn.request("POST", "/api/services/DriveService/boebot/all_stop", "{}",
                             {"Content-Type": "application/json"})  # fmt: skip
            response = conn.getresponse()
            payload = response.read()
            status = response.status
            if k % 2 == 0 and status == 200:
                sim = float(json.loads(payload)["time"])
        except (OSError, http.client.HTTPException):
            status = 0
        finally:
            conn.close()
        after = time.monotonic()
        calls.calls.append(((before + after) / 2, after - before, status, sim))
        k += 1
        time.sleep(max(0.0, interval - (after - before)))
    return calls


def summary(calls: Calls) -> dict[str, float]:
    """``rtf_min``, ``rtf_median`` (3 s windows), ``slowest`` and ``median`` latency s, ``calls``, ``samples``."""
    rtfs = calls.rtf_windows()
    late = calls.latencies()
    return {
        "rtf_min": min(rtfs) if rtfs else float("nan"),
        "rtf_median": statistics.median(rtfs) if rtfs else float("nan"),
        "slowest": max(late),
        "median": statistics.median(late),
        "calls": float(len(late)),
        "samples": float(sum(1 for c in calls.calls if c[3] is not None and c[1] <= PRECISE)),
    }
