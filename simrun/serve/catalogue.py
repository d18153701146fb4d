"""What a served world offers, by name: entities, bound services with their commands and queries, sensors.

The catalogue is built from a prepared world (its ``[[services]]`` bindings and ``[[sensors]]``) and is
plain JSON; the server builds it again after an edit that changes the world's bodies, services or sensors
(:mod:`simrun.serve.edit_routes`), and every request reads the current one. A service call from a client
goes through :func:`command_from_request`, which builds the table a ``[[commands]]`` entry would hold and
hands it to :func:`simrun.run.commands.parse_command`: one validation path for commands files, recordings
and the server. Errors are :class:`RequestError`, which name the
request field (``service``, ``entity``, ``call``, ``args``, ``args.metres``) for the 4xx JSON answer.

Commands are the public methods that ``parse_command`` accepts; those that take no argument and return a
value (``odometry``, ``encoders``, ``joint_states``) and the properties (``busy``) are also the service's
*queries*, read by ``GET /api/services/TYPE/ENTITY``.
"""

from __future__ import annotations

import dataclasses
import functools
import inspect
import math
import typing
from typing import Any

import numpy as np

from simrun.errors import SimrunError
from simrun.robots.contract import robots as robot_contracts
from simrun.run.commands import LIFECYCLE, Command, parse_command
from simrun.world.registry import REGISTRY, names
from simrun.world.world import World


class RequestError(SimrunError, ValueError):
    """A request the server refuses: HTTP ``status``, the ``field`` it names and a one-line message."""

    def __init__(self, status: int, field: str, message: str) -> None:
        super().__init__(f"{field}: {message}" if field else message)
        self.status, self.field, self.message = status, field, message

    def body(self) -> dict[str, Any]:
        """The JSON error body: ``{"error": message, "field": field, "status": status}``."""
        return {"error": self.message, "field": self.field, "status": self.status}


#: JSON types of annotations, for the schema of a command's arguments.
_JSON_TYPES = {float: "number", int: "integer", bool: "boolean", str: "string"}


def _arg_schema(hint: Any) -> dict[str, Any]:
    """JSON Schema of one argument from its annotation (numbers finite; arrays of numbers)."""
    if hint in _JSON_TYPES:
        return {"type": _JSON_TYPES[hint]}
    options = typing.get_args(hint)
    if options:
        inner = [o for o in options if o is not type(None)]
        if all(typing.get_origin(o) in (list, tuple) for o in inner):
            return {"type": "array", "items": {"type": "number"}}
        if len(inner) == 1:
            return _arg_schema(inner[0])
    if typing.get_origin(hint) in (list, tuple):
        return {"type": "array", "items": {"type": "number"}}
    return {}


def command_schema(cls: type, call: str) -> dict[str, Any]:
    """One command's parameters: ``{"parameters": [{"name", "schema", "default"?}], "doc"}``."""
    method = getattr(cls, call)
    hints = typing.get_type_hints(method)
    params = []
    for name, p in list(inspect.signature(method).parameters.items())[1:]:
        item: dict[str, Any] = {"name": name, "schema": _arg_schema(hints.get(name))}
        if p.default is not inspect.Parameter.empty:
            item["default"] = p.default
        params.append(item)
    doc = inspect.getdoc(method) or ""
    return {"parameters": params, "doc": doc.split("\n\n", 1)[0].replace("\n", " ")}


def service_commands(cls: type) -> list[str]:
    """The calls ``parse_command`` accepts for a service type (public methods less the lifecycle)."""
    return [
        n
        for n, m in inspect.getmembers(cls, callable)
        if not n.startswith("_") and n not in LIFECYCLE and not isinstance(m, type)
    ]


def service_queries(cls: type) -> list[str]:
    """Properties and argument-less methods that return a value: what ``GET`` on a service reads.

    Worked out once per class (``inspect.getmembers`` and signatures were most of a service call's time in
    the simulation thread); a new list each call.
    """
    return list(_queries(cls))


@functools.cache
def _queries(cls: type) -> tuple[str, ...]:
    out = []
    for name, member in inspect.getmembers(cls):
        if name.startswith("_") or name in LIFECYCLE:
            continue
        if isinstance(member, property):
            out.append(name)
        elif callable(member) and not isinstance(member, type):
            signature = inspect.signature(member)
            if len(signature.parameters) == 1 and signature.return_annotation not in (None, "None"):
                out.append(name)
    return tuple(out)


def build_catalogue(world: World) -> dict[str, Any]:
    """The world's entities, bound services (commands with schemas, queries) and sensors (type, rate, entity).

    Each entity says whether it is a robot (the robot contract, :mod:`simrun.robots.contract`) and, for a robot,
    its ``root`` body (the dashboard follows it); ``teleop`` lists the robots with wheels and a bound
    ``DriveService``, in entity order (the dashboard's teleoperation list).
    """
    contracts = robot_contracts(world)
    entities = [
        {
            "name": name,
            "type": entity.TYPE,
            "robot": name in contracts,
            **({"root": contracts[name].root} if name in contracts else {}),
        }
        for name, entity in world
    ]
    driven = {s["entity"] for s in world.services if s.get("type") == "DriveService"}
    teleop = [name for name, r in contracts.items() if r.wheels is not None and name in driven]
    services = []
    for binding in world.services:
        kind, entity = binding["type"], binding["entity"]
        cls = REGISTRY[kind].load()
        services.append(
            {
                "type": kind,
                "entity": entity,
                "path": f"/api/services/{kind}/{entity}",
                "commands": {c: command_schema(cls, c) for c in service_commands(cls)},
                "queries": service_queries(cls),
            }
        )
    sensors = []
    for name, sensor in world.sensors.items():
        period = float(sensor.period)
        sensors.append(
            {
                "name": name,
                "type": type(sensor).__name__,
                "entity": sensor.entity,
                "rate_hz": 1.0 / period if period > 0 else None,
                "image": type(sensor).__name__ in ("Webcam", "StereoCamera"),
                # a laser's mounting height above its body origin and range (m): where the dashboard draws it
                **{k: float(getattr(sensor, k)) for k in ("height", "max_range") if hasattr(sensor, k)},
            }
        )
    model = world.model
    bodies = [model.body(b).name or f"body{b}" for b in range(model.nbody)]
    return {
        "entities": entities,
        "services": services,
        "sensors": sensors,
        "teleop": teleop,
        "bodies": bodies,
        "timestep": float(model.opt.timestep),
    }


def command_from_request(
    world_services: list[dict[str, Any]], service: str, entity: str, call: str, body: Any
) -> Command:
    """Validate a service call (``POST /api/services/SERVICE/ENTITY/CALL`` with ``body``) into a :class:`Command`.

    ``body`` is ``{"args": [...]}`` (positional, as a commands file) or ``{"args": {"name": value}}``
    (by parameter name), or empty for no arguments. The time is set when the world applies it.

    Raises:
        RequestError: 404 for an unknown service type or entity or an unbound pair, 422 for a bad call or
            arguments, naming the field.
    """
    if service not in names("services"):
        raise RequestError(404, "service", f"unknown service type {service!r} (known: {', '.join(names('services'))})")
    bound = [s for s in world_services if s.get("type") == service]
    if not any(s.get("entity") == entity for s in bound):
        where = ", ".join(str(s.get("entity")) for s in bound) or "none"
        raise RequestError(404, "entity", f"no {service} is bound to {entity!r} (bound to: {where})")
    if body is None:
        body = {}
    if not isinstance(body, dict):
        raise RequestError(422, "body", f'expected a JSON object such as {{"args": [...]}}, got {type(body).__name__}')
    unknown = [k for k in body if k != "args"]
    if unknown:
        raise RequestError(422, str(unknown[0]), "unknown field (known: args)")
    args = body.get("args", [])
    if isinstance(args, dict):
        args = _positional(service, call, args)

    def fail(message: str, key: str | None = None) -> RequestError:
        return RequestError(422, key or "body", message.removeprefix(f"{key}: ") if key else message)

    table = {"t": 0.0, "service": service, "entity": entity, "call": call, "args": args}
    return parse_command(table, fail)


def _positional(service: str, call: str, named: dict[str, Any]) -> list[Any]:
    """Arguments given by name, in the method's order (defaults filled in)."""
    cls = REGISTRY[service].load()
    method = getattr(cls, call, None)
    if call.startswith("_") or call in LIFECYCLE or not callable(method):
        raise RequestError(
            422, "call", f"{service} has no command {call!r} (commands: {', '.join(service_commands(cls))})"
        )
    params = list(inspect.signature(method).parameters.values())[1:]
    known = [p.name for p in params]
    for key in named:
        if key not in known:
            raise RequestError(422, f"args.{key}", f"{call} has no parameter {key!r} (parameters: {', '.join(known)})")
    out = []
    for p in params:
        if p.name in named:
            out.append(named[p.name])
        elif p.default is inspect.Parameter.empty:
            raise RequestError(422, f"args.{p.name}", f"missing; {call} needs {', '.join(known)}")
        else:
            out.append(p.default)
    return out


def plain(value: Any) -> Any:
    """A reading or query result as JSON-ready data (dataclasses to objects, arrays to lists, NaN/inf to null).

    Images (``uint8`` arrays of 2 or 3 dimensions) become ``{"shape": [...]}``: the pixels go out as
    PNG or JPEG (``/api/sensors/NAME/image``), never as JSON numbers.
    """
    if value is None or isinstance(value, bool | int | str):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, np.ndarray):
        if value.dtype == np.uint8 and value.ndim in (2, 3):
            return {"shape": list(value.shape)}
        if value.dtype.kind == "f":
            return [plain(float(v)) for v in value.ravel()] if value.ndim == 1 else [plain(v) for v in value]
        return value.tolist()
    if isinstance(value, np.generic):
        return plain(value.item())
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [plain(v) for v in value]
    return str(value)
