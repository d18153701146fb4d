"""simrun serve under hostile load: the world's real-time factor and a legitimate request's latency.

Usage: python bench/serve_load.py [any path] [--repeat 3] [--out docs/benchmarks.md]   (no corpus needed)

Every round starts a real ``simrun serve fixtures/scenes/boebot.toml --port 0`` process (real time, rate 1)
and measures it under each load in turn, interleaved: none (the peer), 900 idle + 200 slowloris sockets
(an unfinished request head, a byte every 2 s; opened once the server runs, which keeps the file-descriptor
limit it started with), 4 threads looping ``GET /api/scene.glb``, and both. Per load, three windows of 3 wall
seconds: the real-time factor from ``/api/state``'s simulated time against this process's wall clock (not the
server's own ``measured_rate``) and the slowest ``GET /api/state``. The first window under the flood includes
the server accepting it. Then, in lockstep, ``GET /api/state`` while a ``POST /api/step {"steps": 100000}``
runs (median and slowest of 10).
"""

from __future__ import annotations

import contextlib
import platform
import resource
import socket
import statistics
import sys
import threading
import time
import urllib.parse
import urllib.request
from pathlib import Path

import mujoco
from _report import arguments, load_average, write_section

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))
from serve_helpers import SCENES, Server, serve  # noqa: E402

BEGIN, END = "<!-- serve-load:begin -->", "<!-- serve-load:end -->"
BOEBOT = SCENES / "boebot.toml"
IDLE, SLOWLORIS, GLB_CLIENTS = 900, 200, 4


def _state(server: Server) -> tuple[float, float, float]:
    """(wall s at the request's middle, its latency s, the world's simulated time) of one GET /api/state."""
    before = time.monotonic()
    sim = float(server.get("/api/state")["time"])
    after = time.monotonic()
    return (before + after) / 2, after - before, sim


def _window(server: Server, seconds: float = 3.0) -> tuple[float, float]:
    """(real-time factor, slowest latency s) over ``seconds``."""
    wall0, late0, sim0 = _state(server)
    time.sleep(seconds)
    wall1, late1, sim1 = _state(server)
    return (sim1 - sim0) / (wall1 - wall0), max(late0, late1)


class Load:
    """The flood (idle and slowloris sockets) and/or the scene-GLB loopers against one server."""

    def __init__(self, server: Server, flood: bool, glb: bool) -> None:
        url = urllib.parse.urlsplit(server.url)
        assert url.hostname is not None and url.port is not None
        self.address = (url.hostname, url.port)
        self.stop = threading.Event()
        self.sockets: list[socket.socket] = []
        self.slow: list[socket.socket] = []
        self.downloads = 0
        threads = []
        if flood:
            head = f"GET /api/state HTTP/1.1\r\nHost: {url.hostname}:{url.port}\r\n".encode()
            self.slow = self._open(SLOWLORIS)
            for s in self.slow:
                with contextlib.suppress(OSError):
                    s.sendall(head)
            self.sockets = self.slow + self._open(IDLE)
            threads.append(threading.Thread(target=self._trickle, daemon=True))
        if glb:
            threads += [threading.Thread(target=self._glb, args=(server.url,), daemon=True) for _ in range(GLB_CLIENTS)]
        self.threads = threads
        for thread in threads:
            thread.start()

    def _open(self, count: int) -> list[socket.socket]:
        opened = []
        for _ in range(count):
            s = socket.socket()
            s.settimeout(10)
            try:
                s.connect(self.address)
            except OSError:
                s.close()
                continue
            opened.append(s)
        return opened

    def _trickle(self) -> None:
        while not self.stop.wait(2.0):
            for s in self.slow:
                with contextlib.suppress(OSError):
                    s.send(b"X")

    def _glb(self, url: str) -> None:
        while not self.stop.is_set():
            with contextlib.suppress(OSError), urllib.request.urlopen(url + "api/scene.glb", timeout=30) as answer:
                answer.read()
                self.downloads += 1

    def close(self) -> None:
        self.stop.set()
        for thread in self.threads:
            thread.join(30)
        for s in self.sockets:
            s.close()


def _raise_file_limit(needed: int) -> None:
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft != resource.RLIM_INFINITY and soft < needed:
        resource.setrlimit(resource.RLIMIT_NOFILE, (min(needed, hard), hard))


LOADS = {
    "none (the peer)": (False, False),
    f"{IDLE} idle + {SLOWLORIS} slowloris sockets": (True, False),
    f"{GLB_CLIENTS} clients looping /api/scene.glb": (False, True),
    "both": (True, True),
}


def _long_step_reads(rounds: int) -> list[float]:
    latencies = []
    for _ in range(rounds):
        with serve(BOEBOT, "--lockstep") as server:
            stepping = threading.Thread(target=lambda: server.post("/api/step", {"steps": 100_000}))
            stepping.start()
            time.sleep(0.5)
            for _ in range(10):
                latencies.append(_state(server)[1])
                time.sleep(0.1)
            stepping.join(60)
    return latencies


def main() -> None:
    args = arguments(__doc__, repeat=3)
    results: dict[str, list[tuple[float, float]]] = {name: [] for name in LOADS}
    downloads: dict[str, list[float]] = {name: [] for name in LOADS}
    for _ in range(args.repeat):
        for name, (flood, glb) in LOADS.items():
            with serve(BOEBOT) as server:
                _raise_file_limit(4 * (IDLE + SLOWLORIS) + 256)  # this process only, after the server started
                time.sleep(1.0)
                load = Load(server, flood, glb)
                started = time.monotonic()
                try:
                    results[name] += [_window(server) for _ in range(3)]
                finally:
                    downloads[name].append(load.downloads / (time.monotonic() - started))
                    load.close()
    reads = _long_step_reads(max(1, args.repeat // 3))
    rows = []
    for name, windows in results.items():
        rtfs, late = [w[0] for w in windows], [w[1] for w in windows]
        glb = f"{statistics.mean(downloads[name]):.0f}" if LOADS[name][1] else "-"
        rows.append(f"| {name} | {min(rtfs):.3f} | {statistics.median(rtfs):.3f} | {1000 * max(late):.0f} | "
                    f"{1000 * statistics.median(late):.0f} | {glb} |")  # fmt: skip
    section = "\n".join(
        [
            BEGIN,
            "## Serving under hostile load: `simrun serve` with floods and scene-GLB loopers",
            "",
            f"`python bench/serve_load.py . --repeat {args.repeat}`: a real `simrun serve boebot.toml` (real time) per "
            "load, loads interleaved; each load three 3 s windows per round; real-time factor from `/api/state`'s "
            f"simulated time against the bench's wall clock. Machine: {platform.machine()}, CPython "
            f"{platform.python_version()}, MuJoCo {mujoco.__version__}.",
            "",
            "| load | real-time factor: min | median | slowest GET /api/state ms | median ms | GLBs/s |",
            "|---|---|---|---|---|---|",
            *rows,
            "",
            f"`GET /api/state` during a 100,000-step `POST /api/step` (lockstep): median "
            f"{1000 * statistics.median(reads):.0f} ms, slowest {1000 * max(reads):.0f} ms of {len(reads)}.",
            f"Load average at the time: {load_average()}.",
            END,
        ]
    )
    print(section)
    if args.out:
        write_section(args.out, section, BEGIN, END)


if __name__ == "__main__":
    main()
