"""simrun serve under connection floods: idle and slowloris sockets, busy slots, oversized heads and messages.

A real server on 127.0.0.1 (``simrun serve``); the world's pace is read from its simulated clock
(``/api/state`` ``time`` against this process's wall clock), not from the server's own ``measured_rate``.
"""

from __future__ import annotations

import contextlib
import json
import resource
import socket
import threading
import time
import urllib.parse

import pytest
from serve_helpers import SCENES, Server, serve

from simrun.serve.connections import HEAD_TIMEOUT, MAX_PER_CLIENT
from simrun.serve.gate import CLOSE_TOO_BIG, MAX_MESSAGE
from simrun.serve.gate import MAX_CONNECTIONS as GATE_CONNECTIONS

BOEBOT = SCENES / "boebot.toml"
#: The issue's flood: idle sockets, slowloris sockets (an unfinished head, a byte every 2 s).
IDLE, SLOWLORIS = 900, 200


def _address(server: Server) -> tuple[str, int]:
    url = urllib.parse.urlsplit(server.url)
    assert url.hostname is not None and url.port is not None
    return url.hostname, url.port


def _raise_file_limit(needed: int) -> None:
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft != resource.RLIM_INFINITY and soft < needed:
        if hard != resource.RLIM_INFINITY and hard < needed:
            pytest.skip(f"needs {needed} file descriptors, the hard limit is {hard}")
        resource.setrlimit(resource.RLIMIT_NOFILE, (needed, hard))


def _open(address: tuple[str, int], count: int) -> list[socket.socket]:
    sockets = []
    for _ in range(count):
        s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        s.settimeout(10)
        try:
            s.connect(address)
        except OSError:
            s.close()
            continue
        sockets.append(s)
    return sockets


def _clocked(server: Server) -> tuple[float, float, float]:
    """(wall seconds before the request, its latency in seconds, the world's simulated time) of one GET /api/state."""
    before = time.monotonic()
    state = server.get("/api/state")
    return before, time.monotonic() - before, float(state["time"])


def _real_time_factor(server: Server, seconds: float = 3.0) -> tuple[float, float]:
    """(simulated seconds per wall second over ``seconds``, the slowest request's latency)."""
    wall0, late0, sim0 = _clocked(server)
    time.sleep(seconds)
    wall1, late1, sim1 = _clocked(server)
    # each time is read somewhere inside its request: the middle of each request is the best wall estimate
    return (sim1 - sim0) / ((wall1 + late1 / 2) - (wall0 + late0 / 2)), max(late0, late1)


def _answer(s: socket.socket) -> tuple[bytes, dict]:
    """(status line, JSON body) of one HTTP answer read from ``s``."""
    raw = b""
    while b"\r\n\r\n" not in raw:
        raw += s.recv(65536) or b"\r\n\r\n"
    head, _, body = raw.partition(b"\r\n\r\n")
    length = next(int(v) for k, _, v in (h.partition(b":") for h in head.split(b"\r\n")[1:])
                  if k.strip().lower() == b"content-length")  # fmt: skip
    while len(body) < length:
        body += s.recv(65536)
    return head.split(b"\r\n")[0], json.loads(body)


def _closed(s: socket.socket) -> bool:
    try:
        s.settimeout(0.0)
        return s.recv(1) == b""
    except BlockingIOError:
        return False
    except OSError:  # reset
        return True


def test_idle_and_slowloris_connections_do_not_block_requests_or_the_world():
    with serve(BOEBOT) as server:
        _raise_file_limit(4 * (IDLE + SLOWLORIS) + 256)  # here only: the server keeps its own (often 1,024)
        address = _address(server)
        head = f"GET /api/state HTTP/1.1\r\nHost: {address[0]}:{address[1]}\r\n".encode()
        slow = _open(address, SLOWLORIS)
        for s in slow:
            s.sendall(head)
        idle = _open(address, IDLE)
        stop = threading.Event()

        def trickle() -> None:  # a byte every 2 s on every slowloris socket, the head never finished
            while not stop.wait(2.0):
                for s in slow:
                    with contextlib.suppress(OSError):
                        s.send(b"X")

        thread = threading.Thread(target=trickle, daemon=True)
        thread.start()
        try:
            rtf, latency = _real_time_factor(server)
            assert latency < 3.0, latency
            assert rtf >= 0.8, rtf
            # past the head timeout every flooding socket, trickling or silent, has been closed by the server
            time.sleep(HEAD_TIMEOUT + 2.0)
            still = [s for s in slow + idle if not _closed(s)]
            assert not still, f"{len(still)} of {len(slow) + len(idle)} flooding sockets still open"
            assert server.get("/api/state")["time"] > 0
        finally:
            stop.set()
            thread.join()
            for s in slow + idle:
                s.close()


def test_busy_slots_answer_a_new_connection_503_at_once_and_free_up():
    with serve(BOEBOT, "--lockstep") as server:
        _raise_file_limit(4 * MAX_PER_CLIENT + 256)
        address = _address(server)
        host = f"{address[0]}:{address[1]}"
        # a request whose body never comes is busy (not idle): MAX_PER_CLIENT of them fill this client's slots
        busy = _open(address, MAX_PER_CLIENT)
        for s in busy:
            s.sendall(f"POST /api/pause HTTP/1.1\r\nHost: {host}\r\nContent-Type: application/json\r\n"
                      "Content-Length: 100\r\n\r\n{".encode())  # fmt: skip
        time.sleep(1.0)
        extra = socket.create_connection(address, timeout=5)
        started = time.monotonic()
        extra.sendall(f"GET /api/state HTTP/1.1\r\nHost: {host}\r\n\r\n".encode())
        status, body = _answer(extra)
        assert time.monotonic() - started < 3.0
        assert status.startswith(b"HTTP/1.1 503"), status
        assert body["status"] == 503 and "connections are open" in body["error"]
        extra.close()
        # the busy requests' bodies never came: each is answered 408 naming the body, and the slots free up
        first = busy[0]
        first.settimeout(20)
        status, body = _answer(first)
        assert status.startswith(b"HTTP/1.1 408"), status
        assert body["field"] == "body"
        for s in busy:
            s.close()
        time.sleep(1.0)
        assert server.get("/api/state")["paused"] is False


def test_a_request_head_over_16_kib_is_a_json_400():
    with serve(BOEBOT, "--lockstep") as server:
        address = _address(server)
        s = socket.create_connection(address, timeout=10)
        s.sendall(f"GET /api/state HTTP/1.1\r\nHost: {address[0]}:{address[1]}\r\nX-Big: ".encode() + b"a" * 20_000)
        status, body = _answer(s)
        s.close()
        assert status.startswith(b"HTTP/1.1 400"), status
        assert "16384 bytes" in body["error"]


def _expect_close(ws, code: int) -> None:
    from websockets.exceptions import ConnectionClosed

    with pytest.raises(ConnectionClosed) as closed:
        for _ in range(10_000):
            ws.recv(timeout=10)
    assert closed.value.rcvd is not None and closed.value.rcvd.code == code, closed.value


def test_websocket_messages_over_64_kib_close_the_stream_and_the_foxglove_port_with_1009():
    from websockets.sync.client import connect

    with serve(BOEBOT, "--lockstep", "--foxglove-port", "0") as server:
        line = server.process.stdout.readline()
        assert line.startswith("foxglove ws://127.0.0.1:")
        stream = server.url.replace("http://", "ws://") + "api/stream"
        with connect(stream, open_timeout=10, max_size=None) as ws:
            assert json.loads(ws.recv(timeout=10))["type"] == "hello"
            ws.send("x" * 1000)  # a small message is read and ignored: the stream goes on
            server.post("/api/step", {"steps": 10})
            assert json.loads(ws.recv(timeout=10))["type"] == "poses"
            ws.send("x" * (MAX_MESSAGE + 1))
            _expect_close(ws, CLOSE_TOO_BIG)
        foxglove = line.split()[1]
        gate = urllib.parse.urlsplit(foxglove)
        assert gate.port is not None
        # every handshake slot held by slowloris sockets: a Foxglove client still gets in (the oldest gives way)
        slow = _open(("127.0.0.1", gate.port), GATE_CONNECTIONS)
        for s in slow:
            s.sendall(f"GET / HTTP/1.1\r\nHost: 127.0.0.1:{gate.port}\r\n".encode())
        with connect(foxglove, subprotocols=["foxglove.websocket.v1"], open_timeout=10, max_size=None) as ws:
            assert json.loads(ws.recv(timeout=10))["op"] == "serverInfo"
            ws.send(json.dumps({"op": "subscribe", "subscriptions": [], "pad": "x" * 1000}))
            ws.send(b"\x00" * (MAX_MESSAGE // 2), text=False)  # two fragments of one message, over the limit
            ws.send(["a" * (MAX_MESSAGE // 2), "b" * (MAX_MESSAGE // 2 + 1)])
            _expect_close(ws, CLOSE_TOO_BIG)
        assert sum(_closed(s) for s in slow) >= 1
        for s in slow:
            s.close()
        assert server.get("/api/state")["time"] > 0
