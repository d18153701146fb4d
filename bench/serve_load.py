"""simrun serve under hostile load: the world's real-time factor and a legitimate client's latency.

Usage: python bench/serve_load.py [any path] [--repeat 3] [--out docs/benchmarks.md]   (no corpus needed)

Every round starts a real ``simrun serve fixtures/scenes/boebot.toml --port 0`` process (real time, rate 1)
per load, loads interleaved: none (the peer); 900 idle + 200 slowloris sockets (an unfinished request head,
a byte every 2 s) from 8 other loopback addresses, each one the server closes opened again (at most
``REOPEN_RATE`` a second), so the flood lasts as long as the load; 4 threads looping ``GET
/api/scene.glb``; a client looping ``POST /api/step {"steps": 100000}`` (a real-time world answers 409 at
once: stepping is for lockstep or paused worlds); and all four at once (issue 39's Done-when load). Under
each, a legitimate client (tests/serve_flood.py) makes 10 calls a second for ``SECONDS``, a new connection
each, alternating ``GET /api/state`` and a drive command: the slowest call, and the real-time factor from the
simulated time in its answers (those within ``PRECISE`` s) against this process's wall clock (not the
server's own ``measured_rate``), over sliding 3 s windows. Then, in lockstep, ``GET /api/state`` while a
``POST /api/step {"steps": 100000}`` runs (median and slowest of 10).
"""

from __future__ import annotations

import platform
import statistics
import sys
import threading
import time
from pathlib import Path

import mujoco
from _report import arguments, load_average, write_section

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))
from serve_flood import PRECISE, REOPEN_RATE, Flood, GlbLoopers, StepRequests, legitimate, raise_file_limit, summary  # noqa: E402
from serve_helpers import SCENES, Server, serve  # noqa: E402

BEGIN, END = "<!-- serve-load:begin -->", "<!-- serve-load:end -->"
BOEBOT = SCENES / "boebot.toml"
IDLE, SLOWLORIS, GLB_CLIENTS = 900, 200, 4
#: Wall seconds the legitimate client calls under each load (the flood's first sockets time out after 10 s).
SECONDS = 15.0


def _state(server: Server) -> tuple[float, float, float]:
    """(wall s at the request's middle, its latency s, the world's simulated time) of one GET /api/state."""
    before = time.monotonic()
    sim = float(server.get("/api/state")["time"])
    after = time.monotonic()
    return (before + after) / 2, after - before, sim


class Load:
    """Any of the four loads of the Done-when against one server, started together."""

    def __init__(self, server: Server, flood: bool, glb: bool, steps: bool) -> None:
        self.flood = Flood(server, IDLE, SLOWLORIS) if flood else None
        self.glb = GlbLoopers(server, GLB_CLIENTS) if glb else None
        self.steps = StepRequests(server) if steps else None

    def close(self) -> None:
        for part in (self.glb, self.steps, self.flood):
            if part is not None:
                part.close()


LOADS = {
    "none (the peer)": (False, False, False),
    f"{IDLE} idle + {SLOWLORIS} slowloris sockets, reopened": (True, False, False),
    f"{GLB_CLIENTS} clients looping /api/scene.glb": (False, True, False),
    "a client looping a 100,000-step POST /api/step (409)": (False, False, True),
    "all four at once (the Done-when load)": (True, True, True),
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
    results: dict[str, list[dict[str, float]]] = {name: [] for name in LOADS}
    refused: dict[str, list[int]] = {name: [] for name in LOADS}
    glbs: dict[str, list[float]] = {name: [] for name in LOADS}
    for _ in range(args.repeat):
        for name, (flood, glb, steps) in LOADS.items():
            with serve(BOEBOT) as server:
                raise_file_limit(4 * (IDLE + SLOWLORIS) + 256)  # this process only, after the server started
                time.sleep(1.0)
                load = Load(server, flood, glb, steps)
                try:
                    calls = legitimate(server, SECONDS)
                finally:
                    load.close()
                assert set(calls.statuses()) == {200}, sorted(set(calls.statuses()))
                results[name].append(summary(calls))
                if load.steps is not None:
                    refused[name] += [status for status, _ in load.steps.answers]
                if load.glb is not None:
                    glbs[name].append(sum(s == 200 for s, _ in load.glb.answers) / SECONDS)
    reads = _long_step_reads(max(1, args.repeat // 3))
    rows = []
    for name, runs in results.items():
        steps = refused[name]
        step_cell = f"{sum(s == 409 for s in steps)}/{len(steps)}" if steps else "-"
        glb_cell = f"{statistics.mean(glbs[name]):.0f}" if glbs[name] else "-"
        rows.append(f"| {name} | {min(r['rtf_min'] for r in runs):.3f} | "
                    f"{statistics.median(r['rtf_median'] for r in runs):.3f} | "
                    f"{1000 * max(r['slowest'] for r in runs):.0f} | "
                    f"{1000 * statistics.median(r['median'] for r in runs):.0f} | "
                    f"{sum(int(r['calls']) for r in runs)} | {glb_cell} | {step_cell} |")  # fmt: skip
    section = "\n".join(
        [
            BEGIN,
            "## Serving under hostile load: `simrun serve` with floods, scene-GLB loopers and long step requests",
            "",
            f"`python bench/serve_load.py . --repeat {args.repeat}`: a real `simrun serve boebot.toml` (real time, "
            f"rate 1) per load and round, loads interleaved; for {SECONDS:g} s under each load a legitimate client "
            "(127.0.0.1, a new connection per call, 10 calls a second) alternates `GET /api/state` and a drive "
            "command (`all_stop`); the real-time factor is the world's simulated time from those answers against "
            "the bench's wall clock, over every window of 3 s between two answers given within "
            f"{1000 * PRECISE:.0f} ms (sliding; min over all rounds, median of the rounds' medians; a slower answer's "
            "time is uncertain by half its latency, and a clock that lags stays behind in every later answer). "
            "The flood holds its sockets from 8 other loopback addresses "
            f"(127.0.1.1-8) and opens a new one for each the server closes (at most {REOPEN_RATE:g} a second). "
            f"Machine: {platform.machine()}, CPython {platform.python_version()}, MuJoCo {mujoco.__version__}.",
            "",
            "| load | real-time factor: min | median | slowest legitimate call ms | median ms | calls | GLBs/s | "
            "step requests answered 409 |",
            "|---|---|---|---|---|---|---|---|",
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
