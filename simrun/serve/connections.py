"""Connection limits of ``simrun serve``'s HTTP port: no client can hold the server by opening connections.

uvicorn's h11 protocol has no timeout before a request's head is complete (its keep-alive timer starts only
after a response and any byte cancels it) and counts idle connections in ``limit_concurrency``, so 1,100 idle
or slowloris connections (a byte every few seconds) held every file descriptor and blocked every legitimate
request. :func:`protocol_class` is uvicorn's h11 protocol with a :class:`ConnectionTable`:

* a connection with no request in progress (nothing sent yet, a head still incomplete, or between
  keep-alive requests) is *idle*; it is closed :data:`HEAD_TIMEOUT` seconds after it opened or after its
  last response ended, whatever it trickles (uvicorn's own keep-alive timeout closes a silent one after a
  response sooner);
* a request whose response is not complete :data:`REQUEST_TIMEOUT` seconds after its head arrived (a
  client that never reads the answer) has its connection aborted;
* at most :data:`MAX_CONNECTIONS` connections are open, at most :data:`MAX_PER_CLIENT` from one address
  (WebSockets included). A new connection over a limit closes the *idle* connection of that scope that has
  been idle longest, so idle and slowloris connections never keep a new client out; when every connection of
  the scope is busy (requests in progress, WebSockets), the new one is answered ``503`` (JSON, ``Retry-After:
  1``) as soon as its head arrives, or closed after :data:`REFUSED_TIMEOUT` s; more than
  :data:`MAX_REFUSING` such connections at once are reset at once.

Everything runs on uvicorn's event loop (no locks). The limits are in docs/limits.md ("Server").
"""

from __future__ import annotations

import asyncio
import json
import time
from dataclasses import dataclass
from typing import Any

from uvicorn.protocols.http.h11_impl import H11Protocol

#: Most connections open at once (HTTP and WebSocket), well under a default 1,024 file descriptors.
MAX_CONNECTIONS = 512
#: Most connections open at once from one client address.
MAX_PER_CLIENT = 128
#: Wall seconds an idle connection (no request in progress: none sent yet, an incomplete head, or
#: between keep-alive requests) stays open after it opened or after its last response ended.
HEAD_TIMEOUT = 10.0
#: Wall seconds from a request's complete head to its complete response (beyond: the connection is aborted).
REQUEST_TIMEOUT = 60.0
#: Wall seconds a connection refused for a full table may take to send its head (then it is closed).
REFUSED_TIMEOUT = 2.0
#: Most refused connections waiting to be answered 503; beyond, new ones are reset at once.
MAX_REFUSING = 64
#: Seconds between two sweeps of the table (timeouts are enforced to within this).
SWEEP_INTERVAL = 0.5

_IDLE, _BUSY, _WEBSOCKET = "idle", "busy", "websocket"


@dataclass
class _Entry:
    transport: asyncio.Transport
    client: str
    state: str
    since: float


class ConnectionTable:
    """The open connections of one server, their states and the limits (event-loop thread only).

    Args:
        total: Most connections open at once.
        per_client: Most connections open at once from one address.
        head_timeout: Seconds an idle connection stays open.
        request_timeout: Seconds a request may take until its response is complete.

    Attributes:
        evicted: Idle connections closed to make room for new ones, so far.
        refused: Connections answered 503 (or reset) because every slot was busy, so far.
        timed_out: Connections closed by a timeout, so far.
    """

    def __init__(
        self,
        total: int = MAX_CONNECTIONS,
        per_client: int = MAX_PER_CLIENT,
        head_timeout: float = HEAD_TIMEOUT,
        request_timeout: float = REQUEST_TIMEOUT,
    ) -> None:
        self.total, self.per_client = total, per_client
        self.head_timeout, self.request_timeout = head_timeout, request_timeout
        self._entries: dict[int, _Entry] = {}
        self._clients: dict[str, int] = {}
        # the idle connections in the order they became idle, of everyone and per client (eviction in O(1))
        self._idle: dict[int, _Entry] = {}
        self._idle_of: dict[str, dict[int, _Entry]] = {}
        self._refusing = 0
        self._sweeping = False
        self.evicted = self.refused = self.timed_out = 0

    def __len__(self) -> int:
        return len(self._entries)

    def admit(self, transport: asyncio.Transport, client: str) -> bool:
        """Take a new connection (closing the longest-idle one of a full scope); ``False``: every slot is busy."""
        self._start_sweeping()
        if self._clients.get(client, 0) >= self.per_client and not self._evict(self._idle_of.get(client, {})):
            return False
        if len(self._entries) >= self.total and not self._evict(self._idle):
            return False
        entry = _Entry(transport, client, _BUSY, time.monotonic())
        self._entries[id(transport)] = entry
        self._clients[client] = self._clients.get(client, 0) + 1
        self._set(entry, _IDLE)
        return True

    def refusing(self, transport: asyncio.Transport) -> bool:
        """Note a refused connection waiting for its 503 (closed after :data:`REFUSED_TIMEOUT`); ``False``: too many."""
        if self._refusing >= MAX_REFUSING:
            return False
        self._refusing += 1
        self.refused += 1

        def done() -> None:
            self._refusing -= 1
            if not transport.is_closing():
                transport.close()

        asyncio.get_running_loop().call_later(REFUSED_TIMEOUT, done)
        return True

    def note(self, transport: asyncio.Transport, busy: bool) -> None:
        """A connection's request started (``busy``) or its response ended."""
        entry = self._entries.get(id(transport))
        if entry is not None and entry.state != _WEBSOCKET:
            self._set(entry, _BUSY if busy else _IDLE)

    def upgraded(self, transport: asyncio.Transport) -> None:
        """A connection became a WebSocket (never idle; uvicorn's pings close a dead one)."""
        entry = self._entries.get(id(transport))
        if entry is not None:
            self._set(entry, _WEBSOCKET)

    def drop(self, transport: asyncio.Transport) -> None:
        """Forget a closed connection."""
        entry = self._entries.pop(id(transport), None)
        if entry is None:
            return
        self._set(entry, "")
        left = self._clients[entry.client] - 1
        if left:
            self._clients[entry.client] = left
        else:
            del self._clients[entry.client]

    def _set(self, entry: _Entry, state: str) -> None:
        if state == entry.state:
            return
        key = id(entry.transport)
        if entry.state == _IDLE:
            del self._idle[key]
            mine = self._idle_of[entry.client]
            del mine[key]
            if not mine:
                del self._idle_of[entry.client]
        entry.state, entry.since = state, time.monotonic()
        if state == _IDLE:
            self._idle[key] = entry
            self._idle_of.setdefault(entry.client, {})[key] = entry

    def _evict(self, idle: dict[int, _Entry]) -> bool:
        """Close the longest-idle connection of ``idle`` (in the order they became idle); ``False``: none."""
        if not idle:
            return False
        oldest = next(iter(idle.values()))
        if not oldest.transport.is_closing():
            oldest.transport.close()
            self.evicted += 1
        self.drop(oldest.transport)
        return True

    def _start_sweeping(self) -> None:
        if not self._sweeping:
            self._sweeping = True
            asyncio.get_running_loop().call_later(SWEEP_INTERVAL, self._sweep)

    def _sweep(self) -> None:
        now = time.monotonic()
        for entry in list(self._entries.values()):
            if entry.transport.is_closing():
                self.drop(entry.transport)
            elif entry.state == _IDLE and now - entry.since > self.head_timeout:
                entry.transport.close()
                self.drop(entry.transport)
                self.timed_out += 1
            elif entry.state == _BUSY and now - entry.since > self.request_timeout:
                entry.transport.abort()
                self.drop(entry.transport)
                self.timed_out += 1
        asyncio.get_running_loop().call_later(SWEEP_INTERVAL, self._sweep)


def _json_error(status: int, message: str) -> bytes:
    return json.dumps({"error": message, "field": "", "status": status}).encode()


def _unavailable(table: ConnectionTable) -> Any:
    """An ASGI app answering 503 (JSON, ``Connection: close``) for a connection the table refused."""
    body = _json_error(503, _unavailable_message(table))

    async def app(scope: Any, receive: Any, send: Any) -> None:
        headers = [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode()),
                   (b"connection", b"close"), (b"retry-after", b"1")]  # fmt: skip
        await send({"type": "http.response.start", "status": 503, "headers": headers})
        await send({"type": "http.response.body", "body": body})

    return app


def protocol_class(table: ConnectionTable) -> type[H11Protocol]:
    """The h11 protocol of uvicorn keeping ``table`` (give it as ``uvicorn.Config(http=...)``)."""

    class LimitedH11Protocol(H11Protocol):
        """:class:`uvicorn.protocols.http.h11_impl.H11Protocol` under the limits of :class:`ConnectionTable`."""

        refused = False

        def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
            super().connection_made(transport)
            if table.admit(transport, self.client[0] if self.client else ""):
                return
            self.refused = True
            self.app = _unavailable(table)
            if not table.refusing(transport):
                transport.abort()

        def connection_lost(self, exc: Exception | None) -> None:
            super().connection_lost(exc)
            table.drop(self.transport)

        def data_received(self, data: bytes) -> None:
            super().data_received(data)
            self._note()

        def on_response_complete(self) -> None:
            super().on_response_complete()
            self._note()

        def _note(self) -> None:
            table.note(self.transport, self.cycle is not None and not self.cycle.response_complete)

        def handle_websocket_upgrade(self, event: Any) -> None:
            if self.refused:
                self._answer(503, _unavailable_message(table))
                return
            table.upgraded(self.transport)
            super().handle_websocket_upgrade(event)

        def send_400_response(self, msg: str) -> None:
            self._answer(400, f"not an HTTP/1.1 request, or its head is over {_head_limit(self)} bytes ({msg})")

        def _answer(self, status: int, message: str) -> None:
            import h11

            body = _json_error(status, message)
            headers = [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode()),
                       (b"connection", b"close")]  # fmt: skip
            reason = b"Bad Request" if status == 400 else b"Service Unavailable"
            try:
                for event in (h11.Response(status_code=status, headers=headers, reason=reason), h11.Data(data=body),
                              h11.EndOfMessage()):  # fmt: skip
                    self.transport.write(self.conn.send(event) or b"")
            except h11.LocalProtocolError:  # a response had started already: nothing more can be said
                pass
            self.transport.close()

    return LimitedH11Protocol


def _unavailable_message(table: ConnectionTable) -> str:
    return (
        f"{table.total} connections are open ({table.per_client} per client), all with requests in progress; "
        "try again in a second"
    )


def _head_limit(protocol: H11Protocol) -> int:
    size = protocol.config.h11_max_incomplete_event_size
    return int(size) if size is not None else 16 * 1024
