"""Start a real ``simrun serve`` process on 127.0.0.1 (a free port) for the serve tests, and talk to it."""

from __future__ import annotations

import json
import os
import select
import signal
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

CHECKOUT = Path(__file__).resolve().parent.parent
SCENES = CHECKOUT / "fixtures" / "scenes"
SIMRUN = str(Path(sys.executable).parent / "simrun")


@dataclass
class Server:
    """A running server: its URL and process; ``output`` holds what it printed once stopped."""

    url: str
    process: subprocess.Popen[str]
    output: list[str] = field(default_factory=list)

    def request(self, method: str, path: str, body: Any = None, headers: dict[str, str] | None = None,
                raw: bytes | None = None) -> tuple[int, Any]:  # fmt: skip
        """(status, JSON answer) of one request; ``raw`` sends bytes as they are."""
        data = raw if raw is not None else (json.dumps(body).encode() if body is not None else None)
        sent = {"Content-Type": "application/json"} if data is not None else {}
        sent.update(headers or {})
        req = urllib.request.Request(self.url.rstrip("/") + path, data=data, method=method, headers=sent)
        try:
            with urllib.request.urlopen(req, timeout=30) as response:
                payload = response.read()
                status = response.status
        except urllib.error.HTTPError as exc:
            payload, status = exc.read(), exc.code
        try:
            return status, json.loads(payload)
        except ValueError:
            return status, payload

    def get(self, path: str) -> Any:
        status, body = self.request("GET", path)
        assert status == 200, (status, body)
        return body

    def post(self, path: str, body: Any = None) -> Any:
        status, answer = self.request("POST", path, body if body is not None else {})
        assert status == 200, (status, answer)
        return answer


@contextmanager
def serve(scene: str | Path, *args: str, stop: int = signal.SIGINT) -> Iterator[Server]:
    """``simrun serve SCENE --port 0 ARGS`` until the block ends; then ``stop`` and a clean exit (0) checked."""
    env = dict(os.environ, MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"), PYTHONUNBUFFERED="1")
    process = subprocess.Popen(
        [SIMRUN, "serve", str(scene), "--port", "0", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    assert process.stdout is not None and process.stderr is not None
    deadline = time.monotonic() + 90
    line = ""
    while time.monotonic() < deadline:
        ready, _, _ = select.select([process.stdout], [], [], 0.5)
        if ready:
            line = process.stdout.readline()
            if line.startswith("serving ") or not line:
                break
        if process.poll() is not None:
            break
    if not line.startswith("serving "):
        process.kill()
        out, err = process.communicate()
        raise AssertionError(f"simrun serve did not start: {line}{out}{err}")
    server = Server(line.split()[1], process)
    # drain stderr while the server runs: a burst of tracebacks must never fill the pipe and freeze the server
    # (stdout stays for the tests that read the lines the server prints, e.g. the Foxglove port)
    errors: list[str] = []
    drains = [threading.Thread(target=_drain, args=(process.stderr, errors), daemon=True)]
    for thread in drains:
        thread.start()
    try:
        yield server
    finally:
        if process.poll() is None:
            process.send_signal(stop)
        try:
            process.wait(timeout=60)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
            for thread in drains:
                thread.join(10)
            raise AssertionError(f"simrun serve did not stop on signal {stop}: {''.join(errors)}") from None
        for thread in drains:
            thread.join(10)
        out, err = process.stdout.read(), "".join(errors)
        server.output[:] = [out, err]
    assert process.returncode == 0, (process.returncode, out, err)


def _drain(pipe: Any, into: list[str]) -> None:
    """Read ``pipe`` to its end into ``into`` (a server test's stdout or stderr)."""
    for chunk in iter(lambda: pipe.read(4096), ""):
        into.append(chunk)


def wait_idle(server: Server, kind: str, entity: str, timeout: float = 60.0) -> dict[str, Any]:
    """Poll a service until it is not busy; its state then."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        state = server.get(f"/api/services/{kind}/{entity}")["state"]
        if not state["busy"]:
            return dict(state)
        time.sleep(0.05)
    raise AssertionError(f"{kind} of {entity} still busy after {timeout} s")
