"""A handshake check in front of a WebSocket server that has none of its own (the Foxglove SDK's).

foxglove-sdk's server (``foxglove.start_server``, 0.30) accepts every handshake: it offers no hook to see
the request's ``Host``, ``Origin`` or query (its ``ServerListener`` hears only subscriptions and
messages, after the connection is made). :class:`Gate` listens on the public port instead and reads each
connection's HTTP upgrade request (at most :data:`MAX_HEAD` bytes, within :data:`HEAD_TIMEOUT` seconds).
:class:`~simrun.serve.access.Access` judges it: a refused one is answered ``HTTP 403`` (401 for a missing
token) with the JSON error body and closed, so it never reaches the SDK; an accepted one is relayed byte for
byte, its request first, to the SDK's server on 127.0.0.1.

The SDK's server listens on one of the ports that the Fetch standard forbids browsers to open
(:data:`BROWSER_BLOCKED_PORTS`: fetch and WebSocket both refuse them, ``ERR_UNSAFE_PORT``), so a page cannot go
round the gate to it; programs on this machine can, as they can reach everything on the loopback.
Everything runs on one asyncio loop in its own thread.

The SDK's server speaks the Foxglove WebSocket protocol but accepts only its own subprotocol name,
``foxglove.sdk.v1`` (a handshake offering only the standard ``foxglove.websocket.v1`` gets ``HTTP 400``). When a
client offers the standard name and not the SDK's, the gate offers the SDK's upstream and answers the client
with the name it offered (:data:`STANDARD`): the messages of both are the same protocol (ws-protocol's v1).

Limits (docs/limits.md, "Server"): at most :data:`MAX_CONNECTIONS` connections, relayed or still sending their
handshake; a new one beyond closes the handshake that has waited longest (a slowloris client never keeps a
Foxglove client out), and is answered 503 only when every connection is relayed. The gate reads the frames a
client sends (RFC 6455 framing, not their content): a message over :data:`MAX_MESSAGE` bytes, whole or in
fragments, is never relayed; the client gets a close frame with code 1009 ("message too big") and the
connection is closed.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import socket
import threading
import time
from collections.abc import Callable

from simrun.serve.access import Access

#: Largest HTTP upgrade request read, bytes (beyond: 431 and closed).
MAX_HEAD = 16 * 1024
#: Longest wait for the whole upgrade request, seconds (beyond: the connection is closed).
HEAD_TIMEOUT = 10.0
#: Most connections at once, relayed or in their handshake (beyond: the oldest handshake is closed, or 503).
MAX_CONNECTIONS = 64
#: Largest WebSocket message a client may send, bytes (beyond: close code 1009). Foxglove clients send
#: subscriptions and service calls, a few hundred bytes each.
MAX_MESSAGE = 64 * 1024
#: WebSocket close code for a message that is too big (RFC 6455 section 7.4.1).
CLOSE_TOO_BIG = 1009
#: Ports above 1023 on the Fetch standard's "bad port" list (fetch.spec.whatwg.org/#port-blocking) that
#: Chromium 156 refuses too (``ERR_UNSAFE_PORT``; it still opens 4190 and 6679 of that list): the server
#: behind the gate listens on the first free one.
BROWSER_BLOCKED_PORTS = (6665, 6666, 6667, 6668, 6669, 6697, 10080, 6566, 4045, 3659, 2049, 1723, 1720, 1719,
                         5060, 5061, 6000)  # fmt: skip
#: The standard subprotocol of the Foxglove WebSocket protocol, and the name foxglove-sdk's server accepts.
STANDARD, SDK = "foxglove.websocket.v1", "foxglove.sdk.v1"
_REASONS = {401: "Unauthorized", 403: "Forbidden", 400: "Bad Request", 431: "Request Header Fields Too Large",
            503: "Service Unavailable"}  # fmt: skip


def _answer(status: int, field: str, message: str) -> bytes:
    body = json.dumps({"error": message, "field": field, "status": status}).encode()
    head = (
        f"HTTP/1.1 {status} {_REASONS[status]}\r\nContent-Type: application/json\r\n"
        f"Content-Length: {len(body)}\r\nConnection: close\r\n\r\n"
    )
    return head.encode("latin-1") + body


def parse_head(head: bytes) -> tuple[str, dict[str, str]] | None:
    """(request target, headers by lowercase name) of an HTTP/1.1 request head; ``None`` when malformed.

    A header given twice keeps both values joined by ``", "`` (so two ``Host`` headers never name this server).
    """
    lines = head.decode("latin-1").split("\r\n")
    parts = lines[0].split(" ")
    if len(parts) != 3 or not parts[2].startswith("HTTP/1."):
        return None
    headers: dict[str, str] = {}
    for line in lines[1:]:
        if not line:
            continue
        name, colon, value = line.partition(":")
        if not colon or not name or name != name.strip():
            return None
        key = name.lower()
        headers[key] = f"{headers[key]}, {value.strip()}" if key in headers else value.strip()
    return parts[1], headers


def rename_protocol(head: bytes, old: str, new: str) -> bytes:
    """An HTTP head with ``Sec-WebSocket-Protocol``: ``old`` (one name of its list) replaced by ``new``."""
    lines = head.split(b"\r\n")
    for k, line in enumerate(lines):
        name, colon, value = line.partition(b":")
        if colon and name.strip().lower() == b"sec-websocket-protocol":
            names = [v.strip() for v in value.decode("latin-1").split(",")]
            value_out = ", ".join(new if v == old else v for v in names)
            lines[k] = name + b": " + value_out.encode("latin-1")
    return b"\r\n".join(lines)


class Gate:
    """A TCP listener on 127.0.0.1 that checks WebSocket handshakes and relays the accepted ones.

    Args:
        port: Public port (0: a free one).
        upstream: Port of the server behind it, on 127.0.0.1.
        access: Makes the rules once the public port is known (``access(port)``).

    Attributes:
        port: The public port it listens on.
        refused: Handshakes refused so far.
        evicted: Handshakes closed to make room for a new connection, so far.
        too_big: Connections closed for a message over :data:`MAX_MESSAGE`, so far.
    """

    def __init__(self, port: int, upstream: int, access: Callable[[int], Access]) -> None:
        self._listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        try:
            self._listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            self._listener.bind(("127.0.0.1", port))
            self._listener.listen(128)
        except OSError:
            self._listener.close()
            raise
        self.port = int(self._listener.getsockname()[1])
        self.access = access(self.port)
        self.upstream = upstream
        self.refused = self.evicted = self.too_big = 0
        self._open = 0
        self._pending: dict[asyncio.Task[None], float] = {}
        self._loop = asyncio.new_event_loop()
        self._started = threading.Event()
        self._thread = threading.Thread(target=self._main, name="simrun-serve-foxglove-gate", daemon=True)
        self._thread.start()
        self._started.wait(10)

    def _main(self) -> None:
        asyncio.set_event_loop(self._loop)
        server = self._loop.run_until_complete(
            asyncio.start_server(self._connection, sock=self._listener, limit=MAX_HEAD)
        )
        self._started.set()
        try:
            self._loop.run_forever()
        finally:
            server.close()
            tasks = asyncio.all_tasks(self._loop)
            for task in tasks:
                task.cancel()
            self._loop.run_until_complete(asyncio.gather(*tasks, return_exceptions=True))
            self._loop.close()

    async def _connection(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        task = asyncio.current_task()
        assert task is not None
        try:
            if self._open + len(self._pending) >= MAX_CONNECTIONS:
                if not self._pending:
                    await self._refuse(writer, 503, "", f"{MAX_CONNECTIONS} connections are open; try later")
                    return
                oldest = min(self._pending, key=lambda t: self._pending[t])
                del self._pending[oldest]
                oldest.cancel()  # a handshake still arriving gives way to the new connection
                self.evicted += 1
            self._pending[task] = time.monotonic()
            try:
                await self._handshake(reader, writer)
            finally:
                self._pending.pop(task, None)
        except (OSError, asyncio.IncompleteReadError, TimeoutError):
            pass
        finally:
            with contextlib.suppress(Exception):
                writer.close()

    async def _handshake(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        try:
            head = await asyncio.wait_for(reader.readuntil(b"\r\n\r\n"), HEAD_TIMEOUT)
        except (asyncio.LimitOverrunError, ValueError):
            await self._refuse(writer, 431, "", f"the request head is larger than {MAX_HEAD} bytes")
            return
        parsed = parse_head(head)
        if parsed is None:
            await self._refuse(writer, 400, "", "not an HTTP/1.1 request")
            return
        target, headers = parsed
        problem = self.access.refusal(headers, target.partition("?")[2].encode("latin-1"))
        if problem is not None:
            await self._refuse(writer, problem.status, problem.field, problem.message)
            return
        offered = [p.strip() for p in headers.get("sec-websocket-protocol", "").split(",") if p.strip()]
        renamed = STANDARD in offered and SDK not in offered
        up_reader, up_writer = await asyncio.open_connection("127.0.0.1", self.upstream, limit=MAX_HEAD)
        try:
            up_writer.write(rename_protocol(head, STANDARD, SDK) if renamed else head)
            try:
                answer = await asyncio.wait_for(up_reader.readuntil(b"\r\n\r\n"), HEAD_TIMEOUT)
            except (asyncio.LimitOverrunError, ValueError):
                await self._refuse(writer, 400, "", "the Foxglove server's answer could not be read")
                return
            # the upstream answer names the SDK's subprotocol: name the one the client offered
            writer.write(rename_protocol(answer, SDK, STANDARD) if renamed else answer)
            task = asyncio.current_task()
            assert task is not None
            self._pending.pop(task, None)  # relayed from now on: no handshake to evict
            self._open += 1
            try:
                if not answer.startswith(b"HTTP/1.1 101"):  # refused upstream: relay its answer's body as it is
                    await _pump(up_reader, writer)
                    return
                await _relay(reader, writer, up_reader, up_writer)
            finally:
                self._open -= 1
        finally:
            with contextlib.suppress(Exception):
                up_writer.close()

    async def _refuse(self, writer: asyncio.StreamWriter, status: int, field: str, message: str) -> None:
        self.refused += 1
        writer.write(_answer(status, field, message))
        with contextlib.suppress(OSError):
            await writer.drain()

    def close(self) -> None:
        """Stop listening and drop the relayed connections."""
        if self._loop.is_running():
            self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(10)
        self._listener.close()


async def _pump(source: asyncio.StreamReader, sink: asyncio.StreamWriter) -> None:
    """Copy ``source`` to ``sink`` until it ends (then half-close ``sink``)."""
    with contextlib.suppress(OSError):
        while chunk := await source.read(65536):
            sink.write(chunk)
            await sink.drain()
        if sink.can_write_eof():
            sink.write_eof()


async def _relay(
    client: asyncio.StreamReader,
    client_out: asyncio.StreamWriter,
    upstream: asyncio.StreamReader,
    upstream_out: asyncio.StreamWriter,
) -> None:
    """Relay WebSocket frames both ways until either side ends; a client message over :data:`MAX_MESSAGE` ends it.

    Frames towards the client are written whole under a lock, so the gate's own close frame (1009) never
    lands inside one of the server's frames.
    """
    lock = asyncio.Lock()
    too_big = asyncio.Event()

    async def to_client() -> None:
        while True:
            head, size = await _frame_head(upstream)
            async with lock:
                client_out.write(head)
                await _copy(upstream, client_out, size)

    async def to_server() -> None:
        message = 0  # bytes of the message being received, over its fragments
        while True:
            head, size = await _frame_head(client)
            opcode = head[0] & 0x0F
            if opcode < 8:  # text, binary or a continuation (control frames carry at most 125 bytes)
                message = size if opcode else message + size
                if message > MAX_MESSAGE:
                    too_big.set()
                    return
                if head[0] & 0x80:
                    message = 0
            upstream_out.write(head)
            await _copy(client, upstream_out, size)

    pumps = [asyncio.ensure_future(to_client()), asyncio.ensure_future(to_server())]
    try:
        with contextlib.suppress(OSError, asyncio.IncompleteReadError):
            await asyncio.wait(pumps, return_when=asyncio.FIRST_COMPLETED)
            if too_big.is_set():
                reason = f"a message over {MAX_MESSAGE} bytes".encode()
                async with lock:
                    pumps[0].cancel()
                    payload = CLOSE_TOO_BIG.to_bytes(2, "big") + reason
                    client_out.write(bytes([0x88, len(payload)]) + payload)
                    await asyncio.wait_for(client_out.drain(), 5.0)
    finally:
        for pump in pumps:
            pump.cancel()
        await asyncio.gather(*pumps, return_exceptions=True)


async def _frame_head(source: asyncio.StreamReader) -> tuple[bytes, int]:
    """The next WebSocket frame's header bytes (masking key included) and its payload length."""
    head = await source.readexactly(2)
    size = head[1] & 0x7F
    if size >= 126:
        extra = await source.readexactly(2 if size == 126 else 8)
        head += extra
        size = int.from_bytes(extra, "big")
    if head[1] & 0x80:
        head += await source.readexactly(4)
    return head, size


async def _copy(source: asyncio.StreamReader, sink: asyncio.StreamWriter, size: int) -> None:
    """Copy ``size`` bytes from ``source`` to ``sink``."""
    while size > 0:
        chunk = await source.read(min(size, 65536))
        if not chunk:
            raise asyncio.IncompleteReadError(b"", size)
        sink.write(chunk)
        size -= len(chunk)
        await sink.drain()
