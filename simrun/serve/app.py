"""The HTTP/JSON and WebSocket interface of ``simrun serve`` (Starlette, served by uvicorn).

Every route answers JSON; every refusal is ``{"error", "field", "status"}`` with a 4xx status naming the
request field (never a traceback). Request bodies are JSON objects of at most :data:`MAX_BODY` bytes,
nested at most :data:`MAX_DEPTH` deep, sent as ``application/json`` (empty bodies too, which keeps other
web sites' plain form and ``text/plain`` posts out); ``NaN`` and ``Infinity`` are refused, and every number
must lie in the range its route's schema gives (:func:`check_numbers`). The routes and their schemas are in
``GET /openapi.json`` (:mod:`simrun.serve.openapi`), versioned by :data:`simrun.serve.openapi.API_VERSION`.
Each client address has a request budget (:class:`simrun.serve.request_budget.RequestBudget`: 429 beyond).

Access (:class:`Guard`, the rules of :mod:`simrun.serve.access`): every request and WebSocket handshake
must name this server in ``Host`` (a DNS-rebinding page cannot reach it), come from the server's own
origin or an allowed one when a browser sends ``Origin``, and carry the token when the server has one
(``Authorization: Bearer TOKEN``, or ``?token=TOKEN`` for a browser's first page load and WebSockets).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import math
import re
from collections.abc import Callable
from typing import Any

from starlette.applications import Starlette
from starlette.exceptions import HTTPException
from starlette.requests import ClientDisconnect, Request
from starlette.responses import HTMLResponse, JSONResponse, Response
from starlette.routing import Route, WebSocketRoute
from starlette.types import ASGIApp, Receive, Scope, Send
from starlette.websockets import WebSocket, WebSocketDisconnect

from simrun.errors import SimrunError
from simrun.serve.access import Access
from simrun.serve.catalogue import RequestError, command_from_request, plain, service_queries
from simrun.serve.edit_routes import edit_routes
from simrun.serve.images import FORMATS, encode_jpeg_bytes, encode_png, image_of
from simrun.serve.loop import CALL_TIMEOUT, MAX_RATE, MAX_STEPS, MIN_RATE, REALTIME_STEP, SimLoop, Subscriber
from simrun.serve.openapi import API_VERSION, MAX_ARGUMENT, openapi_document
from simrun.serve.request_budget import RequestBudget, budgets

#: Largest request body, bytes.
MAX_BODY = 64 * 1024
#: Wall seconds a request body may take to arrive, from the handler's first read.
BODY_TIMEOUT = 10.0
#: Most WebSocket clients at once.
MAX_STREAMS = 64


class Guard:
    """ASGI middleware: the ``Host``, ``Origin`` and token rules of :class:`simrun.serve.access.Access`.

    Args:
        app: The application.
        access: The rules (HTTP requests and WebSocket handshakes alike).
    """

    def __init__(self, app: ASGIApp, access: Access) -> None:
        self.app, self.access = app, access

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        """Answer the request, or refuse it (401/403 with the JSON error, a WebSocket handshake too)."""
        if scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        headers = {k.decode("latin-1").lower(): v.decode("latin-1") for k, v in scope.get("headers", [])}
        problem = self.access.refusal(headers, scope.get("query_string", b""))
        if problem is None:
            await self.app(scope, receive, send)
            return
        body = json.dumps({"error": problem.message, "field": problem.field, "status": problem.status}).encode()
        if scope["type"] == "websocket":
            if "websocket.http.response" not in scope.get("extensions", {}):  # closed unaccepted: uvicorn says 403
                await send({"type": "websocket.close", "code": 1008, "reason": problem.message[:120]})
                return
            # the handshake is answered like an HTTP request: the status and the JSON error
            raw = [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode())]
            await send({"type": "websocket.http.response.start", "status": problem.status, "headers": raw})
            await send({"type": "websocket.http.response.body", "body": body})
            return
        response = Response(body, problem.status, media_type="application/json")
        await response(scope, receive, send)


#: Deepest nesting of arrays and objects in a request body (checked on the bytes, before parsing).
MAX_DEPTH = 32
_STRUCTURE = re.compile(rb'"(?:[^"\\]|\\.)*"|[\[\]{}]', re.DOTALL)


def json_depth(raw: bytes, limit: int = MAX_DEPTH) -> int:
    """How deep arrays and objects nest in the JSON text ``raw`` (strings skipped), counting stops past ``limit``."""
    depth = deepest = 0
    for match in _STRUCTURE.finditer(raw):
        c = match.group()[0]
        if c in b"[{":
            depth += 1
            if depth > deepest:
                deepest = depth
                if deepest > limit:
                    break
        elif c in b"]}":
            depth -= 1
    return deepest


async def _body(request: Request, schema: dict[str, Any] | None = None) -> Any:
    """The request's JSON body (``None`` when empty), its numbers checked against ``schema``.

    Every body, an empty one too, must be sent as ``application/json``: a page of another site can send
    ``text/plain`` or a form without asking, never ``application/json``.

    Raises:
        RequestError: 413 too large, 408 not all there within :data:`BODY_TIMEOUT`, 415 not JSON, 400 malformed
            (NaN and Infinity refused) or nested deeper than :data:`MAX_DEPTH`, 422 a number out of its range
            (:func:`check_numbers`), 400 the client left before its body arrived.
    """
    kind = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if kind != "application/json":
        raise RequestError(415, "content-type", f"send the body as application/json, not {kind or 'nothing'!r}")
    chunks: list[bytes] = []
    try:
        async with asyncio.timeout(BODY_TIMEOUT):
            size = 0
            async for chunk in request.stream():
                size += len(chunk)
                if size > MAX_BODY:
                    raise RequestError(413, "body", f"larger than {MAX_BODY} bytes")
                chunks.append(chunk)
    except TimeoutError:
        raise RequestError(408, "body", f"the body did not arrive within {BODY_TIMEOUT:g} s") from None
    except ClientDisconnect:  # nobody is left to answer; no traceback in the log
        raise RequestError(400, "body", "the client closed the connection before its body arrived") from None
    raw = b"".join(chunks)
    if not raw.strip():
        return None
    if json_depth(raw) > MAX_DEPTH:
        raise RequestError(400, "body", f"arrays and objects nest deeper than {MAX_DEPTH} levels")
    try:
        body = json.loads(raw.decode("utf-8"), parse_constant=_refuse_constant)
    except (UnicodeDecodeError, ValueError) as exc:
        raise RequestError(400, "body", f"not valid JSON ({exc})") from None
    check_numbers(body, schema or {})
    return body


def _refuse_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a JSON number")


def _shown(value: int | float) -> str:
    """A number for a message (an integer of hundreds of digits by its length)."""
    text = repr(value)
    return text if len(text) <= 24 else f"an integer of {len(text.lstrip('-'))} digits"


def check_numbers(value: Any, schema: dict[str, Any], field: str = "") -> None:
    """Refuse any number in ``value`` outside its range in ``schema`` (the route's OpenAPI request schema).

    The walk follows ``properties``, ``oneOf`` (an array or an object), ``prefixItems`` (named by their
    ``title``) and ``items``; a number whose schema gives no range must be within
    +-:data:`simrun.serve.openapi.MAX_ARGUMENT`. NaN and infinity are left to the route's own checks;
    booleans are not numbers.

    Raises:
        RequestError: 422 naming the field (``steps``, ``args.metres``) and its allowed range.
    """
    for option in schema.get("oneOf", ()):
        if (option.get("type") == "array") == isinstance(value, list):
            schema = option
            break
    if isinstance(value, dict):
        properties = schema.get("properties", {})
        for key, item in value.items():
            check_numbers(item, properties.get(key, {}), f"{field}.{key}" if field else str(key))
    elif isinstance(value, list):
        prefix = schema.get("prefixItems", [])
        for index, item in enumerate(value):
            inner = prefix[index] if index < len(prefix) else schema.get("items", {})
            name = inner.get("title")
            check_numbers(item, inner, f"{field}.{name}" if name and field else field)
    elif isinstance(value, int | float) and not isinstance(value, bool):
        if isinstance(value, float) and not math.isfinite(value):
            return
        low = schema.get("minimum", -MAX_ARGUMENT)
        high = schema.get("maximum", MAX_ARGUMENT)
        if not low <= value <= high:
            raise RequestError(422, field or "body", f"must be in [{low:g}, {high:g}], got {_shown(value)}")


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
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise RequestError(422, key, f"expected a finite number, got {value!r}"[:200])
    if isinstance(value, float) and not math.isfinite(value):
        raise RequestError(422, key, f"expected a finite number, got {value!r}")
    if not low <= value <= high:  # an int compares exactly, however large
        raise RequestError(422, key, f"must be in [{low:g}, {high:g}], got {_shown(value)}")
    if integer and isinstance(value, float) and not value.is_integer():
        raise RequestError(422, key, f"expected a whole number, got {value!r}")
    return float(value)


def create_app(
    loop: SimLoop,
    access: Access,
    page: Callable[[], str] | None = None,
    recording: Callable[[], Any] | None = None,
) -> ASGIApp:
    """The ASGI application serving ``loop``.

    Args:
        loop: The running simulation loop.
        access: Who may talk to it (``Host``, ``Origin``, token).
        page: Returns the dashboard's HTML (``GET /``); ``None``: no dashboard.
        recording: Starts a new recording in the loop thread (``POST /api/recording/start``); ``None``: none.
    """
    streams: list[Subscriber] = []
    # The catalogue is the world's as it is now: an edit (simrun.serve.edit_routes) that adds or removes an
    # entity, service or sensor replaces its lists in place, so every request reads loop.catalogue afresh,
    # and the OpenAPI document (with each service's command paths) is rebuilt when its services list changed.
    published: dict[str, Any] = {"services": None, "document": None}

    def services() -> list[dict[str, Any]]:
        """The bound services now, as ``[{"type", "entity"}]``."""
        return [{"type": s["type"], "entity": s["entity"]} for s in loop.catalogue["services"]]

    def current_document() -> dict[str, Any]:
        """The OpenAPI document of the world's current services (built again after an edit changed them)."""
        listed = loop.catalogue["services"]
        if published["services"] is not listed:
            published["document"] = openapi_document(loop.catalogue)
            published["services"] = listed  # held, so its id is never reused while compared
        document: dict[str, Any] = published["document"]
        return document

    def schema(path: str) -> dict[str, Any]:
        """The request body schema of ``POST path`` in the published document (``{}``: none there)."""
        body = current_document()["paths"].get(path, {}).get("post", {}).get("requestBody")
        return dict(body["content"]["application/json"]["schema"]) if body else {}

    async def run(fn: Callable[[Any], Any], read: bool = False) -> Any:
        """``fn(world)`` run in the loop thread (``read``: it only reads, and runs during a long step too)."""
        future = loop.call(fn, read)
        answer = asyncio.wrap_future(future)
        try:
            return await asyncio.wait_for(asyncio.shield(answer), CALL_TIMEOUT)
        except TimeoutError:
            if future.cancel():  # it never started: nothing changed, and it never will
                raise RequestError(
                    503, "", f"the simulation was busy for {CALL_TIMEOUT:g} s; the call did not run (nothing changed)"
                ) from None
            return await answer  # it is running: every call ends (a step request by its deadline)

    glb: dict[str, Any] = {"model": None, "bytes": b""}
    glb_lock = asyncio.Lock()

    async def index(request: Request) -> Response:
        if page is None:
            raise RequestError(404, "path", "this server has no dashboard")
        try:
            text = page()
        except SimrunError as exc:  # the viewer bundle is not installed: how to install it
            raise RequestError(503, "", str(exc)) from None
        return HTMLResponse(text, headers={"Cache-Control": "no-store"})

    async def openapi(request: Request) -> Response:
        return JSONResponse(current_document())

    async def api(request: Request) -> Response:
        return JSONResponse({"api_version": API_VERSION, "schema": "/openapi.json", "world": "/api/world"})

    async def world(request: Request) -> Response:
        return JSONResponse(loop.catalogue)

    async def listing(request: Request) -> Response:
        return JSONResponse(loop.catalogue[request.url.path.rsplit("/", 1)[1]])

    async def state(request: Request) -> Response:
        return JSONResponse(await run(loop.state, read=True))

    async def service_state(request: Request) -> Response:
        kind, entity = request.path_params["service"], request.path_params["entity"]
        bound = services()
        if not any(s["type"] == kind and s["entity"] == entity for s in bound):
            command_from_request(bound, kind, entity, "", None)  # raises the 404 naming the field

        def read(w: Any) -> Any:
            target = w.service(kind, entity)
            values = {}
            for name in service_queries(type(target)):
                value = getattr(target, name)
                values[name] = plain(value() if callable(value) else value)
            return {"type": kind, "entity": entity, "time": float(w.data.time), "state": values}

        return JSONResponse(await run(read, read=True))

    async def service_call(request: Request) -> Response:
        p = request.path_params
        path = f"/api/services/{p['service']}/{p['entity']}/{p['call']}"
        body = await _body(request, schema(path))
        command = command_from_request(services(), p["service"], p["entity"], p["call"], body)

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
        if not any(s["name"] == name for s in loop.catalogue["sensors"]):
            known = ", ".join(s["name"] for s in loop.catalogue["sensors"]) or "none"
            raise RequestError(404, "name", f"no sensor {name!r} (sensors: {known})")
        return str(name)

    async def sensor(request: Request) -> Response:
        name = sensor_name(request)

        def read(w: Any) -> Any:
            s = w.sensors[name]
            return {"name": name, "time": float(w.data.time), "samples": int(s.samples), "reading": plain(s.reading)}

        return JSONResponse(await run(read, read=True))

    async def sensor_image(request: Request) -> Response:
        name = sensor_name(request)
        if not next(s for s in loop.catalogue["sensors"] if s["name"] == name)["image"]:
            raise RequestError(404, "name", f"sensor {name!r} is not a camera")
        fmt = request.query_params.get("format", "png")
        if fmt not in FORMATS:
            raise RequestError(422, "format", f"expected png or jpeg, got {fmt!r}")

        def read(w: Any) -> Any:  # the loop thread only copies the pixels
            rgb = image_of(w.sensors[name].reading)
            return None if rgb is None else rgb.copy()

        rgb = await run(read, read=True)
        if rgb is None:
            raise RequestError(409, "name", f"camera {name!r} has no frame yet; let the world run")
        encode = encode_png if fmt == "png" else encode_jpeg_bytes
        return Response(await asyncio.to_thread(encode, rgb), media_type=f"image/{fmt}")

    async def pause(request: Request) -> Response:
        _object(await _body(request, schema("/api/pause")), ())
        return JSONResponse(await run(loop.set_paused(True)))

    async def resume(request: Request) -> Response:
        _object(await _body(request, schema("/api/resume")), ())
        return JSONResponse(await run(loop.set_paused(False)))

    async def step(request: Request) -> Response:
        body = _object(await _body(request, schema("/api/step")), ("steps", "seconds"))
        if "steps" in body and "seconds" in body:
            raise RequestError(422, "seconds", "give steps or seconds, not both")
        if "seconds" in body:
            seconds = _number(body, "seconds", 0.0, MAX_STEPS * loop.catalogue["timestep"])
            steps = round(seconds / loop.catalogue["timestep"])
        else:
            steps = int(_number(body, "steps", 1, MAX_STEPS, integer=True)) if "steps" in body else 1
        if not (loop.options.lockstep or loop.paused):  # refused at once, without a hop to the loop thread
            raise RequestError(409, "steps", REALTIME_STEP)  # (which checks again: a pause may be queued)
        return JSONResponse(await run(loop.step_request(steps)))

    async def reset(request: Request) -> Response:
        _object(await _body(request, schema("/api/reset")), ())
        return JSONResponse(await run(loop.reset()))

    async def rate(request: Request) -> Response:
        body = _object(await _body(request, schema("/api/rate")), ("rate",))
        if "rate" not in body:
            raise RequestError(422, "rate", f"missing; give the real-time factor in [{MIN_RATE:g}, {MAX_RATE:g}]")
        return JSONResponse(await run(loop.set_rate(_number(body, "rate", MIN_RATE, MAX_RATE))))

    async def recording_start(request: Request) -> Response:
        _object(await _body(request, schema("/api/recording/start")), ())
        if recording is None:
            raise RequestError(409, "", "this server records nowhere; start it with --record PATH")
        return JSONResponse(await run(lambda w: recording()))

    async def recording_stop(request: Request) -> Response:
        _object(await _body(request, schema("/api/recording/stop")), ())

        def stop(w: Any) -> Any:  # the loop thread writes the last chunks and the end records (and MCAP summary)
            current = loop.recording
            if current is None or not current.active:
                raise RequestError(409, "", "nothing is being recorded")
            return current, list(current.finish())

        current, written = await run(stop)
        return JSONResponse({"written": [str(p) for p in written], "recording": current.describe()})

    async def scene_glb(request: Request) -> Response:
        # built once per compiled model (a new one after an edit), in a worker thread from a copy of the
        # poses; the loop thread only copies them, and only when the model changed
        from simrun.serve.scene_glb import glb_of, pose_copy

        async with glb_lock:
            if glb["model"] is None or glb["model"] is not loop.model:
                model, xpos, xquat = await run(pose_copy, read=True)
                glb["bytes"] = await asyncio.to_thread(glb_of, model, xpos, xquat)
                glb["model"] = model
            data = glb["bytes"]
        return Response(data, media_type="model/gltf-binary")

    async def stream(ws: WebSocket) -> None:
        query = ws.query_params
        names = {s["name"] for s in loop.catalogue["sensors"]}
        cameras = {s["name"] for s in loop.catalogue["sensors"] if s["image"]}
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
        elif query.get("format", "jpeg") not in FORMATS:
            problem = (422, "format", f"format must be jpeg or png, got {query.get('format')!r}"[:200])
        elif len(streams) >= MAX_STREAMS:
            problem = (503, "", f"{MAX_STREAMS} streams are open; try later")
        await ws.accept()
        if problem is not None:
            status, field, message = problem
            await ws.send_text(json.dumps({"type": "error", "error": message, "field": field, "status": status}))
            await ws.close(1008)
            return
        sub = Subscriber(
            asyncio.get_running_loop(), sensors, query.get("poses", "1") == "1", images, query.get("format", "jpeg")
        )
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
        retry = {"Retry-After": "1"} if exc.status in (429, 503) else None  # a budget or a busy loop: try again
        return JSONResponse(exc.body(), exc.status, headers=retry)

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
        *edit_routes(loop, run, _body),  # the editor (issue 40): before /api/entities, which it extends
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
    # a client's flood is refused before anything else runs (in real time; a lockstep world waits for its clients)
    limits = budgets(loop.options.request_rate)  # --request-rate
    return RequestBudget(Guard(app, access), *limits, applies=lambda: not loop.options.lockstep)
