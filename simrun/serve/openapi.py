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
        "/api/entities": {"get": _op("The entities: name, type, robot.")},
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
