"""The published schema of ``simrun serve``: an OpenAPI 3.1 document, built for the world being served.

Besides the fixed routes (state, pause, step, reset, rate, recording, sensors, the stream), every bound
service's commands appear as their own paths (``/api/services/DriveService/boebot/drive_distance``) with
the JSON Schema of their arguments, so a generic OpenAPI tool can call them. :data:`API_VERSION` is the
interface's version (``info.version``): the major number changes when a route or field changes meaning.

Every number a request may carry has its range here (``minimum``/``maximum``): ``steps``, ``seconds``,
``rate``, and each command argument (at most :data:`MAX_ARGUMENT` in magnitude; the services check their
own, tighter limits such as a power in [-1, 1]). The server enforces these ranges from this document
(:func:`simrun.serve.app.check_numbers`), so a field added here is bounded there.
"""

from __future__ import annotations

from typing import Any

from simrun import __version__
from simrun.serve.loop import MAX_RATE, MAX_STEPS, MIN_RATE

#: Version of the HTTP/WebSocket interface (``info.version`` of the document, ``api_version`` of ``GET /api``).
API_VERSION = "1.0"
#: Largest magnitude of a number in a service command's arguments (metres, degrees, seconds, radians...).
MAX_ARGUMENT = 1e6

_ERROR = {
    "type": "object",
    "required": ["error", "field", "status"],
    "properties": {
        "error": {"type": "string", "description": "What is wrong and how to fix it (one line)."},
        "field": {"type": "string", "description": "The request field refused (args, entity, steps...); '' for none."},
        "status": {"type": "integer"},
    },
}
_STATE = {
    "type": "object",
    "properties": {
        "time": {"type": "number", "description": "Simulated time, s."},
        "mode": {"enum": ["realtime", "lockstep"]},
        "paused": {"type": "boolean"},
        "rate": {"type": "number", "description": "Target real-time factor (simulated s per wall s)."},
        "measured_rate": {"type": ["number", "null"], "description": "Measured over about the last wall second."},
        "steps": {"type": "integer"},
        "recording": {"type": ["object", "null"]},
        "poses": {
            "type": "object",
            "description": "Body name to [x, y, z, qw, qx, qy, qz]: world frame (Z up), metres, unit quaternion.",
            "additionalProperties": {"type": "array", "items": {"type": "number"}, "minItems": 7, "maxItems": 7},
        },
    },
}


def _json(schema: dict[str, Any]) -> dict[str, Any]:
    return {"content": {"application/json": {"schema": schema}}}


def _op(summary: str, body: dict[str, Any] | None = None, result: dict[str, Any] | None = None) -> dict[str, Any]:
    op: dict[str, Any] = {
        "summary": summary,
        "responses": {
            "200": {"description": "OK", **_json(result or {"type": "object"})},
            "4XX": {"description": "Refused: the field named", **_json({"$ref": "#/components/schemas/Error"})},
        },
    }
    if body is not None:
        op["requestBody"] = {"required": False, **_json(body)}
    return op


def _empty() -> dict[str, Any]:
    return {"type": "object", "additionalProperties": False}


def bounded(schema: dict[str, Any]) -> dict[str, Any]:
    """A copy of an argument's schema with the range of its numbers (+-:data:`MAX_ARGUMENT`) added."""
    out = dict(schema)
    if out.get("type") in ("number", "integer"):
        out.setdefault("minimum", -MAX_ARGUMENT)
        out.setdefault("maximum", MAX_ARGUMENT)
    if isinstance(out.get("items"), dict):
        out["items"] = bounded(out["items"])
    return out


def openapi_document(catalogue: dict[str, Any]) -> dict[str, Any]:
    """The OpenAPI document of a server for ``catalogue`` (:func:`simrun.serve.catalogue.build_catalogue`)."""
    state = {"$ref": "#/components/schemas/State"}
    longest = MAX_STEPS * float(catalogue["timestep"])
    paths: dict[str, Any] = {
        "/api": {"get": _op("Interface version and links.")},
        "/api/world": {"get": _op("Entities, bound services (commands, queries) and sensors.")},
        "/api/services": {"get": _op("The bound services with their commands' argument schemas.")},
        "/api/sensors": {"get": _op("The sensors: name, type, entity, rate (Hz), whether they give images.")},
        "/api/state": {"get": _op("Time, mode, rates, recording and every body's pose.", result=state)},
        "/api/scene.glb": {"get": {"summary": "The world's visual meshes as binary glTF (Y-up)."}},
        "/api/services/{service}/{entity}": {"get": _op("A service's queries (odometry, encoders, busy...).")},
        "/api/sensors/{name}": {"get": _op("A sensor's latest reading.")},
        "/api/sensors/{name}/image": {"get": {"summary": "A camera's latest frame (?format=png|jpeg)."}},
        "/api/pause": {"post": _op("Stop stepping (calls still run).", _empty(), state)},
        "/api/resume": {"post": _op("Step again in real time.", _empty(), state)},
        "/api/step": {
            "post": _op(
                "Advance (lockstep, or paused): steps (default 1) or seconds.",
                {
                    "type": "object",
                    "additionalProperties": False,
                    "properties": {
                        "steps": {"type": "integer", "minimum": 1, "maximum": MAX_STEPS},
                        "seconds": {
                            "type": "number",
                            "minimum": 0,
                            "maximum": longest,
                            "description": "Simulated seconds.",
                        },
                    },
                },
                state,
            )
        },
        "/api/reset": {"post": _op("Back to time 0 (refused while recording).", _empty(), state)},
        "/api/rate": {
            "post": _op(
                "Set the real-time factor.",
                {
                    "type": "object",
                    "required": ["rate"],
                    "properties": {"rate": {"type": "number", "minimum": MIN_RATE, "maximum": MAX_RATE}},
                },
                state,
            )
        },
        "/api/recording/start": {"post": _op("Start a new recording (the server's --record path).", _empty())},
        "/api/recording/stop": {"post": _op("Finish the recording and write it.", _empty())},
        "/api/stream": {
            "get": {
                "summary": "WebSocket: ?poses=0|1&sensors=all|a,b&images=cam. JSON text messages: "
                "hello, poses {time, poses}, sensor {name, time, reading}, image {name, time, format, data (base64)}.",
            }
        },
    }
    paths.update(edit_paths())
    for service in catalogue["services"]:
        for call, info in service["commands"].items():
            properties = {p["name"]: bounded(p["schema"]) for p in info["parameters"]}
            required = [p["name"] for p in info["parameters"] if "default" not in p]
            positional = [{"title": name, **schema} for name, schema in properties.items()]
            args = {
                "oneOf": [
                    {"type": "array", "maxItems": len(properties), "prefixItems": positional},
                    {"type": "object", "properties": properties, "required": required, "additionalProperties": False},
                ]
            }
            body = {"type": "object", "additionalProperties": False, "properties": {"args": args}}
            paths[f"{service['path']}/{call}"] = {"post": _op(info["doc"] or call, body)}
    return {
        "openapi": "3.1.0",
        "info": {
            "title": "simrun serve",
            "version": API_VERSION,
            "description": f"A running simrun world (simrun {__version__}): services, sensors, poses.",
        },
        "servers": [{"url": "/"}],
        "paths": paths,
        "components": {
            "schemas": {"Error": _ERROR, "State": _STATE},
            "securitySchemes": {"token": {"type": "http", "scheme": "bearer"}},
        },
    }


# --- the editor's routes (simrun/serve/edit_routes.py, issue 40) -------------------------------------------------

_VEC3 = {"type": "array", "items": {"type": "number", "minimum": -MAX_ARGUMENT, "maximum": MAX_ARGUMENT}}
_TABLE = {
    "type": "object",
    "description": "An entity's scene table: type, name, parent, pose {position, orientation}, free, kinematic and "
    "the type's keys (GET /api/edit lists them with units and defaults).",
}
_SEED = {"type": "integer", "minimum": 0, "maximum": 2**63}


def edit_request_schemas() -> dict[str, dict[str, Any]]:
    """The request body schema of each edit route, by the name :mod:`simrun.serve.edit_routes` gives it.

    Numbers are within +-:data:`MAX_ARGUMENT` unless given here (a push's ``duration``, a sensor's ``seed``).
    """
    from simrun.world.edit import MAX_BATCH
    from simrun.world.edit_push import MAX_PUSH_SECONDS

    sensor = {"type": "object", "properties": {"seed": _SEED}, "description": "A [[sensors]] table's keys."}
    return {
        "insert": {
            "type": "object",
            "additionalProperties": False,
            "properties": {
                "entity": _TABLE,
                "entities": {"type": "array", "items": _TABLE, "maxItems": MAX_BATCH},
                "parent": {"type": "string", "description": "Full name of the entity they go under."},
            },
        },
        "change": {"type": "object", "description": "The keys to change, as a scene table writes them."},
        "remove": _empty(),
        "teleport": {
            "type": "object",
            "additionalProperties": False,
            "required": ["position"],
            "properties": {
                "position": {**_VEC3, "description": "m, relative to the parent (the world at the top)."},
                "orientation": {
                    "type": "array",
                    "items": {"type": "number", "minimum": -MAX_ARGUMENT, "maximum": MAX_ARGUMENT},
                    "description": "Unit quaternion (w, x, y, z).",
                },
                "keep_velocity": {"type": "boolean"},
            },
        },
        "force": {
            "type": "object",
            "additionalProperties": False,
            "properties": {
                "force": {**_VEC3, "description": "N, world frame, at the body's centre of mass."},
                "torque": {**_VEC3, "description": "N m, world frame."},
                "duration": {"type": "number", "minimum": 0, "maximum": MAX_PUSH_SECONDS, "description": "s."},
                "body": {"type": "string", "description": "A body of the entity (NAME/link); default its own."},
            },
        },
        "world": {
            "type": "object",
            "additionalProperties": False,
            "required": ["gravity"],
            "properties": {"gravity": {**_VEC3, "description": "m/s^2."}},
        },
        "service": {"type": "object", "description": "The [[services]] keys to change (rate, limits, gain...)."},
        "service-add": {"type": "object", "required": ["service"], "properties": {"service": {"type": "object"}}},
        "sensor": sensor,
        "sensor-add": {"type": "object", "required": ["sensor"], "properties": {"sensor": sensor}},
        "save": {
            "type": "object",
            "additionalProperties": False,
            "properties": {
                "state": {"enum": ["initial", "current"]},
                "folder": {"type": "string", "description": "Absolute folder the text will be saved in."},
            },
        },
        "save-entities": {
            "type": "object",
            "additionalProperties": False,
            "required": ["names"],
            "properties": {"names": {"type": "array", "items": {"type": "string"}}, "folder": {"type": "string"}},
        },
        "load-entities": {
            "type": "object",
            "additionalProperties": False,
            "required": ["toml"],
            "properties": {"toml": {"type": "string"}, "parent": {"type": "string"}},
        },
    }


_TABLES = {"type": "object", "additionalProperties": {"type": "object"}}
#: ``GET /api/entities/NAME``'s answer (simrun/serve/edit_routes.py ``one``).
_ENTITY = {
    "type": "object",
    "properties": {
        "name": {"type": "string"},
        "type": {"type": "string"},
        "parent": {"type": ["string", "null"]},
        "values": {"type": "object", "description": "Its scene table now."},
        "pose": {"type": ["array", "null"], "description": "World [x, y, z, qw, qx, qy, qz] now: m, unit quaternion."},
        "services": {"type": "array", "items": {"type": "string"}, "description": "Types of the services bound to it."},
        "sensors": {"type": "array", "items": {"type": "string"}, "description": "Names of its sensors."},
        "schema": {"type": "object", "description": "Its type's keys (GET /api/edit's types.entities[k])."},
        "service_settings": {
            **_TABLES,
            "description": "Service type to its [[services]] table now (as PATCH /api/edit/services changed it);"
            " a key it lacks is at its default.",
        },
        "sensor_settings": {
            **_TABLES,
            "description": "Sensor name to its [[sensors]] table now (rate Hz, noise...; as PATCH"
            " /api/edit/sensors changed it); a key it lacks is at its default.",
        },
    },
}


def edit_paths() -> dict[str, Any]:
    """The editor's paths of the document (reading always; changing with ``simrun serve --edit``)."""
    body = edit_request_schemas()
    name = "/api/entities/{name}"
    changed = {"type": "object", "properties": {"time": {"type": "number", "description": "Simulated time, s."}}}

    def op(summary: str, key: str, method_body: bool = True) -> dict[str, Any]:
        out = _op(summary + " (needs --edit; 403 without, 409 while recording, 429 over the rate).", body[key], changed)
        out["requestBody"]["required"] = method_body
        return out

    return {
        "/api/entities": {
            "get": _op("Every entity: name, type, parent, values (its table), pose (world, now), services, sensors."),
            "post": op("Insert an entity ({entity: table}) or a list ({entities: [...]}), under parent.", "insert"),
        },
        name: {
            "get": _op(
                "One entity, with its type's schema (keys, types, units, defaults, descriptions) and the current"
                " settings of its services and sensors.",
                result=_ENTITY,
            ),
            "patch": op("Change an entity's keys (pose, mass, dimensions, color, material...).", "change"),
            "delete": op("Remove an entity, its children and the services and sensors bound to them.", "remove"),
        },
        name + "/teleport": {"post": op("Move an entity (free and kinematic bodies at once).", "teleport")},
        name + "/force": {"post": op("Push a body with a force and torque for a duration.", "force")},
        "/api/edit": {"get": _op("Whether edits are allowed, the limits and every registered type's schema.")},
        "/api/edit/log": {"get": _op("The session's edits: {edits: [{t (simulated s), kind, args}]}, in order.")},
        "/api/edit/undo": {"post": op("Undo the last edit (a push has none: 409; the one before is next).", "remove")},
        "/api/edit/world": {"post": op("Change the world's gravity.", "world")},
        "/api/edit/save": {"post": _op("The world as scene TOML ({toml}), at current poses.", body["save"])},
        "/api/edit/save-entities": {
            "post": _op("The named entities and those below as an entities file ({toml}).", body["save-entities"])
        },
        "/api/edit/load-entities": {"post": op("Insert the entities of an entities file's text.", "load-entities")},
        "/api/edit/services": {"post": op("Bind a service from a [[services]] table.", "service-add")},
        "/api/edit/services/{service}/{entity}": {
            "patch": op("Change a bound service's settings.", "service"),
            "delete": op("Unbind a service.", "remove"),
        },
        "/api/edit/sensors": {"post": op("Add a sensor from a [[sensors]] table.", "sensor-add")},
        "/api/edit/sensors/{name}": {
            "patch": op("Change a sensor's settings (rate, noise, seed...).", "sensor"),
            "delete": op("Remove a sensor.", "remove"),
        },
    }
