"""The live world in the Foxglove WebSocket protocol (``simrun serve --foxglove-port N``), through foxglove-sdk.

Foxglove (the app, or any client of its protocol, ``foxglove.websocket.v1`` or the SDK's ``foxglove.sdk.v1``)
connects to ``ws://127.0.0.1:N`` and subscribes to the channels of
:class:`simrun.record.foxglove_channels.FoxgloveChannels`, the ones an MCAP export has: ``/clock``, ``/tf``,
``/scene``, ``/NAME/pose`` and ``/NAME/joint_states`` per robot, ``/NAME/odometry`` per drive service, all
logged whenever the loop publishes poses (``pose_rate`` per simulated second, after every step request), and
``/sensors/NAME`` (``/sensors/NAME/compressed`` for a webcam's JPEG) for every sensor, at each new reading
the loop publishes (at most :data:`simrun.serve.loop.MIN_SENSOR_INTERVAL` apart in wall time). The channels
follow edits (``simrun serve --edit``): an inserted robot's, an added drive's or sensor's channels are
advertised, a removed one's unadvertised, at the next publication after the edit.

With ``mcap``, every message the server logs is also written to that MCAP file as it happens (foxglove-sdk's
writer, a sink of the same context: the same channels and the same messages as the live stream;
``simrun serve --foxglove-mcap``), finished by :meth:`FoxgloveLive.close`.

Camera images are logged by a thread of their own (:class:`_ImageLogger`: the raw image and its JPEG), so the
simulation thread never encodes one; a camera whose frames come faster than they are encoded has its older
frames skipped (the latest is logged).

Log times are nanoseconds of simulated time, as in the MCAP export (:mod:`simrun.record.mcap_export`). The SDK's
server keeps at most :data:`BACKLOG` messages per client and drops the oldest, so a slow client never
slows the simulation. The server listens on the loopback address only (use an SSH tunnel from another
machine). The protocol has no authentication and the SDK's server checks no handshake, so the port is a
:class:`simrun.serve.gate.Gate` that applies the rules of the HTTP server (:mod:`simrun.serve.access`:
``Host``, ``Origin``, the token as ``?token=``) before it relays a connection to the SDK's server, which
listens on a port browsers may not open; the gate also lets a client offer the standard subprotocol.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import threading
from collections.abc import Iterable
from pathlib import Path
from typing import Any

#: Messages the Foxglove server buffers per client before it drops the oldest.
BACKLOG = 256


class FoxgloveLive:
    """A Foxglove WebSocket server fed by the simulation loop (its methods run in the loop thread).

    Args:
        port: TCP port on 127.0.0.1 (0: a free one).
        catalogue: The served world's catalogue (:func:`simrun.serve.catalogue.build_catalogue`).
        token: The server's token (clients give it as ``?token=`` or ``Authorization: Bearer``), or ``None``.
        origins: Web origins allowed besides the port's own (``--allow-origin``).
        world: The served world (read in the loop thread, when the loop publishes).
        mcap: Also write every message to this MCAP file (beside it until :meth:`close`, then renamed).

    Attributes:
        port: The port it listens on.
        channels: The channels and their message counts.
    """

    def __init__(
        self,
        port: int,
        catalogue: dict[str, Any],
        token: str | None = None,
        origins: Iterable[str] = (),
        *,
        world: Any,
        mcap: Path | None = None,
    ) -> None:
        import foxglove

        from simrun.record.foxglove_channels import FoxgloveChannels
        from simrun.serve.access import Access
        from simrun.serve.gate import BROWSER_BLOCKED_PORTS, Gate
        from simrun.services.drive_service import DriveService

        self._context = foxglove.Context()
        self._server: Any = None
        error: Exception | None = None
        for inner in BROWSER_BLOCKED_PORTS:  # the first free one (the SDK refuses a port in use)
            try:
                self._server = foxglove.start_server(name="simrun serve", host="127.0.0.1", port=inner,
                                                     context=self._context, message_backlog_size=BACKLOG)  # fmt: skip
                break
            except RuntimeError as exc:
                error = exc
        if self._server is None:
            raise RuntimeError(f"no free port for the server behind the gate ({error})")
        allowed = tuple(origins)
        try:
            self._gate = Gate(port, int(self._server.port), lambda p: Access.bound("127.0.0.1", p, token, allowed))
        except OSError:
            self._server.stop()
            raise
        self.port = self._gate.port
        self.mcap = mcap
        self._writer: Any = None
        self._tmp: str | None = None
        try:
            if mcap is not None:  # the writer of every MCAP simrun writes (the export's), on this context
                from simrun.record.mcap_export import open_writer, temporary_beside

                self._tmp = temporary_beside(mcap)
                self._writer = open_writer(self._tmp, self._context)
            self.channels = FoxgloveChannels(world, self._context)
        except BaseException:  # whatever stops it (Ctrl+C included): the SDK's server, the gate, the file go; re-raised
            self.close()
            raise
        self._world, self._drive_type = world, DriveService
        self._images = _ImageLogger(self.channels)

    @property
    def url(self) -> str:
        """``ws://127.0.0.1:PORT``."""
        return f"ws://127.0.0.1:{self.port}"

    def poses(self, time: float, poses: dict[str, list[float]]) -> None:
        """Log the world's frame at simulated ``time`` s (loop thread; ``poses`` are the published body poses).

        The messages come from the world's state (:meth:`FoxgloveChannels.frame`), the same state as ``poses``;
        each drive's odometry is its current estimate. The channels follow the world first
        (:meth:`FoxgloveChannels.refresh`): after an edit, a new robot's, drive's or sensor's channels are
        advertised and a removed one's unadvertised before this frame is logged.
        """
        self.channels.refresh()
        self.channels.frame()
        for drive in self._world.controllers:
            if isinstance(drive, self._drive_type):
                self.channels.odometry(drive.name, time, dataclasses.astuple(drive.odometry()))

    def sensor(self, name: str, time: float, reading: Any) -> None:
        """Log a sensor's reading taken at simulated ``time`` s (a camera's by the image thread)."""
        from simrun.serve.images import image_of

        self.channels.refresh()  # a sensor an edit added reads before the next frame: its channel first
        if image_of(reading) is not None:
            self._images.put(name, time, reading)
        else:
            self.channels.sensor(name, time, reading)

    def close(self) -> None:
        """Stop the gate and the server, and finish the MCAP (renamed over ``mcap``)."""
        images = getattr(self, "_images", None)
        if images is not None:
            images.close()  # the frames still waiting are logged first
        gate = getattr(self, "_gate", None)
        if gate is not None:
            gate.close()
        if self._server is not None:
            self._server.stop()
            self._server = None
        if self._writer is not None:
            self._writer.close()
            self._writer = None
            assert self._tmp is not None and self.mcap is not None
            os.chmod(self._tmp, 0o644)
            os.replace(self._tmp, self.mcap)
            self._tmp = None
        if self._tmp is not None:
            with contextlib.suppress(OSError):
                os.unlink(self._tmp)
            self._tmp = None


class _ImageLogger:
    """Logs camera readings through ``channels`` in its own thread (the latest frame of each camera waits)."""

    def __init__(self, channels: Any) -> None:
        self.channels = channels
        self._waiting: dict[str, tuple[float, Any]] = {}
        self._ready = threading.Condition()
        self._closed = False
        self._thread = threading.Thread(target=self._main, name="simrun-serve-foxglove-images", daemon=True)
        self._thread.start()

    def put(self, name: str, time: float, reading: Any) -> None:
        """Queue camera ``name``'s reading taken at simulated ``time`` s (readings are not changed once taken)."""
        with self._ready:
            self._waiting[name] = (time, reading)
            self._ready.notify()

    def close(self) -> None:
        """Log what waits, then stop the thread."""
        with self._ready:
            self._closed = True
            self._ready.notify()
        self._thread.join(30)

    def _main(self) -> None:
        while True:
            with self._ready:
                while not self._waiting and not self._closed:
                    self._ready.wait()
                if not self._waiting:
                    return
                name, (time, reading) = self._waiting.popitem()
            with contextlib.suppress(Exception):  # a channel that cannot log (closed at shutdown) loses the frame
                self.channels.sensor(name, time, reading)
