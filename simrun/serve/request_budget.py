"""Per-client request budgets of ``simrun serve``: no single client's flood can take the world's CPU.

Every HTTP request and WebSocket handshake is counted against its client address (``scope["client"]``) in
two token buckets, refilled continuously: one for every route (:data:`REQUESTS_PER_SECOND`, a burst of
:data:`REQUEST_BURST`) and one for the requests that change something (``POST``, ``PUT``, ``PATCH``,
``DELETE``: service commands, steps, edits; :data:`CHANGES_PER_SECOND`, a burst of :data:`CHANGE_BURST`).
A request that finds either bucket empty is answered ``429`` with the server's JSON error
(``{"error", "field": "", "status": 429}``) and ``Retry-After`` (whole seconds until a token is back, at least
1), without reaching the routes, the loop thread or the edit budget (:mod:`simrun.serve.edit_routes`, which
also caps edits from all clients together); a refused request does not spend a token. Each 429 is held
:data:`PENALTY` wall seconds before it is sent (the event loop sleeps; no CPU), so one connection of a
client that does not wait gets at most ``1 / PENALTY`` refusals a second, and a flood over many connections is
bounded by the connection limits (:mod:`simrun.serve.connections`). A refused WebSocket handshake is answered
like an HTTP request when the server can (``websocket.http.response``), else closed with code 1008.

The budgets hold while the world runs in real time; a ``--lockstep`` server has none (its world advances
only by its clients' step requests, so no request takes time from it, and a lockstep client, a test harness or
a learning loop, sends steps and commands back to back: 229 sequential ``POST`` requests a second measured here).

Everything runs on the event loop (no locks). The numbers are in docs/limits.md ("Server") and docs/serve.md.
"""

from __future__ import annotations

import asyncio
import collections
import json
import math
import time
from collections.abc import Callable

from starlette.types import ASGIApp, Receive, Scope, Send

#: Requests (any route, WebSocket handshakes included) one client address may send per wall second, sustained.
REQUESTS_PER_SECOND = 300.0
#: Requests one client address may send at once before the sustained rate applies.
REQUEST_BURST = 2.0 * REQUESTS_PER_SECOND
#: Changing requests (``POST``, ``PUT``, ``PATCH``, ``DELETE``) one client address may send per wall second.
CHANGES_PER_SECOND = 0.5 * REQUESTS_PER_SECOND
#: Changing requests one client address may send at once before the sustained rate applies.
CHANGE_BURST = REQUESTS_PER_SECOND
#: Wall seconds a 429 is held before it is sent.
PENALTY = 0.1
#: Client addresses whose buckets are kept (beyond, the one seen longest ago is forgotten: a full bucket).
MAX_CLIENTS = 4096
#: Methods that count as changing requests.
CHANGING = frozenset({"POST", "PUT", "PATCH", "DELETE"})


class Bucket:
    """A token bucket: ``rate`` tokens a second up to ``burst`` (full when made).

    Args:
        rate: Tokens added per wall second.
        burst: Most tokens held.
        now: The wall clock now (``time.monotonic`` seconds).
    """

    __slots__ = ("burst", "last", "rate", "tokens")

    def __init__(self, rate: float, burst: float, now: float) -> None:
        self.rate, self.burst, self.tokens, self.last = rate, burst, burst, now

    def fill(self, now: float) -> float:
        """Add the tokens earned since the last look; the tokens held now."""
        self.tokens = min(self.burst, self.tokens + (now - self.last) * self.rate)
        self.last = now
        return self.tokens

    def wait(self) -> float:
        """Seconds until one token is held (0 when one is)."""
        return max(0.0, (1.0 - self.tokens) / self.rate)


def budgets(rate: float = REQUESTS_PER_SECOND) -> tuple[float, float, float, float]:
    """The four numbers of a client's budget from its request ``rate`` (per wall second; ``--request-rate``).

    Returns:
        ``(rate, burst, change_rate, change_burst)``: ``rate``, twice it, half of it and ``rate`` (the defaults:
        :data:`REQUESTS_PER_SECOND`, :data:`REQUEST_BURST`, :data:`CHANGES_PER_SECOND`, :data:`CHANGE_BURST`).
    """
    return rate, 2.0 * rate, 0.5 * rate, rate


class RequestBudget:
    """ASGI middleware: the per-client buckets (see the module).

    Args:
        app: The application.
        rate, burst: Any request's budget per client address (per wall second, at once).
        change_rate, change_burst: A changing request's budget per client address.
        penalty: Wall seconds each 429 is held.
        applies: Whether the budgets hold now (``None``: always); the server's is "not lockstep".

    Attributes:
        refused: Requests answered 429 so far, by client address.
    """

    def __init__(
        self,
        app: ASGIApp,
        rate: float = REQUESTS_PER_SECOND,
        burst: float = REQUEST_BURST,
        change_rate: float = CHANGES_PER_SECOND,
        change_burst: float = CHANGE_BURST,
        penalty: float = PENALTY,
        applies: Callable[[], bool] | None = None,
    ) -> None:
        self.app, self.applies = app, applies
        self.rate, self.burst, self.change_rate, self.change_burst = rate, burst, change_rate, change_burst
        self.penalty = penalty
        self._clients: collections.OrderedDict[str, tuple[Bucket, Bucket]] = collections.OrderedDict()
        self.refused: dict[str, int] = {}

    def check(self, client: str, changing: bool, now: float) -> tuple[float, str]:
        """Spend a request of ``client`` (a change when ``changing``).

        Returns:
            ``(0, "")``, or the seconds until it may send one and which budget is spent (``"requests"`` or
            ``"changing requests"``).
        """
        buckets = self._clients.get(client)
        if buckets is None:
            buckets = (Bucket(self.rate, self.burst, now), Bucket(self.change_rate, self.change_burst, now))
            self._clients[client] = buckets
            while len(self._clients) > MAX_CLIENTS:
                self._clients.popitem(last=False)
        else:
            self._clients.move_to_end(client)
        every, changes = buckets
        every.fill(now)
        changes.fill(now)
        if every.tokens < 1.0:
            return max(every.wait(), changes.wait() if changing else 0.0), "requests"
        if changing and changes.tokens < 1.0:
            return changes.wait(), "changing requests"
        every.tokens -= 1.0
        if changing:
            changes.tokens -= 1.0
        return 0.0, ""

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        """Pass the request on, or answer 429 (held :attr:`penalty` s) when its client's budget is spent."""
        if scope["type"] not in ("http", "websocket") or (self.applies is not None and not self.applies()):
            await self.app(scope, receive, send)
            return
        client = scope.get("client")
        address = str(client[0]) if client else ""
        changing = scope["type"] == "http" and scope.get("method", "GET") in CHANGING
        wait, spent = self.check(address, changing, time.monotonic())
        if not spent:
            await self.app(scope, receive, send)
            return
        self.refused[address] = self.refused.get(address, 0) + 1
        if self.penalty > 0:
            await asyncio.sleep(self.penalty)
        which = f"{self.change_rate:g} {spent}" if spent == "changing requests" else f"{self.rate:g} {spent}"
        retry = max(1, math.ceil(wait))
        message = f"more than {which} a second from {address or 'this client'}; retry after {retry} s"
        body = json.dumps({"error": message, "field": "", "status": 429}).encode()
        headers = [
            (b"content-type", b"application/json"),
            (b"content-length", str(len(body)).encode()),
            (b"retry-after", str(retry).encode()),
        ]
        if scope["type"] == "websocket":
            if "websocket.http.response" not in scope.get("extensions", {}):
                await send({"type": "websocket.close", "code": 1008, "reason": message[:120]})
                return
            await send({"type": "websocket.http.response.start", "status": 429, "headers": headers})
            await send({"type": "websocket.http.response.body", "body": body})
            return
        await send({"type": "http.response.start", "status": 429, "headers": headers})
        await send({"type": "http.response.body", "body": body})
