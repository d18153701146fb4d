"""Who may talk to ``simrun serve``: the ``Host``, ``Origin`` and token rules of every port it opens.

One :class:`Access` holds the rules of one listening port (the HTTP/WebSocket server, or the Foxglove
port) and answers, from a request's headers alone, whether it is refused and why:

1. ``Host`` must name this server: the address it was bound to (for the loopback also ``localhost``,
   ``127.0.0.1`` and ``[::1]``; for another address also the machine's host name; for a wildcard bind
   such as ``0.0.0.0`` any IP literal, which no DNS-rebinding page can send), with the bound port. A page
   that rebinds its own name to this machine sends its own name: 403, field ``host``.
2. ``Origin``, when a browser sends one (every WebSocket handshake, every POST), must be the server's own
   origin (``http://`` or ``https://`` followed by the request's ``Host``) or one given with
   ``--allow-origin``: 403, field ``origin``. Clients that are not browsers (curl, :mod:`simrun.client`,
   Foxglove's own libraries) send none and are not affected.
3. With a token, the request must carry it, as ``Authorization: Bearer TOKEN`` (as UTF-8 or latin-1
   bytes, or percent-encoded UTF-8) or ``?token=TOKEN`` (percent-encoded UTF-8), compared in constant time
   (:func:`hmac.compare_digest`): 401, field ``authorization``. Any printable token works (spaces inside,
   ``+&=%#?``, non-ASCII letters); one that starts or ends with a space, or holds a control character, is
   refused at start (:func:`check_token`): HTTP drops the first and cannot carry the second.

Library code: no I/O; :func:`normalise_origin` raises :class:`~simrun.errors.UsageError` for a malformed
``--allow-origin``.
"""

from __future__ import annotations

import contextlib
import hmac
import ipaddress
import re
import socket
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from urllib.parse import unquote_to_bytes

from simrun.errors import UsageError

#: Addresses that mean "every interface": any IP literal is then accepted as ``Host``.
WILDCARDS = frozenset({"", "0.0.0.0", "::", "[::]"})
_LOOPBACK = frozenset({"localhost", "127.0.0.1", "::1"})
_SCHEME = re.compile(r"[a-z][a-z0-9+.-]*\Z")
_DEFAULT_PORTS = {"http": 80, "https": 443, "ws": 80, "wss": 443}


@dataclass(frozen=True)
class Refusal:
    """Why a request is refused: HTTP ``status`` (401 or 403), the ``field`` it names, a one-line ``message``."""

    status: int
    field: str
    message: str


def _is_ip(name: str) -> bool:
    try:
        ipaddress.ip_address(name)
    except ValueError:
        return False
    return True


def _is_loopback(name: str) -> bool:
    if name == "localhost":
        return True
    try:
        return ipaddress.ip_address(name).is_loopback
    except ValueError:
        return False


def split_host(value: str) -> tuple[str, int | None] | None:
    """``Host``-style ``name[:port]`` (``[v6]:port`` for IPv6) as (lowercase name without brackets, port).

    Returns ``None`` for anything else (an empty name, a bad port, stray brackets, spaces, a path).
    """
    value = value.strip().lower()
    if not value or any(c in value for c in " \t/\\?#@"):
        return None
    if value.startswith("["):
        end = value.find("]")
        if end < 0:
            return None
        name, rest = value[1:end], value[end + 1 :]
        if not _is_ip(name) or ":" not in name:
            return None
    else:
        name, colon, port_text = value.partition(":")
        rest = colon + port_text
        if ":" in port_text or not name:
            return None
    if not rest:
        return name, None
    if not rest.startswith(":") or not rest[1:].isdigit() or len(rest) > 6:
        return None
    port = int(rest[1:])
    return (name, port) if 0 < port < 65536 else None


def normalise_origin(value: str) -> str:
    """An origin as browsers send it: ``scheme://host[:port]``, lowercase, without the scheme's default port.

    Raises:
        UsageError: ``value`` is not an origin (a path, a query, user info, ``*`` or ``null``).
    """
    text = value.strip().lower().rstrip("/")
    scheme, sep, rest = text.partition("://")
    hint = "give scheme://host[:port], e.g. https://app.foxglove.dev or http://localhost:3000"
    if text in ("*", "null"):
        raise UsageError(f"--allow-origin {value!r}: {text} would let any page in; {hint}")
    if not sep or not _SCHEME.match(scheme):
        raise UsageError(f"--allow-origin {value!r} is not an origin; {hint}")
    parts = split_host(rest)
    if parts is None:
        raise UsageError(f"--allow-origin {value!r} is not an origin (no path, query or user); {hint}")
    name, port = parts
    shown = f"[{name}]" if ":" in name else name
    if port is None or port == _DEFAULT_PORTS.get(scheme):
        return f"{scheme}://{shown}"
    return f"{scheme}://{shown}:{port}"


def _origin_of_header(value: str) -> str | None:
    try:
        return normalise_origin(value)
    except UsageError:
        return None


@dataclass(frozen=True)
class Access:
    """The access rules of one listening port (see the module).

    Attributes:
        names: ``Host`` names accepted (lowercase; IPv6 without brackets).
        port: The bound TCP port the ``Host`` must carry (it may be left out when it is 80).
        any_ip: Accept any IP literal as the ``Host`` name (a wildcard bind).
        token: The required token, or ``None``.
        origins: Origins allowed besides the server's own (normalised, :func:`normalise_origin`).
    """

    names: frozenset[str]
    port: int
    any_ip: bool = False
    token: str | None = None
    origins: frozenset[str] = frozenset()

    @classmethod
    def bound(cls, host: str, port: int, token: str | None = None, origins: Iterable[str] = ()) -> Access:
        """The rules of a server bound to ``host:port`` (``host`` as given to ``--host``)."""
        name = host.strip().lower().removeprefix("[").removesuffix("]")
        names = {name}
        if host in WILDCARDS or name in WILDCARDS:
            names = set(_LOOPBACK) | {socket.gethostname().lower()}
            return cls(frozenset(names), port, True, token, frozenset(normalise_origin(o) for o in origins))
        if _is_loopback(name):
            names |= _LOOPBACK
        else:
            names.add(socket.gethostname().lower())
            if not _is_ip(name):  # a name: the addresses it was bound through are its too
                with contextlib.suppress(OSError):
                    names |= {str(info[4][0]).lower() for info in socket.getaddrinfo(name, port)}
        return cls(frozenset(names), port, False, token, frozenset(normalise_origin(o) for o in origins))

    def host_ok(self, value: str) -> bool:
        """Whether a ``Host`` header value names this server (name and port)."""
        parts = split_host(value)
        if parts is None:
            return False
        name, port = parts
        if port != self.port and not (port is None and self.port == 80):
            return False
        return name in self.names or (self.any_ip and _is_ip(name))

    def refusal(self, headers: Mapping[str, str], query: bytes = b"") -> Refusal | None:
        """Why a request with these ``headers`` (lowercase names, latin-1 values) and raw ``query`` is refused.

        Returns:
            ``None`` when it may proceed.
        """
        host = headers.get("host", "")
        if not self.host_ok(host):
            return Refusal(403, "host", f"Host {host[:80]!r} is not this server's address (port {self.port})")
        origin = headers.get("origin")
        if origin is not None:
            own = {_origin_of_header(f"{scheme}://{host}") for scheme in ("http", "https")}
            normal = _origin_of_header(origin)
            if normal is None or not (normal in self.origins or normal in own):
                return Refusal(
                    403,
                    "origin",
                    f"a page from {origin[:80]!r} may not use this server; "
                    f"start it with --allow-origin {normal or 'ORIGIN'} to allow that page",
                )
        if self.token is not None and not self.token_ok(headers.get("authorization", ""), query):
            return Refusal(401, "authorization", "missing or wrong token: send 'Authorization: Bearer TOKEN' "
                           "(or ?token=TOKEN)")  # fmt: skip
        return None

    def token_ok(self, authorization: str, query: bytes) -> bool:
        """Whether the ``Authorization`` header value or the ``token`` query parameter carries the token.

        Both are compared as bytes with :func:`hmac.compare_digest`: the header's bytes as sent (UTF-8 or
        latin-1 text) or percent-decoded (how a browser's ``fetch``, which sends only latin-1 header text,
        can carry any token), the query parameter percent-decoded.
        """
        assert self.token is not None
        given: list[bytes] = []
        scheme, _, credentials = authorization.partition(" ")
        if scheme.lower() == "bearer" and credentials:
            raw = credentials.encode("latin-1", "replace")
            given += [raw, unquote_to_bytes(raw)]
        for pair in query.split(b"&"):
            key, eq, value = pair.partition(b"=")
            if eq and key == b"token":
                given.append(unquote_to_bytes(value.replace(b"+", b" ")))
        wanted = [self.token.encode("utf-8")]
        try:
            latin = self.token.encode("latin-1")
        except UnicodeEncodeError:
            latin = wanted[0]
        wanted.append(latin)
        ok = False
        for candidate in given:
            for token in wanted:
                ok |= hmac.compare_digest(candidate, token)
        return ok


def check_token(token: str) -> None:
    """Refuse a token that cannot travel in a header: control characters, or spaces at either end.

    Raises:
        UsageError: Naming what is wrong.
    """
    if not token.isprintable():
        raise UsageError("--token must be printable text (no control characters or line breaks)")
    if token != token.strip():
        raise UsageError("--token must not start or end with a space (HTTP drops them from the header)")
