"""The HTTP/JSON and WebSocket interface of ``simrun serve`` (Starlette, served by uvicorn).

Every route answers JSON; every refusal is ``{"error", "field", "status"}`` with a 4xx status naming the
request field (never a traceback). Request bodies are JSON objects of at most :data:`MAX_BODY` bytes,
sent as ``application/json`` (which also keeps other web sites' plain form posts out); ``NaN`` and
``Infinity`` are refused. The routes and their schemas are in ``GET /openapi.json``
(:mod:`simrun.serve.openapi`), versioned by :data:`simrun.serve.openapi.API_VERSION`.

Access (:class:`Guard`): with a token every request needs ``Authorization: Bearer TOKEN`` (or
``?token=TOKEN``, for a browser's first page load and WebSockets); without one, only requests whose
``Host`` is the loopback address the server listens on are answered (a DNS-rebinding page cannot reach
it). WebSocket handshakes from a page of another origin are refused.
"""

from __future__ import annotations

import asyncio
import contextlib
import hmac
import json
import math
from collections.abc import Callable
from typing import Any
from urllib.parse import parse_qs, urlsplit

from starlette.applications import Starlette
from starlette.exceptions import HTTPException
from starlette.requests import Request
from starlette.responses import HTMLResponse, JSONResponse, Response
from starlette.routing import Route, WebSocketRoute
from starlette.types import ASGIApp, Receive, Scope, Send
from starlette.websockets import WebSocket, WebSocketDisconnect

from simrun.errors import SimrunError
from simrun.serve.catalogue import RequestError, command_from_request, plain, service_queries
from simrun.serve.loop import CALL_TIMEOUT, MAX_RATE, MAX_STEPS, MIN_RATE, SimLoop, Subscriber, encode_png
from simrun.serve.openapi import API_VERSION, openapi_document

#: Largest request body, bytes.
MAX_BODY = 64 * 1024
#: Most WebSocket clients at once.
MAX_STREAMS = 64


class Guard:
    """ASGI middleware: the token, or (without one) loopback ``Host`` names only; same-origin WebSockets.

    Args:
        app: The application.
        token: The required token, or ``None``.
        hosts: ``Host`` header values accepted without a token (``127.0.0.1:8765``, ``localhost:8765``).
    """

    def __init__(self, app: ASGIApp, token: str | None, hosts: set[str]) -> None:
        self.app, self.token, self.hosts = app, token, hosts

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        """Answer the request, or refuse it (401/403 JSON; WebSocket close 1008)."""
        if scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        headers = {k.decode("latin-1").lower(): v.decode("latin-1") for k, v in scope.get("headers", [])}
        problem = self._refusal(scope, headers)
        if problem is None:
            await self.app(scope, receive, send)
            return
        status, message = problem
        if scope["type"] == "websocket":
            await send({"type": "websocket.close", "code": 1008, "reason": message[:120]})
            return
        body = json.dumps({"error": message, "field": "authorization" if status == 401 else "host", "status": status})
        response = Response(body, status, media_type="application/json")
        await response(scope, receive, send)

    def _refusal(self, scope: Scope, headers: dict[str, str]) -> tuple[int, str] | None:
        host = headers.get("host", "")
        if self.token is not None:
            given = headers.get("authorization", "").removeprefix("Bearer ").strip()
            if not given:
                given = (parse_qs(scope.get("query_string", b"").decode("latin-1")).get("token") or [""])[0]
            if not hmac.compare_digest(given.encode(), self.token.encode()):
                return 401, "missing or wrong token: send 'Authorization: Bearer TOKEN' (or ?token=TOKEN)"
        elif host not in self.hosts:
            return 403, f"Host {host!r} is not this server's loopback address; use http://{sorted(self.hosts)[0]}/"
        origin = headers.get("origin")
        if scope["type"] == "websocket" and origin and urlsplit(origin).netloc != host:
            return 403, f"WebSocket from another origin ({origin}) refused"
        return None


async def _body(request: Request) -> Any:
    """The request's JSON body (``None`` when empty).

    Raises:
        RequestError: 413 too large, 415 not JSON, 400 malformed (NaN and Infinity refused).
    """
    chunks, size = [], 0
    async for chunk in request.stream():
        size += len(chunk)
        if size > MAX_BODY:
            raise RequestError(413, "body", f"larger than {MAX_BODY} bytes")
        chunks.append(chunk)
    raw = b"".join(chunks)
    if not raw.strip():
        return None
    kind = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if kind != "application/json":
        raise RequestError(415, "content-type", f"send the body as application/json, not {kind or 'nothing'!r}")
    try:
        return json.loads(raw.decode("utf-8"), parse_constant=_refuse_constant)
    except (UnicodeDecodeError, ValueError) as exc:
        raise RequestError(400, "body", f"not valid JSON ({exc})") from None


def _refuse_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a JSON number")


def _object(body: Any, known: tuple[str, ...]) -> dict[str, Any]:
    """``body`` as an object with only ``known`` fields (``None``: empty)."""
    if body is None:
        return {}
    if not isinstance(body, dict):
        raise RequestError(422, "body", f"expected a JSON object, got {type(body).__name__}")
    for key in body:
        if key not in known:
            raise RequestError(422, str(key), f"unknown field (known: {', '.join(known) or 'none'})")
    return body


def _number(body: dict[str, Any], key: str, low: float, high: float, integer: bool = False) -> float:
    value = body[key]
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise RequestError(422, key, f"expected a finite number, got {value!r}")
    if integer and not float(value).is_integer():
        raise RequestError(422, key, f"expected a whole number, got {value!r}")
    if not low <= value <= high:
        raise RequestError(422, key, f"must be in [{low:g}, {high:g}], got {value!r}")
    return float(value)


def create_app(
    loop: SimLoop,
    token: str | None = None,
    hosts: set[str] | None = None,
    page: Callable[[], str] | None = None,
    recording: Callable[[], Any] | None = None,
) -> ASGIApp:
    """The ASGI application serving ``loop``.

    Args:
        loop: The running simulation loop.
        token: Required bearer token, or ``None`` (then only ``hosts`` are answered).
        hosts: Accepted ``Host`` values without a token.
        page: Returns the dashboard's HTML (``GET /``); ``None``: no dashboard.
        recording: Starts a new recording in the loop thread (``POST /api/recording/start``); ``None``: none.
    """
    catalogue = loop.catalogue
    services = [{"type": s["type"], "entity": s["entity"]} for s in catalogue["services"]]
    document = openapi_document(catalogue)
    streams: list[Subscriber] = []

    async def run(fn: Callable[[Any], Any]) -> Any:
        future = loop.call(fn)
        try:
            return await asyncio.wait_for(asyncio.wrap_future(future), CALL_TIMEOUT)
        except TimeoutError:
            raise RequestError(503, "", f"the simulation did not answer within {CALL_TIMEOUT:g} s") from None

    async def index(request: Request) -> Response:
        if page is None:
            raise RequestError(404, "path", "this server has no dashboard")
        try:
            text = page()
        except SimrunError as exc:  # the viewer bundle is not installed: how to install it
            raise RequestError(503, "", str(exc)) from None
        return HTMLResponse(text, headers={"Cache-Control": "no-store"})

    async def openapi(request: Request) -> Response:
        return JSONResponse(document)

    async def api(request: Request) -> Response:
        return JSONResponse({"api_version": API_VERSION, "schema": "/openapi.json", "world": "/api/world"})

    async def world(request: Request) -> Response:
        return JSONResponse(catalogue)

    async def listing(request: Request) -> Response:
        return JSONResponse(catalogue[request.url.path.rsplit("/", 1)[1]])

    async def state(request: Request) -> Response:
        return JSONResponse(await run(loop.state))

    async def service_state(request: Request) -> Response:
        kind, entity = request.path_params["service"], request.path_params["entity"]
        if not any(s["type"] == kind and s["entity"] == entity for s in services):
            command_from_request(services, kind, entity, "", None)  # raises the 404 naming the field

        def read(w: Any) -> Any:
            target = w.service(kind, entity)
            values = {}
            for name in service_queries(type(target)):
                value = getattr(target, name)
                values[name] = plain(value() if callable(value) else value)
            return {"type": kind, "entity": entity, "time": float(w.data.time), "state": values}

        return JSONResponse(await run(read))

    async def service_call(request: Request) -> Response:
        p = request.path_params
        command = command_from_request(services, p["service"], p["entity"], p["call"], await _body(request))

        def call(w: Any) -> Any:
            result = loop.apply(command)(w)
            target = w.service(command.service, command.entity)
            if p["call"] in service_queries(type(target)):
                value = getattr(target, p["call"])
                result["result"] = plain(value() if callable(value) else value)
            return result

        return JSONResponse(await run(call))

    def sensor_name(request: Request) -> str:
        name = request.path_params["name"]
        if not any(s["name"] == name for s in catalogue["sensors"]):
            known = ", ".join(s["name"] for s in catalogue["sensors"]) or "none"
            raise RequestError(404, "name", f"no sensor {name!r} (sensors: {known})")
        return str(name)

    async def sensor(request: Request) -> Response:
        name = sensor_name(request)

        def read(w: Any) -> Any:
            s = w.sensors[name]
            return {"name": name, "time": float(w.data.time), "samples": int(s.samples), "reading": plain(s.reading)}

        return JSONResponse(await run(read))

    async def sensor_image(request: Request) -> Response:
        name = sensor_name(request)
        if not next(s for s in catalogue["sensors"] if s["name"] == name)["image"]:
            raise RequestError(404, "name", f"sensor {name!r} is not a camera")
        fmt = request.query_params.get("format", "png")
        if fmt not in ("png", "jpeg"):
            raise RequestError(422, "format", f"expected png or jpeg, got {fmt!r}")

        def read(w: Any) -> Any:
            reading = w.sensors[name].reading
            rgb = getattr(reading, "rgb", None)
            if rgb is None and reading is not None:
                rgb = reading.left.rgb
            return rgb

        rgb = await run(read)
        if rgb is None:
            raise RequestError(409, "name", f"camera {name!r} has no frame yet; let the world run")
        if fmt == "png":
            return Response(encode_png(rgb), media_type="image/png")
        import base64

        from simrun.serve.loop import encode_jpeg

        return Response(base64.b64decode(encode_jpeg(rgb)), media_type="image/jpeg")

    async def pause(request: Request) -> Response:
        _object(await _body(request), ())
        return JSONResponse(await run(loop.set_paused(True)))

    async def resume(request: Request) -> Response:
        _object(await _body(request), ())
        return JSONResponse(await run(loop.set_paused(False)))

    async def step(request: Request) -> Response:
        body = _object(await _body(request), ("steps", "seconds"))
        if "steps" in body and "seconds" in body:
            raise RequestError(422, "seconds", "give steps or seconds, not both")
        if "seconds" in body:
            seconds = _number(body, "seconds", 0.0, MAX_STEPS * catalogue["timestep"])
            steps = round(seconds / catalogue["timestep"])
        else:
            steps = int(_number(body, "steps", 1, MAX_STEPS, integer=True)) if "steps" in body else 1
        return JSONResponse(await run(loop.step_request(steps)))

    async def reset(request: Request) -> Response:
        _object(await _body(request), ())
        return JSONResponse(await run(loop.reset()))

    async def rate(request: Request) -> Response:
        body = _object(await _body(request), ("rate",))
        if "rate" not in body:
            raise RequestError(422, "rate", f"missing; give the real-time factor in [{MIN_RATE:g}, {MAX_RATE:g}]")
        return JSONResponse(await run(loop.set_rate(_number(body, "rate", MIN_RATE, MAX_RATE))))

    async def recording_start(request: Request) -> Response:
        _object(await _body(request), ())
        if recording is None:
            raise RequestError(409, "", "this server records nowhere; start it with --record PATH")
        return JSONResponse(await run(lambda w: recording()))

    async def recording_stop(request: Request) -> Response:
        _object(await _body(request), ())

        def stop(w: Any) -> Any:
            current = loop.recording
            if current is None or not current.active:
                raise RequestError(409, "", "nothing is being recorded")
            written = current.finish()
            return {"written": [str(p) for p in written], "recording": current.describe()}

        return JSONResponse(await run(stop))

    async def scene_glb(request: Request) -> Response:
        from simrun.serve.page import world_glb

        return Response(await run(world_glb), media_type="model/gltf-binary")

    async def stream(ws: WebSocket) -> None:
        query = ws.query_params
        names = {s["name"] for s in catalogue["sensors"]}
        cameras = {s["name"] for s in catalogue["sensors"] if s["image"]}
        wanted = query.get("sensors", "all")
        sensors = None if wanted == "all" else {n for n in wanted.split(",") if n}
        images = {n for n in query.get("images", "").split(",") if n}
        problem: tuple[int, str, str] | None = None
        missing, not_cameras = sorted((sensors or set()) - names), sorted(images - cameras)
        if missing:
            problem = (422, "sensors", f"no sensor {missing[0]!r} (sensors: {', '.join(sorted(names)) or 'none'})")
        elif not_cameras:
            problem = (422, "images", f"no camera {not_cameras[0]!r} (cameras: {', '.join(sorted(cameras)) or 'none'})")
        elif query.get("poses", "1") not in ("0", "1"):
            problem = (422, "poses", "poses must be 0 or 1")
        elif len(streams) >= MAX_STREAMS:
            problem = (503, "", f"{MAX_STREAMS} streams are open; try later")
        await ws.accept()
        if problem is not None:
            status, field, message = problem
            await ws.send_text(json.dumps({"type": "error", "error": message, "field": field, "status": status}))
            await ws.close(1008)
            return
        sub = Subscriber(asyncio.get_running_loop(), sensors, query.get("poses", "1") == "1", images)
        streams.append(sub)
        loop.broadcast.add(sub)
        try:
            await ws.send_text(json.dumps({"type": "hello", "api_version": API_VERSION, "state": loop.latest()}))
            receiver = asyncio.ensure_future(ws.receive())
            while not receiver.done():
                waiter = asyncio.ensure_future(sub.ready.wait())
                await asyncio.wait({receiver, waiter}, return_when=asyncio.FIRST_COMPLETED)
                waiter.cancel()
                sub.ready.clear()
                while sub.messages and not receiver.done():
                    await ws.send_text(sub.messages.popleft())
                if receiver.done() and receiver.result().get("type") == "websocket.receive":
                    receiver = asyncio.ensure_future(ws.receive())  # clients may send; nothing is read from it
            receiver.cancel()
        except (WebSocketDisconnect, RuntimeError, OSError):
            pass
        finally:
            loop.broadcast.remove(sub)
            streams.remove(sub)
            with contextlib.suppress(Exception):
                await ws.close()

    async def refused(request: Request, exc: Exception) -> Response:
        assert isinstance(exc, RequestError)
        return JSONResponse(exc.body(), exc.status)

    async def http_error(request: Request, exc: Exception) -> Response:
        assert isinstance(exc, HTTPException)
        field = "path" if exc.status_code == 404 else "method" if exc.status_code == 405 else ""
        message = {404: f"no route {request.url.path}; see /openapi.json", 405: f"{request.method} not allowed here"}
        body = {"error": message.get(exc.status_code, str(exc.detail)), "field": field, "status": exc.status_code}
        return JSONResponse(body, exc.status_code)

    async def library_refusal(request: Request, exc: Exception) -> Response:
        # simrun refused what was asked (a world without visual geoms has no scene.glb...): one line, 422
        return JSONResponse({"error": str(exc).splitlines()[0] if str(exc) else "", "field": "", "status": 422}, 422)

    async def internal(request: Request, exc: Exception) -> Response:
        return JSONResponse({"error": f"internal error: {type(exc).__name__}", "field": "", "status": 500}, 500)

    routes = [
        Route("/", index),
        Route("/openapi.json", openapi),
        Route("/api", api),
        Route("/api/world", world),
        Route("/api/entities", listing),
        Route("/api/services", listing),
        Route("/api/sensors", listing),
        Route("/api/state", state),
        Route("/api/scene.glb", scene_glb),
        Route("/api/services/{service}/{entity:path}/{call}", service_call, methods=["POST"]),
        Route("/api/services/{service}/{entity:path}", service_state),
        Route("/api/sensors/{name}", sensor),
        Route("/api/sensors/{name}/image", sensor_image),
        Route("/api/pause", pause, methods=["POST"]),
        Route("/api/resume", resume, methods=["POST"]),
        Route("/api/step", step, methods=["POST"]),
        Route("/api/reset", reset, methods=["POST"]),
        Route("/api/rate", rate, methods=["POST"]),
        Route("/api/recording/start", recording_start, methods=["POST"]),
        Route("/api/recording/stop", recording_stop, methods=["POST"]),
        WebSocketRoute("/api/stream", stream),
    ]
    app = Starlette(
        routes=routes,
        exception_handlers={
            RequestError: refused,
            SimrunError: library_refusal,
            HTTPException: http_error,
            Exception: internal,
        },
    )
    return Guard(app, token, hosts or set())
