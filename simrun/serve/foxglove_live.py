"""The live world in the Foxglove WebSocket protocol (``simrun serve --foxglove-port N``), through foxglove-sdk.

Foxglove (the app, or any client of its protocol) connects to ``ws://127.0.0.1:N`` and subscribes to:

* ``/tf``: ``foxglove.FrameTransforms``, each body's pose from ``world`` (Z up, metres), whenever the loop
  publishes poses (30 per simulated second, after every step request);
* ``/sensors/NAME``: ``foxglove.LaserScan`` for each laser, at its own rate (its robot's body frame, the scan
  origin ``height`` above it).

Log times are nanoseconds of simulated time, as in the MCAP export (:mod:`simrun.record.mcap_export`). The SDK's
server keeps at most :data:`BACKLOG` messages per client and drops the oldest, so a slow client never
slows the simulation. The server listens on the loopback address only (use an SSH tunnel from another
machine). The protocol has no authentication and the SDK's server checks no handshake, so the port is a
:class:`simrun.serve.gate.Gate` that applies the rules of the HTTP server (:mod:`simrun.serve.access`:
``Host``, ``Origin``, the token as ``?token=``) before it relays a connection to the SDK's server, which
listens on a port browsers may not open.
"""

from __future__ import annotations

from collections.abc import Iterable
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

    Attributes:
        port: The port it listens on.
    """

    def __init__(
        self, port: int, catalogue: dict[str, Any], token: str | None = None, origins: Iterable[str] = ()
    ) -> None:
        import foxglove
        from foxglove import channels

        from simrun.serve.access import Access
        from simrun.serve.gate import BROWSER_BLOCKED_PORTS, Gate

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
        self._tf = channels.FrameTransformsChannel("/tf", context=self._context)
        self._lasers = {
            s["name"]: (s, channels.LaserScanChannel(f"/sensors/{s['name']}", context=self._context))
            for s in catalogue["sensors"]
            if "height" in s
        }

    @property
    def url(self) -> str:
        """``ws://127.0.0.1:PORT``."""
        return f"ws://127.0.0.1:{self.port}"

    def poses(self, time: float, poses: dict[str, list[float]]) -> None:
        """Publish body poses (``[x, y, z, qw, qx, qy, qz]`` by body name) at simulated ``time`` seconds."""
        from foxglove import messages as fm

        stamp = _stamp(time)
        transforms = [
            fm.FrameTransform(
                timestamp=stamp,
                parent_frame_id="world",
                child_frame_id=name,
                translation=fm.Vector3(x=p[0], y=p[1], z=p[2]),
                rotation=fm.Quaternion(x=p[4], y=p[5], z=p[6], w=p[3]),
            )
            for name, p in poses.items()
        ]
        self._tf.log(fm.FrameTransforms(transforms=transforms), log_time=round(time * 1e9))

    def sensor(self, name: str, time: float, reading: Any) -> None:
        """Publish a laser's scan (other sensors are not in this stream)."""
        from foxglove import messages as fm

        if name not in self._lasers or reading is None:
            return
        info, channel = self._lasers[name]
        angles = [float(a) for a in reading.angles]
        scan = fm.LaserScan(
            timestamp=_stamp(time),
            frame_id=info["entity"],
            pose=fm.Pose(
                position=fm.Vector3(x=0.0, y=0.0, z=float(info["height"])),
                orientation=fm.Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
            ),
            start_angle=angles[0],
            end_angle=angles[-1],
            ranges=[float(r) for r in reading.ranges],
            intensities=[],
        )
        channel.log(scan, log_time=round(time * 1e9))

    def close(self) -> None:
        """Stop the gate and the server."""
        self._gate.close()
        self._server.stop()


def _stamp(time: float) -> Any:
    from foxglove import messages as fm

    ns = round(time * 1e9)
    return fm.Timestamp(ns // 1_000_000_000, ns % 1_000_000_000)
