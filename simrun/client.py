"""A small Python client of ``simrun serve`` (standard-library HTTP, ``websockets`` for the stream).

Example::

    from simrun.client import Client

    sim = Client("http://127.0.0.1:8765/")
    drive = sim.service("DriveService", "boebot")
    drive.drive_distance(1.0)               # POST /api/services/DriveService/boebot/drive_distance
    while drive.state()["busy"]:            # GET  /api/services/DriveService/boebot
        time.sleep(0.1)
    x, y, z, *quat = sim.state()["poses"]["boebot"]

In a lockstep server, :meth:`Client.step` advances the world. A refusal raises :class:`ClientError`
with the HTTP status and the request field the server named.
"""

from __future__ import annotations

import json
import math
import urllib.error
import urllib.request
from collections.abc import Iterator
from typing import Any
from urllib.parse import quote, urlencode, urlsplit

from simrun.errors import SimrunError


class ClientError(SimrunError):
    """The server refused a request (``status``, ``field``) or could not be reached (``status`` 0)."""

    def __init__(self, message: str, status: int = 0, field: str = "") -> None:
        super().__init__(message)
        self.status, self.field = status, field


class Service:
    """One bound service: attribute calls are its commands (``drive.cmd_vel(0.1, 0.0)``)."""

    def __init__(self, client: Client, kind: str, entity: str) -> None:
        self._client, self.kind, self.entity = client, kind, entity

    def state(self) -> dict[str, Any]:
        """The service's queries now (``busy``, ``odometry``, ``encoders``...)."""
        return dict(self._client.get(f"/api/services/{quote(self.kind)}/{quote(self.entity)}")["state"])

    def call(self, name: str, *args: Any, **kwargs: Any) -> dict[str, Any]:
        """Call command ``name`` with positional or keyword arguments (not both)."""
        return self._client.call(self.kind, self.entity, name, *args, **kwargs)

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_"):
            raise AttributeError(name)
        return lambda *args, **kwargs: self.call(name, *args, **kwargs)


class Client:
    """A connection to a ``simrun serve`` server.

    Args:
        url: The server's address (``http://127.0.0.1:8765/``).
        token: The server's token, when it has one.
        timeout: Seconds to wait for an answer.
    """

    def __init__(self, url: str = "http://127.0.0.1:8765/", token: str | None = None, timeout: float = 30.0) -> None:
        parts = urlsplit(url)
        if parts.scheme not in ("http", "https") or not parts.netloc:
            raise ClientError(f"{url!r} is not an http:// address of a simrun server")
        self.base = f"{parts.scheme}://{parts.netloc}"
        self.token, self.timeout = token, timeout

    # -- HTTP ----------------------------------------------------------------------------------------------

    def _request(self, method: str, path: str, body: Any = None) -> bytes:
        data = None
        headers = {"Accept": "application/json"}
        if body is not None:
            data = json.dumps(body, allow_nan=False).encode("utf-8")
            headers["Content-Type"] = "application/json"
        if self.token:
            # a header carries latin-1 text only: any other token goes percent-encoded (the server decodes it)
            headers["Authorization"] = f"Bearer {self.token if self.token.isascii() else quote(self.token, safe='')}"
        request = urllib.request.Request(self.base + path, data=data, method=method, headers=headers)
        try:
            with urllib.request.urlopen(request, timeout=self.timeout) as response:
                return bytes(response.read())
        except urllib.error.HTTPError as exc:
            raw = exc.read()
            try:
                error = json.loads(raw)
                raise ClientError(f"{method} {path}: {error['error']}", exc.code, error.get("field", "")) from None
            except (ValueError, KeyError, TypeError):
                raise ClientError(f"{method} {path}: HTTP {exc.code}", exc.code) from None
        except (urllib.error.URLError, OSError) as exc:
            reason = getattr(exc, "reason", exc)
            raise ClientError(f"cannot reach {self.base}: {reason}") from None

    def get(self, path: str) -> Any:
        """``GET path`` as JSON."""
        return json.loads(self._request("GET", path))

    def post(self, path: str, body: Any = None) -> Any:
        """``POST path`` with a JSON body, as JSON."""
        return json.loads(self._request("POST", path, body if body is not None else {}))

    # -- the world -----------------------------------------------------------------------------------------

    def world(self) -> dict[str, Any]:
        """Entities, services (commands and their argument schemas, queries) and sensors."""
        return dict(self.get("/api/world"))

    def state(self) -> dict[str, Any]:
        """Time, mode, rates, recording and every body's pose (``[x, y, z, qw, qx, qy, qz]``, world frame, m)."""
        return dict(self.get("/api/state"))

    def pose(self, body: str) -> list[float]:
        """One body's world pose ``[x, y, z, qw, qx, qy, qz]`` (metres, unit quaternion)."""
        poses = self.state()["poses"]
        if body not in poses:
            raise ClientError(f"no body {body!r} (bodies: {', '.join(poses)})", 404, "body")
        return list(poses[body])

    def service(self, kind: str, entity: str) -> Service:
        """A bound service, whose commands are methods."""
        return Service(self, kind, entity)

    def call(self, kind: str, entity: str, name: str, *args: Any, **kwargs: Any) -> dict[str, Any]:
        """Call a service command now; returns ``{"time": applied at, "applied": true, ...}``."""
        if args and kwargs:
            raise ClientError("give a command's arguments by position or by name, not both")
        for value in (*args, *kwargs.values()):
            if isinstance(value, float) and not math.isfinite(value):
                raise ClientError(f"{name}: arguments must be finite numbers, got {value}", 0, "args")
        payload: dict[str, Any] = {"args": dict(kwargs) if kwargs else list(args)}
        return dict(self.post(f"/api/services/{quote(kind)}/{quote(entity)}/{quote(name)}", payload))

    def sensor(self, name: str) -> dict[str, Any]:
        """A sensor's latest reading: ``{"name", "time", "samples", "reading"}``."""
        return dict(self.get(f"/api/sensors/{quote(name)}"))

    def image(self, name: str, fmt: str = "png") -> bytes:
        """A camera's latest frame as PNG (or ``fmt="jpeg"``) bytes."""
        return self._request("GET", f"/api/sensors/{quote(name)}/image?format={quote(fmt)}")

    # -- time ----------------------------------------------------------------------------------------------

    def pause(self) -> dict[str, Any]:
        """Stop stepping."""
        return dict(self.post("/api/pause"))

    def resume(self) -> dict[str, Any]:
        """Step again in real time."""
        return dict(self.post("/api/resume"))

    def step(self, steps: int | None = None, seconds: float | None = None) -> dict[str, Any]:
        """Advance a lockstep (or paused) world by ``steps`` physics steps or ``seconds``; returns the state."""
        body: dict[str, Any] = {}
        if steps is not None:
            body["steps"] = steps
        if seconds is not None:
            body["seconds"] = seconds
        return dict(self.post("/api/step", body))

    def reset(self) -> dict[str, Any]:
        """Back to time 0."""
        return dict(self.post("/api/reset"))

    def set_rate(self, rate: float) -> dict[str, Any]:
        """Set the real-time factor."""
        return dict(self.post("/api/rate", {"rate": rate}))

    def start_recording(self) -> dict[str, Any]:
        """Start a new recording (to the server's ``--record`` path, numbered)."""
        return dict(self.post("/api/recording/start"))

    def stop_recording(self) -> dict[str, Any]:
        """Finish the recording; ``{"written": [paths]}``."""
        return dict(self.post("/api/recording/stop"))

    # -- the stream ----------------------------------------------------------------------------------------

    def stream(
        self, poses: bool = True, sensors: str | list[str] = "all", images: tuple[str, ...] | list[str] = ()
    ) -> Iterator[dict[str, Any]]:
        """The WebSocket stream: ``hello``, then ``poses``, ``sensor`` and ``image`` messages as they come.

        Args:
            poses: Receive body poses.
            sensors: ``"all"``, or the sensor names to receive.
            images: Camera sensors whose frames to receive (JPEG, base64 in ``data``).
        """
        from websockets.sync.client import connect

        query = {"poses": "1" if poses else "0", "sensors": sensors if isinstance(sensors, str) else ",".join(sensors)}
        if images:
            query["images"] = ",".join(images)
        if self.token:
            query["token"] = self.token
        url = "ws" + self.base.removeprefix("http") + "/api/stream?" + urlencode(query)
        with connect(url, open_timeout=self.timeout, max_size=2**24) as ws:
            for message in ws:
                item = json.loads(message)
                if item.get("type") == "error":
                    raise ClientError(f"stream: {item['error']}", int(item.get("status", 0)), item.get("field", ""))
                yield item
