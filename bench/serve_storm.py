"""By hand (docs/serve.md "Limits"): the real-time factor of a served world under a flood from one client.

Usage, from the checkout: ``python bench/serve_storm.py [THREADS [PER_THREAD [KINDS]]]`` (default 100 10
none,teleport,get). ``simrun serve fixtures/scenes/boebot_sensors.toml --edit`` runs at rate 1; THREADS
keep-alive connections each send PER_THREAD requests back to back (``teleport``: ``POST
/api/entities/box/teleport``; ``get``: ``GET /api``; ``none``: a 0.1 s sleep each). Printed per kind: the
requests, their rate, the statuses, the ``Retry-After`` values seen, the real-time factor (simulated over wall
seconds, over the flood and at least 3 s) and the loop's own measured rate at the end.
"""

from __future__ import annotations

import http.client
import json
import sys
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
from serve_helpers import SCENES, serve


def flood(host: str, port: int, kind: str, per: int, counts: dict[object, int], retry: set[str | None]) -> None:
    """One client connection sending ``per`` requests of ``kind``; statuses counted into ``counts``."""
    lock = threading.Lock()
    conn = http.client.HTTPConnection(host, port, timeout=30)
    for _ in range(per):
        status: object = 0
        try:
            if kind == "none":
                time.sleep(0.1)
            else:
                if kind == "get":
                    conn.request("GET", "/api")
                else:
                    body = json.dumps({"position": [1.6, 1.0, 0.1]})
                    conn.request("POST", "/api/entities/box/teleport", body, {"Content-Type": "application/json"})
                response = conn.getresponse()
                response.read()
                status = response.status
                if status == 429:
                    retry.add(response.getheader("Retry-After"))
        except (http.client.HTTPException, OSError) as exc:
            status = type(exc).__name__
            conn.close()
            conn = http.client.HTTPConnection(host, port, timeout=30)
        with lock:
            counts[status] = counts.get(status, 0) + 1
    conn.close()


def main() -> None:
    threads = int(sys.argv[1]) if len(sys.argv) > 1 else 100
    per = int(sys.argv[2]) if len(sys.argv) > 2 else 10
    kinds = sys.argv[3].split(",") if len(sys.argv) > 3 else ["none", "teleport", "get"]
    for kind in kinds:
        with serve(SCENES / "boebot_sensors.toml", "--edit") as server:
            time.sleep(1.5)
            host, port = server.url.split("//")[1].strip("/").rsplit(":", 1)
            counts: dict[object, int] = {}
            retry: set[str | None] = set()
            t0, w0 = server.get("/api/state")["time"], time.monotonic()
            workers = [
                threading.Thread(target=flood, args=(host, int(port), kind, per, counts, retry)) for _ in range(threads)
            ]
            for worker in workers:
                worker.start()
            for worker in workers:
                worker.join()
            took = time.monotonic() - w0
            time.sleep(max(0.0, 3.0 - took))
            end = server.get("/api/state")
            w1 = time.monotonic()
            total = sum(counts.values())
            rtf = (end["time"] - t0) / (w1 - w0)
            line = f"{kind}: {total} requests in {took:.2f} s ({total / took:.0f}/s) {counts} Retry-After {retry}"
            print(f"{line} RTF {rtf:.3f} over {w1 - w0:.1f} s, measured_rate {end.get('measured_rate')}", flush=True)


if __name__ == "__main__":
    main()
