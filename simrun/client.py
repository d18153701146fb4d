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
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from typing import Any, NoReturn
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
        retries: Times a request the server's budgets refuse (``429``: it did not run) is sent again, each
            after the ``Retry-After`` seconds the server gives; ``0``: a 429 is raised at once.
    """

    def __init__(
        self, url: str = "http://127.0.0.1:8765/", token: str | None = None, timeout: float = 30.0, retries: int = 10
    ) -> None:
        parts = urlsplit(url)
        if parts.scheme not in ("http", "https") or not parts.netloc:
            raise ClientError(f"{url!r} is not an http:// address of a simrun server")
        self.base = f"{parts.scheme}://{parts.netloc}"
        self.token, self.timeout, self.retries = token, timeout, retries

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
        for attempt in range(self.retries + 1):
            try:
                with urllib.request.urlopen(request, timeout=self.timeout) as response:
                    return bytes(response.read())
            except urllib.error.HTTPError as exc:
                if exc.code != 429 or attempt == self.retries:
                    self._refused(method, path, exc)
                exc.read()
                wait = exc.headers.get("Retry-After", "1")
                time.sleep(min(30.0, max(0.1, float(wait) if wait.replace(".", "", 1).isdigit() else 1.0)))
            except (urllib.error.URLError, OSError) as exc:
                reason = getattr(exc, "reason", exc)
                raise ClientError(f"cannot reach {self.base}: {reason}") from None
        raise AssertionError("unreachable")  # the last attempt returns or raises

    @staticmethod
    def _refused(method: str, path: str, exc: urllib.error.HTTPError) -> NoReturn:
        """Raise the server's refusal as a :class:`ClientError` (its message, status and field)."""
        raw = exc.read()
        try:
            error = json.loads(raw)
        except ValueError:
            error = None
        if isinstance(error, dict) and isinstance(error.get("error"), str):
            raise ClientError(f"{method} {path}: {error['error']}", exc.code, str(error.get("field", "")))
        raise ClientError(f"{method} {path}: HTTP {exc.code}", exc.code)

    def get(self, path: str) -> Any:
        """``GET path`` as JSON."""
        return json.loads(self._request("GET", path))

    def post(self, path: str, body: Any = None) -> Any:
        """``POST path`` with a JSON body, as JSON."""
        return json.loads(self._request("POST", path, body if body is not None else {}))

    def patch(self, path: str, body: Any) -> Any:
        """``PATCH path`` with a JSON body, as JSON."""
        return json.loads(self._request("PATCH", path, body))

    def delete(self, path: str) -> Any:
        """``DELETE path`` (an empty JSON body), as JSON."""
        return json.loads(self._request("DELETE", path, {}))

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

    # -- editing (simrun serve --edit; docs/serve.md "Editing the world") -----------------------------------

    def entities(self) -> list[dict[str, Any]]:
        """Every entity: ``name``, ``type``, ``parent``, ``values`` (its scene table), ``pose`` (world, now)..."""
        return list(self.get("/api/entities"))

    def entity(self, name: str) -> dict[str, Any]:
        """One entity, with ``schema``: its type's keys (type, unit, default, description)."""
        return dict(self.get(f"/api/entities/{quote(name)}"))

    def edit_info(self) -> dict[str, Any]:
        """Whether edits are allowed, the limits, and every registered type's schema (``types``)."""
        return dict(self.get("/api/edit"))

    def insert(self, table: dict[str, Any] | list[dict[str, Any]], parent: str | None = None) -> list[str]:
        """Insert an entity from its scene table (or a list of them); returns the full names inserted."""
        body: dict[str, Any] = {"entity" if isinstance(table, dict) else "entities": table}
        if parent is not None:
            body["parent"] = parent
        return list(self.post("/api/entities", body)["inserted"])

    def change(self, name: str, changes: dict[str, Any] | None = None, **keys: Any) -> dict[str, Any]:
        """Change an entity's keys (``change("box", mass=2.0)``, ``change("floor", {"material": {...}})``)."""
        return dict(self.patch(f"/api/entities/{quote(name)}", {**(changes or {}), **keys})["entity"])

    def remove(self, name: str) -> dict[str, list[str]]:
        """Remove an entity, its children and their services and sensors; returns what went."""
        return dict(self.delete(f"/api/entities/{quote(name)}")["removed"])

    def teleport(
        self, name: str, position: Any, orientation: Any = None, keep_velocity: bool = False
    ) -> dict[str, Any]:
        """Move an entity to a pose relative to its parent (m, unit quaternion w, x, y, z)."""
        body: dict[str, Any] = {"position": list(position), "keep_velocity": keep_velocity}
        if orientation is not None:
            body["orientation"] = list(orientation)
        return dict(self.post(f"/api/entities/{quote(name)}/teleport", body))

    def apply_force(
        self, name: str, force: Any = (0.0, 0.0, 0.0), torque: Any = (0.0, 0.0, 0.0), duration: float = 0.1,
        body: str | None = None,
    ) -> dict[str, Any]:  # fmt: skip
        """Push a body: force (N) and torque (N m), world frame, for ``duration`` simulated seconds."""
        payload: dict[str, Any] = {"force": list(force), "torque": list(torque), "duration": duration}
        if body is not None:
            payload["body"] = body
        return dict(self.post(f"/api/entities/{quote(name)}/force", payload))

    def set_gravity(self, gravity: Any) -> dict[str, Any]:
        """Change the world's gravity (m/s^2)."""
        return dict(self.post("/api/edit/world", {"gravity": list(gravity)}))

    def change_service(self, kind: str, entity: str, **settings: Any) -> dict[str, Any]:
        """Change a bound service's settings (``rate``, ``limits``...)."""
        return dict(self.patch(f"/api/edit/services/{quote(kind)}/{quote(entity)}", settings))

    def add_service(self, table: dict[str, Any]) -> dict[str, Any]:
        """Bind a service from a ``[[services]]`` table."""
        return dict(self.post("/api/edit/services", {"service": table}))

    def remove_service(self, kind: str, entity: str) -> dict[str, Any]:
        """Unbind a service."""
        return dict(self.delete(f"/api/edit/services/{quote(kind)}/{quote(entity)}"))

    def change_sensor(self, name: str, **settings: Any) -> dict[str, Any]:
        """Change a sensor's settings (``rate``, ``noise``, ``seed``...)."""
        return dict(self.patch(f"/api/edit/sensors/{quote(name)}", settings))

    def add_sensor(self, table: dict[str, Any]) -> dict[str, Any]:
        """Add a sensor from a ``[[sensors]]`` table."""
        return dict(self.post("/api/edit/sensors", {"sensor": table}))

    def remove_sensor(self, name: str) -> dict[str, Any]:
        """Remove a sensor."""
        return dict(self.delete(f"/api/edit/sensors/{quote(name)}"))

    def save_scene(self, path: str | None = None, state: str = "initial") -> str:
        """The world as scene TOML (entities at their current poses); written to ``path`` when given.

        Relative paths in the text are rewritten for ``path``'s folder (the server's machine must see it:
        a client on another machine saves the text as it comes, relative to the served scene's folder).
        """
        return self._saved("/api/edit/save", {"state": state}, path)

    def save_entities(self, names: list[str], path: str | None = None) -> str:
        """The named entities (and those below them) as an entities file's text; written to ``path`` when given."""
        return self._saved("/api/edit/save-entities", {"names": list(names)}, path)

    def _saved(self, route: str, body: dict[str, Any], path: str | None) -> str:
        from pathlib import Path

        if path is not None:
            body["folder"] = str(Path(path).resolve().parent)
        text = str(self.post(route, body)["toml"])
        if path is not None:
            from simrun.outfile import write_text

            write_text(Path(path), text)
        return text

    def load_entities(self, text: str, parent: str | None = None) -> dict[str, list[str]]:
        """Insert the entities of an entities file's text (its paths relative to the served scene's folder)."""
        body: dict[str, Any] = {"toml": text}
        if parent is not None:
            body["parent"] = parent
        return dict(self.post("/api/edit/load-entities", body)["added"])

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
