"""simrun serve refuses hostile requests with a 4xx JSON error naming the field; the world keeps running."""

from __future__ import annotations

import json
import time

import pytest
from serve_helpers import SCENES, Server, serve

SENSORS = SCENES / "boebot_sensors.toml"
DRIVE = "/api/services/DriveService/boebot"
JSON = {"Content-Type": "application/json"}

#: (id, method, path, body or raw bytes, extra headers, status, field)
HOSTILE = [
    ("unknown-entity", "POST", "/api/services/DriveService/ghost/cmd_vel", {"args": [0.1, 0]}, None, 404, "entity"),
    ("unknown-service", "POST", "/api/services/Teleporter/boebot/go", {}, None, 404, "service"),
    ("unknown-command", "POST", f"{DRIVE}/fly", {"args": [1]}, None, 422, "call"),
    ("private-method", "POST", f"{DRIVE}/_start", {"args": ["x"]}, None, 422, "call"),
    ("lifecycle-method", "POST", f"{DRIVE}/tick", {"args": [1, 2]}, None, 422, "call"),
    ("string-for-number", "POST", f"{DRIVE}/drive_distance", {"args": ["far"]}, None, 422, "args"),
    ("nan", "POST", f"{DRIVE}/cmd_vel", b'{"args": [NaN, 0]}', JSON, 400, "body"),
    ("infinity-literal", "POST", f"{DRIVE}/cmd_vel", b'{"args": [Infinity, 0]}', JSON, 400, "body"),
    ("overflow-to-inf", "POST", f"{DRIVE}/cmd_vel", b'{"args": [1e999, 0]}', JSON, 422, "args"),
    ("too-many-args", "POST", f"{DRIVE}/cmd_vel", {"args": [1, 2, 3]}, None, 422, "args"),
    ("missing-named-arg", "POST", f"{DRIVE}/cmd_vel", {"args": {"linear": 0.1}}, None, 422, "args.angular"),
    ("nested-arrays", "POST", f"{DRIVE}/cmd_vel", {"args": [[[1]], 0]}, None, 422, "args"),
    ("unknown-body-field", "POST", f"{DRIVE}/all_stop", {"args": [], "when": 3}, None, 422, "when"),
    ("body-not-object", "POST", f"{DRIVE}/all_stop", [1, 2], None, 422, "body"),
    ("not-json", "POST", f"{DRIVE}/all_stop", b"{args: [", JSON, 400, "body"),
    ("wrong-content-type", "POST", f"{DRIVE}/all_stop", b"args=1", {"Content-Type": "text/plain"}, 415, "content-type"),
    ("body-too-large", "POST", f"{DRIVE}/cmd_vel", b'{"args": [' + b"0," * 40000 + b"0]}", JSON, 413, "body"),
    ("out-of-range-power", "POST", f"{DRIVE}/drive_distance", {"args": [1.0, -2.0]}, None, 422, "args"),
    ("negative-steps", "POST", "/api/step", {"steps": -5}, None, 422, "steps"),
    ("fractional-steps", "POST", "/api/step", {"steps": 2.5}, None, 422, "steps"),
    ("zero-rate", "POST", "/api/rate", {"rate": 0}, None, 422, "rate"),
    ("boolean-rate", "POST", "/api/rate", {"rate": True}, None, 422, "rate"),
    ("unknown-sensor", "GET", "/api/sensors/sonar9", None, None, 404, "name"),
    ("image-of-a-laser", "GET", "/api/sensors/laser/image", None, None, 404, "name"),
    ("image-format", "GET", "/api/sensors/view_cam/image?format=bmp", None, None, 422, "format"),
    ("unknown-route", "GET", "/api/teleport", None, None, 404, "path"),
    ("wrong-method", "GET", "/api/step", None, None, 405, "method"),
    ("unbound-query", "GET", "/api/services/ArmService/boebot", None, None, 404, "entity"),
]


@pytest.fixture(scope="module")
def server():
    with serve(SENSORS, "--rate", "5") as running:
        yield running


@pytest.mark.parametrize(("method", "path", "body", "headers", "status", "field"), [h[1:] for h in HOSTILE],
                         ids=[h[0] for h in HOSTILE])  # fmt: skip
def test_hostile_request_gets_its_4xx_naming_the_field(server: Server, method, path, body, headers, status, field):
    raw = body if isinstance(body, bytes) else None
    got, answer = server.request(method, path, None if raw is not None else body, headers=headers, raw=raw)
    assert got == status, answer
    assert isinstance(answer, dict) and answer["field"] == field and answer["status"] == status
    assert answer["error"] and "Traceback" not in answer["error"] and "\n" not in answer["error"]


def test_the_world_still_runs_after_the_hostile_requests(server: Server):
    first = server.get("/api/state")["time"]
    time.sleep(0.3)
    assert server.get("/api/state")["time"] > first
    assert server.post(f"{DRIVE}/cmd_vel", {"args": [0.05, 0.0]})["applied"]


@pytest.mark.parametrize(
    ("query", "field"),
    [({"sensors": ["ghost"]}, "sensors"), ({"images": ["laser"]}, "images"), ({"images": ["nope"]}, "images")],
    ids=["unknown-sensor", "image-of-a-laser", "unknown-camera"],
)
def test_a_stream_asking_for_what_is_not_there_is_refused_naming_the_field(server: Server, query, field):
    from simrun.client import Client, ClientError

    with pytest.raises(ClientError) as refused:
        next(Client(server.url).stream(**query))
    assert refused.value.status == 422 and refused.value.field == field


def test_a_stream_from_another_origin_is_refused(server: Server):
    from websockets.exceptions import InvalidStatus
    from websockets.sync.client import connect

    url = "ws" + server.url.removeprefix("http") + "api/stream"
    with pytest.raises(InvalidStatus) as refused, connect(url, origin="http://evil.example", open_timeout=10):
        pass
    assert refused.value.response.status_code == 403
    with connect(url, origin=server.url.rstrip("/"), open_timeout=10) as ws:  # the dashboard's own origin
        assert json.loads(ws.recv(timeout=10))["type"] == "hello"
