"""Running ``simrun serve``: the simulation thread, the ASGI app on uvicorn, and a clean shutdown.

:func:`serve` loads the scene in the simulation thread (a refused scene fails before anything listens),
binds the socket (so ``--port 0`` works and the address is known), and runs uvicorn until SIGINT or
SIGTERM (uvicorn's own handlers: open requests finish, streams close); then the simulation thread stops
and the recording is written. Safe defaults: a host other than the loopback needs a token; every port
checks ``Host``, ``Origin`` and the token (:mod:`simrun.serve.access`).
"""

from __future__ import annotations

import ipaddress
import signal
import socket
import threading
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from simrun.errors import SimrunError, UsageError
from simrun.serve.loop import ServeOptions, SimLoop
from simrun.world.world import World

#: Shortest token accepted, characters.
MIN_TOKEN = 16
_LOOPBACK_NAMES = ("localhost",)
_SIGNALS = (signal.SIGINT, signal.SIGTERM)
#: Largest WebSocket message a stream client may send, bytes (beyond: closed with code 1009); the stream
#: reads and ignores what clients send.
MAX_WS_MESSAGE = 64 * 1024
#: Messages of a stream client buffered before its reader takes them (the stream takes them at once).
WS_QUEUE = 4
#: Wall seconds a silent keep-alive connection stays open after a response (uvicorn's timer).
KEEP_ALIVE = 5
#: Largest request head (request line and headers), bytes (beyond: 400).
MAX_HEAD = 16 * 1024
#: Connections the kernel queues before the server accepts them.
BACKLOG = 1024


def is_loopback(host: str) -> bool:
    """Whether ``host`` names only this machine (127.0.0.0/8, ::1, localhost)."""
    if host in _LOOPBACK_NAMES:
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def check_access(host: str, token: str | None, origins: tuple[str, ...] = ()) -> None:
    """Refuse to listen beyond the loopback without a token, short or unprintable tokens, malformed origins.

    Raises:
        UsageError: A non-loopback host without ``--token``, a token under :data:`MIN_TOKEN` characters or
            with control characters (:func:`simrun.serve.access.check_token`), an ``--allow-origin`` that is
            not ``scheme://host[:port]``.
    """
    from simrun.serve.access import check_token, normalise_origin

    if token is not None and len(token) < MIN_TOKEN:
        raise UsageError(f"--token must be at least {MIN_TOKEN} characters (e.g. from 'openssl rand -hex 16')")
    if token is not None:
        check_token(token)
    for origin in origins:
        normalise_origin(origin)
    if not is_loopback(host) and token is None:
        raise UsageError(
            f"--host {host} makes the world reachable from other machines: give --token TOKEN (or SIMRUN_TOKEN) "
            "so that only clients with it can drive the world"
        )


@dataclass
class Served:
    """What :func:`serve` did: the URL it listened on and the files written at shutdown."""

    url: str
    written: list[Path]
    error: str | None


def check_foxglove_mcap(path: Path, options: ServeOptions, world: Any) -> None:
    """Refuse a ``--foxglove-mcap`` target that is not ``.mcap``, is an input or a recording of the session.

    Raises:
        SimrunError: The target is refused (the message says why).
    """
    from meshtool.formats import check_suffix
    from simrun.outfile import check_output, scene_files

    wrong = check_suffix(path, "mcap")
    if wrong is not None:
        raise SimrunError(wrong, path=str(path))
    taken = [p for p in (options.record, options.record_mcap) if p is not None]
    check_output(path, inputs=[*scene_files(options.scene), *taken], world=world)


def bind(host: str, port: int) -> socket.socket:
    """A listening TCP socket on ``host:port`` (0: a free port).

    Raises:
        SimrunError: The address cannot be bound (in use, not this machine's).
    """
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind((host, port))
        sock.listen(BACKLOG)
    except OSError as exc:
        sock.close()
        raise SimrunError(f"cannot listen on {host}:{port}: {exc.strerror or exc}") from None
    sock.set_inheritable(True)
    return sock


def serve(
    options: ServeOptions,
    host: str = "127.0.0.1",
    port: int = 8765,
    token: str | None = None,
    on_ready: Callable[[str], None] | None = None,
    foxglove_port: int | None = None,
    foxglove_mcap: Path | None = None,
    allow_origins: tuple[str, ...] = (),
) -> Served:
    """Serve ``options.scene`` until SIGINT or SIGTERM.

    Args:
        options: The scene, mode and recording.
        host: Address to listen on (loopback by default; others need ``token``).
        port: TCP port (0: any free one).
        token: Bearer token every request must carry.
        on_ready: Called with the URL once the server listens (and with the Foxglove server's ``ws://`` URL).
        foxglove_port: Also serve the Foxglove WebSocket protocol on 127.0.0.1 at this port (0: a free one).
        foxglove_mcap: With ``foxglove_port``, also write what that server logs to this MCAP as it happens.
        allow_origins: Web origins (``https://app.example``) whose pages may use the server besides its own.

    Returns:
        The URL and the files written (the recording).

    Raises:
        SimrunError: A refused scene, recording target, address or access setting.
    """
    import uvicorn

    from simrun.serve.access import Access
    from simrun.serve.app import create_app
    from simrun.serve.connections import ConnectionTable, protocol_class
    from simrun.serve.page import dashboard_html

    check_access(host, token, allow_origins)
    written: list[Path] = []

    def start_recording(world: World, loop: SimLoop) -> Any:
        from simrun.serve.recording import LiveRecording

        assert options.record is not None
        return LiveRecording(
            world, loop, options.record, options.scene, options.record_sensors, options.seed or 0, options.record_mcap
        )

    loop = SimLoop(options, start_recording if options.record is not None else None)
    loop.start()
    takes = [0]

    def new_recording() -> Any:
        current = loop.recording
        if current is not None and current.active:
            from simrun.serve.catalogue import RequestError

            raise RequestError(409, "", f"already recording to {current.path}; stop it first")
        if current is not None:
            written.extend(current.written)
        takes[0] += 1
        assert options.record is not None and loop._world is not None
        target = options.record.with_name(f"{options.record.stem}-{takes[0] + 1}{options.record.suffix}")
        mcap = options.record_mcap
        if mcap is not None:
            mcap = mcap.with_name(f"{mcap.stem}-{takes[0] + 1}{mcap.suffix}")
        from simrun.serve.recording import LiveRecording

        loop.recording = LiveRecording(
            loop._world, loop, target, options.scene, options.record_sensors, options.seed or 0, mcap
        )
        return loop.recording.describe()

    try:
        sock = bind(host, port)
        if foxglove_port is not None:
            from simrun.serve.foxglove_live import FoxgloveLive

            if foxglove_mcap is not None:
                try:
                    check_foxglove_mcap(foxglove_mcap, options, loop._world)
                except SimrunError:
                    sock.close()
                    raise
            try:
                loop.foxglove = FoxgloveLive(foxglove_port, loop.catalogue, token, allow_origins, world=loop._world,
                                             mcap=foxglove_mcap)  # fmt: skip
            except Exception as exc:  # the SDK's own error (a port in use): one line
                sock.close()
                raise SimrunError(f"cannot start the Foxglove server on 127.0.0.1:{foxglove_port}: {exc}") from None
    except SimrunError:
        loop.stop()
        raise
    bound_port = sock.getsockname()[1]
    shown = f"[{host}]" if ":" in host else host
    url = f"http://{shown}:{bound_port}/"
    app = create_app(
        loop,
        Access.bound(host, bound_port, token, allow_origins),
        page=lambda: dashboard_html(loop.catalogue, token is not None, options.record is not None),
        recording=new_recording if options.record is not None else None,
    )
    # h11 (not httptools, whatever is installed: nicegui brings uvicorn[standard]) under the connection limits
    # of simrun.serve.connections, on asyncio: the limits in docs/limits.md ("Server") are these, measured so
    config = uvicorn.Config(
        app,
        log_level="warning",
        access_log=False,
        http=protocol_class(ConnectionTable()),
        loop="asyncio",
        ws="websockets",
        ws_per_message_deflate=False,
        ws_max_size=MAX_WS_MESSAGE,
        ws_max_queue=WS_QUEUE,
        timeout_keep_alive=KEEP_ALIVE,
        h11_max_incomplete_event_size=MAX_HEAD,
        backlog=BACKLOG,
        timeout_graceful_shutdown=3,
        lifespan="off",
    )
    server = uvicorn.Server(config)
    if on_ready is not None:
        original = server.startup

        async def startup(sockets: Any = None) -> None:
            await original(sockets)
            on_ready(url)
            if loop.foxglove is not None:
                on_ready(loop.foxglove.url)

        server.startup = startup  # type: ignore[method-assign]
    # uvicorn's handler only sets a flag; the world thread is told at once too, so a long lockstep step stops
    # at its next chunk and answers (never a signal inside MuJoCo, never an exit under a running step)
    uvicorn_exit = server.handle_exit

    def handle_exit(sig: int, frame: Any) -> None:
        loop.interrupt()
        uvicorn_exit(sig, frame)

    server.handle_exit = handle_exit  # type: ignore[method-assign]
    # uvicorn catches SIGINT/SIGTERM while it runs, then raises them again under the handlers it found:
    # with Python's defaults that would kill the process (SIGTERM) or raise KeyboardInterrupt before the
    # recording is written. Handlers that only note the signal make both a clean stop.
    caught: list[int] = []
    previous = {}
    if threading.current_thread() is threading.main_thread():
        previous = {sig: signal.signal(sig, lambda number, frame: caught.append(number)) for sig in _SIGNALS}
    try:
        server.run(sockets=[sock])
    finally:
        sock.close()
        loop.stop()
        if loop.foxglove is not None:
            loop.foxglove.close()
            if foxglove_mcap is not None:
                written.append(foxglove_mcap)
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    if loop.recording is not None:
        written.extend(loop.recording.written)
    return Served(url, written, loop.error)
