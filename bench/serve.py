"""simrun serve: command-to-actuation latency, stream rates held and real-time factor with 1 and 10 clients.

Usage: python bench/serve.py [any path] [--repeat 3] [--out docs/benchmarks.md]   (no corpus needed)

Every server is a real ``simrun serve --port 0`` process on 127.0.0.1; clients are threads of this process
(the Python client, :mod:`simrun.client`). Measured, in one run:

* throughput: ``pioneer_room.toml`` (Pioneer 3-DX, 360-ray laser at 10 Hz) served at ``--rate 1000`` (as fast
  as it goes) with 0 and 10 stream clients, against the same scene stepped by ``World.step`` in a child
  process with no server (the peer: what serving costs), simulated seconds per wall second, best of --repeat,
  interleaved;
* real time: the same scene at ``--rate 1`` with 1 and 10 clients reading the stream: the measured real-time
  factor, and per client the pose messages (30 per simulated second) and laser scans (10 Hz) received;
* latency: ``boebot.toml`` at ``--rate 1`` with 1 and 10 clients: wall time of ``POST .../cmd_vel`` until the
  answer says it was applied (median, 95th percentile of 100), and from the request until the stream shows the
  robot moved 0.5 mm (median of 10 starts from rest: the drive's control period and the robot's acceleration
  are part of it).
"""

from __future__ import annotations

import platform
import statistics
import subprocess
import sys
import threading
import time
from pathlib import Path

import mujoco
from _report import arguments, load_average, write_section

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))
from serve_helpers import SCENES, Server, serve  # noqa: E402

from simrun.client import Client  # noqa: E402

BEGIN, END = "<!-- serve:begin -->", "<!-- serve:end -->"
ROOM, BOEBOT = SCENES / "pioneer_room.toml", SCENES / "boebot.toml"
BARE = """
import sys, time
from simrun.scene.scene_file import load_scene
from simrun.run.session import prepare
world = load_scene(sys.argv[1]); prepare(world)
world.step(5)
start = time.perf_counter(); t0 = world.time
while time.perf_counter() - start < 3.0:
    world.step(5)
print((world.time - t0) / (time.perf_counter() - start))
"""


class Listeners:
    """``n`` clients reading the stream in threads, counting messages by kind."""

    def __init__(self, url: str, n: int) -> None:
        self.counts = [dict[str, int]() for _ in range(n)]
        self.stop = threading.Event()
        self.threads = [threading.Thread(target=self._listen, args=(url, k), daemon=True) for k in range(n)]
        for thread in self.threads:
            thread.start()
        time.sleep(0.5)

    def _listen(self, url: str, k: int) -> None:
        for message in Client(url).stream():
            kind = message.get("name", message["type"])
            self.counts[k][kind] = self.counts[k].get(kind, 0) + 1
            if self.stop.is_set():
                return

    def reset(self) -> None:
        for count in self.counts:
            count.clear()

    def close(self) -> None:
        self.stop.set()
        for thread in self.threads:
            thread.join(5)


def _speed(server: Server, seconds: float) -> float:
    t0, w0 = server.get("/api/state")["time"], time.perf_counter()
    time.sleep(seconds)
    t1, w1 = server.get("/api/state")["time"], time.perf_counter()
    return (t1 - t0) / (w1 - w0)


def throughput(clients: int) -> float:
    with serve(ROOM, "--rate", "1000") as server:
        listeners = Listeners(server.url, clients) if clients else None
        time.sleep(0.5)
        speed = _speed(server, 3.0)
        if listeners:
            listeners.close()
    return speed


def bare() -> float:
    done = subprocess.run([sys.executable, "-c", BARE, str(ROOM)], capture_output=True, text=True, check=True)
    return float(done.stdout.strip())


def realtime(clients: int) -> tuple[float, float, float, float, float]:
    """(real-time factor, min and mean poses per simulated s, min and mean scans per simulated s)."""
    with serve(ROOM) as server:
        listeners = Listeners(server.url, clients)
        time.sleep(1.0)
        listeners.reset()
        t0, w0 = server.get("/api/state")["time"], time.perf_counter()
        time.sleep(5.0)
        t1, w1 = server.get("/api/state")["time"], time.perf_counter()
        counts = [dict(c) for c in listeners.counts]
        listeners.close()
    simulated = t1 - t0
    poses = [c.get("poses", 0) / simulated for c in counts]
    scans = [c.get("laser", 0) / simulated for c in counts]
    return simulated / (w1 - w0), min(poses), statistics.mean(poses), min(scans), statistics.mean(scans)


def latency(clients: int) -> tuple[float, float, float]:
    """(median and p95 of the applied round trip, median request-to-motion), milliseconds."""
    with serve(BOEBOT) as server:
        listeners = Listeners(server.url, clients - 1) if clients > 1 else None
        sim = Client(server.url)
        drive = sim.service("DriveService", "boebot")
        trips = []
        for _ in range(100):
            start = time.perf_counter()
            drive.cmd_vel(0.0, 0.0)
            trips.append(time.perf_counter() - start)
        motions = []
        for k in range(10):
            drive.all_stop()
            time.sleep(1.0)
            stream = sim.stream(sensors=[])
            first = next(m for m in stream if m["type"] == "poses")
            x0 = first["poses"]["boebot"][0]
            start = time.perf_counter()
            drive.cmd_vel(0.1 if k % 2 == 0 else -0.1, 0.0)
            for message in stream:
                if message["type"] == "poses" and abs(message["poses"]["boebot"][0] - x0) >= 0.0005:
                    motions.append(time.perf_counter() - start)
                    break
            stream.close()
        if listeners:
            listeners.close()
    trips.sort()
    return 1000 * statistics.median(trips), 1000 * trips[94], 1000 * statistics.median(motions)


def main() -> None:
    args = arguments(__doc__, repeat=3)
    speeds: dict[str, list[float]] = {"bare": [], "0": [], "10": []}
    for _ in range(args.repeat):  # interleaved
        speeds["bare"].append(bare())
        speeds["0"].append(throughput(0))
        speeds["10"].append(throughput(10))
    best = {k: max(v) for k, v in speeds.items()}
    rt = {n: realtime(n) for n in (1, 10)}
    lat = {n: latency(n) for n in (1, 10)}
    lines = [
        BEGIN,
        "## Serving: `simrun serve` over HTTP and WebSocket",
        "",
        f"`python bench/serve.py . --repeat {args.repeat}`: real `simrun serve` processes on 127.0.0.1, clients are "
        f"threads of the bench (`simrun.client`). Machine: {platform.machine()}, CPython "
        f"{platform.python_version()}, MuJoCo {mujoco.__version__}.",
        "",
        "Throughput, `pioneer_room.toml` (360-ray laser at 10 Hz) as fast as it goes, simulated s per wall s, best "
        f"of {args.repeat}, interleaved:",
        "",
        "| loop | simulated s / wall s | ratio to World.step alone |",
        "|---|---|---|",
        f"| `World.step` in a child process, no server (the peer) | {best['bare']:.1f} | 1.00 |",
        f"| `simrun serve --rate 1000`, no client | {best['0']:.1f} | {best['0'] / best['bare']:.2f} |",
        f"| `simrun serve --rate 1000`, 10 stream clients | {best['10']:.1f} | {best['10'] / best['bare']:.2f} |",
        "",
        "Real time (`--rate 1`), the same scene, 5 wall seconds; per client: pose messages (published 30 per "
        "simulated second) and laser scans (10 Hz) received per simulated second:",
        "",
        "| clients | real-time factor | poses/s min / mean | scans/s min / mean |",
        "|---|---|---|---|",
        *(f"| {n} | {r[0]:.3f} | {r[1]:.1f} / {r[2]:.1f} | {r[3]:.1f} / {r[4]:.1f} |" for n, r in rt.items()),
        "",
        "Latency, `boebot.toml` at `--rate 1` (the other clients read the stream meanwhile): `POST cmd_vel` until "
        "the answer says it was applied (median, 95th percentile of 100), and until the stream shows the robot "
        "0.5 mm further (median of 10 starts from rest):",
        "",
        "| clients | applied: median ms | applied: p95 ms | request to motion: median ms |",
        "|---|---|---|---|",
        *(f"| {n} | {v[0]:.1f} | {v[1]:.1f} | {v[2]:.0f} |" for n, v in lat.items()),
        "",
        "A command is applied at the next step boundary (in real time the loop sleeps on its call queue between "
        "chunks of at most 10 ms of simulated time; faster, chunks of about 5 ms of wall time); the robot then moves "
        "when the drive service next ticks (50 Hz) and its "
        "wheels have accelerated it 0.5 mm, and the stream shows it in the next pose message (30 per simulated "
        "second).",
        f"Load average at the time: {load_average()}.",
        END,
    ]
    write_section(args.out, "\n".join(lines), BEGIN, END)
    print("\n".join(lines))


if __name__ == "__main__":
    main()
