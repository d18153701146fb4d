"""Every number a request can carry is bounded, and so is the nesting of a body: a hostile value is a 4xx naming
the field and its range, never a 500 (an ``OverflowError`` for 10^400, a ``RecursionError`` for deep JSON).

The fields are not listed here: they come from the running server's own ``/openapi.json`` (every POST route,
each property, each command argument by name and by position), so a field added to a route is tested too.
Ground truth besides the answers: the server's log holds no traceback afterwards.
"""

from __future__ import annotations

import json
from typing import Any

import pytest
from serve_helpers import SCENES, Server, serve

JSON = {"Content-Type": "application/json"}
HUGE = 10**400
#: Scenes whose services cover every service type a fixture binds (drive, arm, joints).
SCENES_WITH_NUMBERS = [SCENES / "arm_on_base.toml", SCENES / "mjcf_arm_on_base.toml"]


def _numeric(schema: dict[str, Any]) -> bool:
    if schema.get("type") == "array":
        return _numeric(schema.get("items", {}))
    return schema.get("type") in ("number", "integer")


def _range(schema: dict[str, Any]) -> tuple[float, float] | None:
    leaf = schema.get("items", schema)
    return (leaf["minimum"], leaf["maximum"]) if "minimum" in leaf else None


def request_fields(document: dict[str, Any]) -> list[tuple[str, str, Any, dict[str, Any]]]:
    """(path, field, body builder, schema) for every field of every POST body in an OpenAPI document.

    The builder makes the body that puts a value in that field (in an array for an array field). A command's
    arguments appear twice: by name (``{"args": {"metres": v}}``) and by position (``{"args": [0, v]}``).
    Routes without fields get an unknown field ``x``.
    """
    out: list[tuple[str, str, Any, dict[str, Any]]] = []
    for path, operations in document["paths"].items():
        body = operations.get("post", {}).get("requestBody")
        if body is None:
            continue
        schema = body["content"]["application/json"]["schema"]
        properties = schema.get("properties", {})
        if not properties:
            out.append((path, "x", lambda v: {"x": v}, {}))
        for name, prop in properties.items():
            if name != "args":
                out.append((path, name, lambda v, name=name: {name: v}, prop))
                continue
            positional, named = prop["oneOf"]
            for index, (arg, arg_schema) in enumerate(named["properties"].items()):
                assert positional["prefixItems"][index]["title"] == arg

                def wrap(v: Any, s: dict[str, Any] = arg_schema) -> Any:
                    return [v] if s.get("type") == "array" else v

                out.append((path, f"args.{arg}", lambda v, a=arg, w=wrap: {"args": {a: w(v)}}, arg_schema))
                out.append((path, f"args.{arg}", lambda v, i=index, w=wrap: {"args": [0] * i + [w(v)]}, arg_schema))
    return out


def _post(server: Server, path: str, raw: bytes) -> tuple[int, Any]:
    return server.request("POST", path, raw=raw, headers=JSON)


@pytest.mark.parametrize("scene", SCENES_WITH_NUMBERS, ids=[p.stem for p in SCENES_WITH_NUMBERS])
def test_every_numeric_field_of_every_route_is_bounded_and_named(scene):
    problems: list[str] = []
    cases = numeric = 0
    with serve(scene, "--lockstep") as server:
        document = server.get("/openapi.json")
        before = server.get("/api/state")
        fields = request_fields(document)
        for path, field, build, schema in fields:
            bounds = _range(schema)
            if _numeric(schema):
                numeric += 1
                if bounds is None:
                    problems.append(f"{path} {field}: the schema gives no range")
                    continue
            low, high = bounds or (-1e6, 1e6)
            beyond = [HUGE, -HUGE, high * 10 + 1, low * 10 - 1 if low < 0 else low - 1]
            for value in beyond:
                cases += 1
                status, answer = _post(server, path, json.dumps(build(value)).encode())
                shown = f"{path} {field}={str(value)[:12]}: {status} {answer}"
                if not (isinstance(answer, dict) and 400 <= status < 500 and answer.get("field") == field):
                    problems.append(shown)
                elif bounds is not None and f"[{low:g}, {high:g}]" not in answer["error"]:
                    problems.append(f"{shown} (the range is not named)")
            if bounds is not None and field.startswith("args."):  # a bound itself is not out of range (lockstep:
                # a command at its bound is applied, not run; steps or a rate at theirs would change the world)
                for value in (low, high):
                    status, answer = _post(server, path, json.dumps(build(value)).encode())
                    if status == 500 or (isinstance(answer, dict) and "must be in" in answer.get("error", "")):
                        problems.append(f"{path} {field}={value}: refused at its bound: {answer}")
        after = server.get("/api/state")
    assert not problems, "\n".join(problems[:40])
    assert numeric >= 17 and cases >= 4 * len(fields)
    assert after["time"] == before["time"] and after["steps"] == before["steps"]  # nothing out of range stepped
    assert "Traceback" not in server.output[1] and "Exception" not in server.output[1], server.output[1][-3000:]


def test_every_post_route_refuses_deep_json_before_parsing_it():
    problems: list[str] = []
    with serve(SCENES / "mjcf_arm_on_base.toml", "--lockstep") as server:
        posts = [p for p, ops in server.get("/openapi.json")["paths"].items() if "post" in ops]
        assert len(posts) >= 20
        drive = "/api/services/DriveService/base/cmd_vel"
        for path in posts:
            deep = b'{"args": ' + b"[" * 30000 + b"]" * 30000 + b"}"
            for raw in (deep, b"[" * 30000, b"{" * 30000, b"[" * 33 + b"]" * 33):
                status, answer = _post(server, path, raw)
                if status != 400 or not isinstance(answer, dict) or answer["field"] != "body":
                    problems.append(f"{path} {raw[:12]!r}: {status} {answer}")
                elif "nest deeper than 32" not in answer["error"]:
                    problems.append(f"{path}: {answer['error']}")
        # 32 levels are parsed (and refused for what they are); brackets inside strings do not count
        status, answer = _post(server, drive, b"[" * 32 + b"]" * 32)
        assert status == 422 and answer["field"] == "body", answer
        status, answer = _post(server, drive, json.dumps({"args": ["[" * 1000 + "{" * 1000, 0]}).encode())
        assert status == 422 and answer["field"] == "args" and "nest" not in answer["error"], answer
        assert server.post(drive, {"args": [0.1, 0.0]})["applied"]  # the server still works
    assert not problems, "\n".join(problems[:40])
    assert "Traceback" not in server.output[1] and "Exception" not in server.output[1], server.output[1][-3000:]


def test_the_published_document_gives_every_request_number_a_range():
    from simrun.run.session import prepare
    from simrun.scene.scene_file import load_scene
    from simrun.serve.catalogue import build_catalogue
    from simrun.serve.loop import MAX_RATE, MAX_STEPS, MIN_RATE
    from simrun.serve.openapi import openapi_document

    world = load_scene(SCENES / "mjcf_arm_on_base.toml")
    prepare(world)
    document = openapi_document(build_catalogue(world))
    fields = request_fields(document)
    unbounded = [(p, f) for p, f, _, s in fields if _numeric(s) and _range(s) is None]
    assert not unbounded
    ranges = {(p, f): _range(s) for p, f, _, s in fields}
    assert ranges["/api/step", "steps"] == (1, MAX_STEPS)
    assert ranges["/api/rate", "rate"] == (MIN_RATE, MAX_RATE)
    assert ranges["/api/step", "seconds"] == (0, MAX_STEPS * world.model.opt.timestep)
