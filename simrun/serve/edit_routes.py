"""The editor's routes of ``simrun serve``: list, insert, change, remove, move and push entities; save and load.

Reading is always allowed: ``GET /api/entities`` (every entity with its current values and world pose),
``GET /api/entities/NAME`` (one, with its type's schema and the current settings of its services and sensors),
``GET /api/edit`` (whether edits are allowed, the limits, and the schema of every registered type for a "new
entity" dialog), ``POST /api/edit/save`` and ``/api/edit/save-entities`` (scene text). Every other route
changes the world and is refused (403) unless the server runs with ``--edit``, recorded when a recording runs
(an edit record of the ``.simlog``, which ``simrun resim`` applies again at the same step), and limited to
:data:`MAX_EDITS_PER_SECOND` and :data:`EDIT_SHARE` of the loop thread's time (429 beyond).

Each edit runs on the world's loop thread between steps (as a service command does) through
:mod:`simrun.world.edit`; an edit refused there leaves the world exactly as it was and is answered 404 (no
such entity, service or sensor), 409 (a name taken) or 422, naming the request field (``entity.mass``,
``entities[3].pose.position[1]``, ``force``). Request and answer schemas are in ``/openapi.json``
(:func:`simrun.serve.openapi.edit_paths`).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any

import mujoco
from starlette.requests import Request
from starlette.responses import JSONResponse, Response
from starlette.routing import Route

from simrun.errors import SimrunError
from simrun.serve.catalogue import RequestError, build_catalogue
from simrun.serve.loop import SimLoop
from simrun.serve.openapi import edit_request_schemas
from simrun.world import edit, edit_push, edit_save, edit_schema
from simrun.world.edit import EditError
from simrun.world.edit_apply import EditRecord, apply_edit, inverse, undo_of
from simrun.world.world import World

#: Most edits accepted per wall second (a burst of as many is allowed); beyond, 429.
MAX_EDITS_PER_SECOND = 50.0
#: Largest share of the loop thread's wall time edits may take (a burst of that many seconds); beyond, 429.
EDIT_SHARE = 0.2
#: Edits the undo list remembers.
MAX_UNDO = 100
_STATUS = {"invalid": 422, "missing": 404, "conflict": 409}

Run = Callable[[Callable[[Any], Any]], Awaitable[Any]]
Body = Callable[..., Awaitable[Any]]


class Budget:
    """Edits' share of the loop thread: :data:`MAX_EDITS_PER_SECOND` a wall second and :data:`EDIT_SHARE` of its time.

    Two token buckets (thread-safe): a count refilled at :data:`MAX_EDITS_PER_SECOND` (as many in a burst), and
    loop-thread seconds refilled at :data:`EDIT_SHARE` per wall second (as much in a burst), which each edit
    pays for after it ran (a recompile of a large world costs more than a teleport); one edit at a time. An edit
    is refused while either is spent or another runs, so edits never take more than that share from the physics.
    """

    def __init__(self, rate: float = MAX_EDITS_PER_SECOND, share: float = EDIT_SHARE) -> None:
        self.rate, self.share = rate, share
        self.tokens, self.seconds, self.last = rate, share, time.monotonic()
        self.running = 0
        self._lock = threading.Lock()

    def take(self) -> None:
        """Spend one edit.

        Raises:
            RequestError: 429 when none is left this second.
        """
        with self._lock:
            now = time.monotonic()
            self.tokens = min(self.rate, self.tokens + (now - self.last) * self.rate)
            self.seconds = min(self.share, self.seconds + (now - self.last) * self.share)
            self.last = now
            if self.tokens < 1.0:
                raise RequestError(429, "", f"more than {self.rate:g} edits a second; slow down")
            if self.seconds <= 0.0:
                raise RequestError(429, "", f"edits took {self.share:.0%} of the simulation's time; slow down")
            if self.running:
                raise RequestError(429, "", "another edit is running; send the next when it is answered")
            self.tokens -= 1.0
            self.running += 1

    def spent(self, seconds: float) -> None:
        """Charge the loop-thread time an edit took (it has ended)."""
        with self._lock:
            self.seconds -= seconds
            self.running = max(0, self.running - 1)


def refusal(exc: EditError) -> RequestError:
    """An :class:`EditError` as the 4xx answer naming its field."""
    return RequestError(_STATUS.get(exc.reason, 422), exc.key or "", exc.message or str(exc))


def edit_routes(loop: SimLoop, run: Run, body: Body) -> list[Route]:
    """The routes (for :func:`simrun.serve.app.create_app`, listed before its own ``/api/entities``).

    Args:
        loop: The served world's loop; ``loop.options.extra["edit"]`` allows edits (``simrun serve --edit``).
        run: Runs a call on the loop thread and awaits its answer (the app's).
        body: Reads a request's JSON body checked against a schema (the app's ``_body``).
    """
    allowed = bool(loop.options.extra.get("edit", False))
    budget = Budget()
    schemas = edit_request_schemas()

    log: list[EditRecord] = []

    undo: list[tuple[str, list[EditRecord] | None]] = []  # (kind, the edits undoing it), last edit last

    def apply(world: World, kind: str, args: dict[str, Any], undoable: bool = True) -> Any:
        """One edit through the one dispatcher (:func:`apply_edit`), kept in the session's log and undo list."""
        t = float(world.data.time)
        try:
            before = inverse(world, kind, args) if undoable else None
        except SimrunError:  # the edit itself names the problem
            before = None
        size_before = int(mujoco.mj_stateSize(world.model, mujoco.mjtState.mjSTATE_INTEGRATION))
        result = apply_edit(world, kind, args)
        record = EditRecord(t, kind, args)
        log.append(record)
        size = int(mujoco.mj_stateSize(world.model, mujoco.mjtState.mjSTATE_INTEGRATION))
        loop.edit_history.append((t, record.to_json(), size_before, size))
        recording = loop.recording
        if recording is not None and recording.active:  # a .simlog edit record: simrun resim applies it again
            recording.recorder.edit(t, record.to_json(), size)
        if undoable:
            undo.append((kind, undo_of(t, kind, args, result, before)))
            del undo[:-MAX_UNDO]
        return result

    async def mutate(request: Request, name: str, fn: Callable[[World, Any], Any]) -> Response:
        payload = await body(request, schemas.get(name, {}))  # a malformed body is answered as on every route
        if not allowed:
            raise RequestError(403, "", "edits are off; start the server with simrun serve --edit")
        budget.take()
        began = [0.0]

        def call(world: World) -> Any:
            began[0] = time.perf_counter()
            model, offered = world.model, _offered(world)
            try:
                result = fn(world, payload)
            except EditError as exc:
                raise refusal(exc) from None
            if world.model is not model or _offered(world) != offered:  # new bodies, names, services or sensors
                loop.catalogue.update(build_catalogue(world))
            loop._publish(world, poses=True)
            return {"time": float(world.data.time), **(result or {})}

        try:
            return JSONResponse(await run(call))
        finally:
            budget.spent(time.perf_counter() - began[0] if began[0] else 0.0)

    def fields(payload: Any, known: tuple[str, ...], required: tuple[str, ...] = ()) -> dict[str, Any]:
        if payload is None:
            payload = {}
        if not isinstance(payload, dict):
            raise RequestError(422, "body", f"expected a JSON object, got {type(payload).__name__}")
        for key in payload:
            if key not in known:
                raise RequestError(422, str(key), f"unknown field (known: {', '.join(known)})")
        for key in required:
            if key not in payload:
                raise RequestError(422, key, "missing")
        return payload

    def path_name(request: Request) -> str:
        return str(request.path_params["name"])

    # -- reading ---------------------------------------------------------------------------------------------

    async def listing(request: Request) -> Response:
        def read(world: World) -> Any:
            robots = {e["name"]: e for e in loop.catalogue["entities"]}
            out = []
            for item in edit.describe_all(world):
                known = robots.get(item["name"], {})
                root = {"root": known["root"]} if "root" in known else {}
                out.append({**item, "robot": known.get("robot", False), **root})
            return out

        return JSONResponse(await run(read))

    async def one(request: Request) -> Response:
        name = path_name(request)

        def read(world: World) -> Any:
            try:
                edit._entity(world, name)
            except EditError as exc:
                raise refusal(exc) from None
            item = edit.describe(world, name)
            return {**item, "schema": edit_schema.type_schema("entities", item["type"]), **_settings(world, item)}

        return JSONResponse(await run(read))

    async def about(request: Request) -> Response:
        return JSONResponse(
            {
                "allowed": allowed,
                "edits_per_second": MAX_EDITS_PER_SECOND,
                "max_batch": edit.MAX_BATCH,
                "max_push_seconds": edit_push.MAX_PUSH_SECONDS,
                "applied": len(log),
                "types": edit_schema.types_schema(),
            }
        )

    async def edit_log(request: Request) -> Response:
        return JSONResponse({"edits": [{"t": r.t, "kind": r.kind, "args": r.args} for r in log]})

    async def save(request: Request) -> Response:
        payload = fields(await body(request, schemas.get("save", {})), ("state", "folder"))
        state = payload.get("state", "initial")
        if state not in ("initial", "current"):
            raise RequestError(422, "state", f"expected initial or current, got {state!r}"[:200])
        folder = _folder(payload)

        def read(world: World) -> Any:
            return {"toml": edit_save.current_scene_text(world, state, folder or world.base_dir)}

        return JSONResponse(await run(read))

    async def save_entities(request: Request) -> Response:
        payload = fields(await body(request, schemas.get("save-entities", {})), ("names", "folder"), ("names",))
        folder = _folder(payload)

        def read(world: World) -> Any:
            try:
                return {"toml": edit_save.entities_text(world, payload["names"], folder or world.base_dir)}
            except EditError as exc:
                raise refusal(exc) from None

        return JSONResponse(await run(read))

    # -- changing --------------------------------------------------------------------------------------------

    async def insert(request: Request) -> Response:
        def fn(world: World, payload: Any) -> Any:
            p = fields(payload, ("entity", "entities", "parent"))
            if ("entity" in p) == ("entities" in p):
                raise RequestError(422, "entity", "give entity (a table) or entities (a list of tables)")
            parent = p.get("parent")
            if parent is not None and not isinstance(parent, str):
                raise RequestError(422, "parent", "expected the full name of an entity")
            tables = p["entity"] if "entity" in p else p["entities"]
            return {"inserted": apply(world, "insert", {"tables": tables, "parent": parent})}

        return await mutate(request, "insert", fn)

    async def change(request: Request) -> Response:
        name = path_name(request)

        def fn(world: World, payload: Any) -> Any:
            if not isinstance(payload, dict) or not payload:
                raise RequestError(422, "body", "expected a JSON object of the keys to change")
            apply(world, "change", {"name": name, "changes": payload})
            return {"entity": edit.describe(world, name)}

        return await mutate(request, "change", fn)

    async def remove(request: Request) -> Response:
        name = path_name(request)
        return await mutate(request, "remove", lambda world, _: {"removed": apply(world, "remove", {"name": name})})

    async def teleport(request: Request) -> Response:
        name = path_name(request)

        def fn(world: World, payload: Any) -> Any:
            p = fields(payload, ("position", "orientation", "keep_velocity"), ("position",))
            keep = p.get("keep_velocity", False)
            if not isinstance(keep, bool):
                raise RequestError(422, "keep_velocity", "expected true or false")
            args = {"name": name, "position": p["position"], "orientation": p.get("orientation"), "keep_velocity": keep}
            return apply(world, "teleport", args)

        return await mutate(request, "teleport", fn)

    async def force(request: Request) -> Response:
        name = path_name(request)

        def fn(world: World, payload: Any) -> Any:
            p = fields(payload, ("force", "torque", "duration", "body"))
            return apply(world, "apply_force", {"name": name, **p})

        return await mutate(request, "force", fn)

    async def world_options(request: Request) -> Response:
        def fn(world: World, payload: Any) -> Any:
            p = fields(payload, ("gravity",), ("gravity",))
            apply(world, "set_gravity", {"gravity": p["gravity"]})
            return {"gravity": [float(g) for g in world.model.opt.gravity]}

        return await mutate(request, "world", fn)

    async def service_change(request: Request) -> Response:
        kind, entity = request.path_params["service"], request.path_params["entity"]

        def fn(world: World, payload: Any) -> Any:
            apply(world, "change_service", {"kind": kind, "entity": entity, "settings": payload})
            return {"service": next(s for s in world.services if s["type"] == kind and s["entity"] == entity)}

        return await mutate(request, "service", fn)

    async def service_add(request: Request) -> Response:
        def fn(world: World, payload: Any) -> Any:
            p = fields(payload, ("service",), ("service",))
            apply(world, "add_service", {"table": p["service"]})
            return {"service": p["service"]}

        return await mutate(request, "service-add", fn)

    async def service_remove(request: Request) -> Response:
        kind, entity = request.path_params["service"], request.path_params["entity"]

        def fn(world: World, payload: Any) -> Any:
            apply(world, "remove_service", {"kind": kind, "entity": entity})
            return {"removed": f"{kind}:{entity}"}

        return await mutate(request, "remove", fn)

    async def sensor_change(request: Request) -> Response:
        name = path_name(request)

        def fn(world: World, payload: Any) -> Any:
            apply(world, "change_sensor", {"name": name, "settings": payload})
            return {"sensor": next(s for s in world.sensor_specs if s["name"] == name)}

        return await mutate(request, "sensor", fn)

    async def sensor_add(request: Request) -> Response:
        def fn(world: World, payload: Any) -> Any:
            p = fields(payload, ("sensor",), ("sensor",))
            apply(world, "add_sensor", {"table": p["sensor"]})
            return {"sensor": p["sensor"]}

        return await mutate(request, "sensor-add", fn)

    async def sensor_remove(request: Request) -> Response:
        name = path_name(request)

        def fn(world: World, payload: Any) -> Any:
            apply(world, "remove_sensor", {"name": name})
            return {"removed": name}

        return await mutate(request, "remove", fn)

    async def load_entities(request: Request) -> Response:
        def fn(world: World, payload: Any) -> Any:
            p = fields(payload, ("toml", "parent"), ("toml",))
            if not isinstance(p["toml"], str):
                raise RequestError(422, "toml", "expected the text of an entities file")
            parent = p.get("parent")
            if parent is not None and not isinstance(parent, str):
                raise RequestError(422, "parent", "expected the full name of an entity")
            return {"added": apply(world, "load_entities", {"text": p["toml"], "parent": parent})}

        return await mutate(request, "load-entities", fn)

    async def undo_last(request: Request) -> Response:
        def fn(world: World, payload: Any) -> Any:
            fields(payload, ())
            if not undo:
                raise RequestError(409, "", "no edit to undo")
            kind, records = undo.pop()
            if records is None:
                raise RequestError(409, "", f"the last edit ({kind}) cannot be undone; the one before it is next")
            for record in records:
                apply(world, record.kind, record.args, undoable=False)
            return {"undone": kind, "edits": [{"kind": r.kind, "args": r.args} for r in records]}

        return await mutate(request, "remove", fn)

    return [
        Route("/api/edit/undo", undo_last, methods=["POST"]),
        Route("/api/entities", listing, methods=["GET"]),
        Route("/api/entities", insert, methods=["POST"]),
        Route("/api/entities/{name:path}/teleport", teleport, methods=["POST"]),
        Route("/api/entities/{name:path}/force", force, methods=["POST"]),
        Route("/api/entities/{name:path}", one, methods=["GET"]),
        Route("/api/entities/{name:path}", change, methods=["PATCH"]),
        Route("/api/entities/{name:path}", remove, methods=["DELETE"]),
        Route("/api/edit", about, methods=["GET"]),
        Route("/api/edit/log", edit_log, methods=["GET"]),
        Route("/api/edit/world", world_options, methods=["POST"]),
        Route("/api/edit/save", save, methods=["POST"]),
        Route("/api/edit/save-entities", save_entities, methods=["POST"]),
        Route("/api/edit/load-entities", load_entities, methods=["POST"]),
        Route("/api/edit/services", service_add, methods=["POST"]),
        Route("/api/edit/services/{service}/{entity:path}", service_change, methods=["PATCH"]),
        Route("/api/edit/services/{service}/{entity:path}", service_remove, methods=["DELETE"]),
        Route("/api/edit/sensors", sensor_add, methods=["POST"]),
        Route("/api/edit/sensors/{name}", sensor_change, methods=["PATCH"]),
        Route("/api/edit/sensors/{name}", sensor_remove, methods=["DELETE"]),
    ]


def _settings(world: World, item: dict[str, Any]) -> dict[str, Any]:
    """The current settings of an entity's services and sensors: their tables now, as PATCH changed them.

    ``{"service_settings": {TYPE: [[services]] table}, "sensor_settings": {NAME: [[sensors]] table}}``, read
    from ``world.services`` and ``world.sensor_specs`` (the merged tables each change builds the service or
    sensor again from); a key a table lacks is at its type's default (``GET /api/edit``). Units as the schema's
    (``rate`` Hz, ``noise`` in the reading's unit).
    """
    services = {s["type"]: s for s in world.services if s.get("entity") == item["name"]}
    sensors = {s["name"]: s for s in world.sensor_specs if s.get("name") in item["sensors"]}
    return {
        "service_settings": {k: edit_schema.json_value(v) for k, v in services.items()},
        "sensor_settings": {k: edit_schema.json_value(v) for k, v in sensors.items()},
    }


def _offered(world: World) -> tuple[Any, ...]:
    """What the catalogue lists besides bodies: the bound services and each sensor with its period (s)."""
    services = tuple((s.get("type"), s.get("entity")) for s in world.services)
    return services, tuple((name, float(s.period)) for name, s in world.sensors.items())


def _folder(payload: dict[str, Any]) -> Path | None:
    """The ``folder`` a saved text is for (an absolute path; relative paths are rewritten for it)."""
    folder = payload.get("folder")
    if folder is None:
        return None
    if not isinstance(folder, str) or not Path(folder).is_absolute() or "\x00" in folder:
        raise RequestError(422, "folder", "expected an absolute folder path (where the text will be saved)")
    return Path(folder)
