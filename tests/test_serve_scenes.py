"""simrun serve over every fixture scene with services or sensors: each is listed, read and callable by name."""

from __future__ import annotations

import io
import time

import pytest
from PIL import Image
from serve_helpers import SCENES, serve

SCENE_FILES = sorted(
    p for p in SCENES.glob("*.toml") if "[[services]]" in p.read_text() or "[[sensors]]" in p.read_text()
)


@pytest.mark.parametrize("scene", SCENE_FILES, ids=[p.stem for p in SCENE_FILES])
def test_every_service_and_sensor_of_the_scene_is_reachable(scene):
    from simrun.errors import SimrunError
    from simrun.scene.scene_file import load_scene

    try:
        world = load_scene(scene)
        world.check_bindings()
    except SimrunError as exc:
        pytest.skip(f"the scene itself is refused: {exc}")
    bindings = [(s["type"], s["entity"]) for s in world.services]
    sensors = dict(world.sensors)
    with serve(scene) as server:
        listed = server.get("/api/world")
        assert [(s["type"], s["entity"]) for s in listed["services"]] == bindings
        assert [s["name"] for s in listed["sensors"]] == list(sensors)
        assert [e["name"] for e in listed["entities"]] == [name for name, _ in world]
        paths = server.get("/openapi.json")["paths"]
        for service in listed["services"]:
            state = server.get(service["path"])
            assert set(state["state"]) == set(service["queries"]) and service["queries"]
            for call in service["commands"]:
                assert f"{service['path']}/{call}" in paths
            free = [c for c, info in service["commands"].items() if all("default" in p for p in info["parameters"])]
            for call in free:  # the commands that need no argument (all_stop, reset_encoders...) run as they are
                status, answer = server.request("POST", f"{service['path']}/{call}", {})
                assert status == 200 and answer["applied"], (call, answer)
        deadline = time.monotonic() + 60
        for sensor in listed["sensors"]:
            while (reading := server.get(f"/api/sensors/{sensor['name']}"))["samples"] == 0:
                assert time.monotonic() < deadline, sensor
                time.sleep(0.1)
            assert reading["reading"] is not None
            if sensor["image"]:
                status, png = server.request("GET", f"/api/sensors/{sensor['name']}/image")
                assert status == 200 and Image.open(io.BytesIO(png)).format == "PNG"


def test_an_arm_on_a_child_entity_moves_to_joint_targets_sent_as_an_array():
    with serve(SCENES / "arm_on_base.toml", "--rate", "20") as server:
        path = "/api/services/ArmService/base/arm"  # the entity's full name has a slash
        joints = server.get(path)["state"]["joint_states"]
        target = list(joints["positions"])
        target[0] += 0.4  # the base yaw joint
        answer = server.post(f"{path}/move_to", {"args": {"joint_positions": target, "duration": 1.0}})
        assert answer["applied"]
        deadline = time.monotonic() + 30
        while server.get(path)["state"]["busy"]:
            assert time.monotonic() < deadline
            time.sleep(0.05)
        time.sleep(0.1)  # 2 simulated seconds at 20x: the servo settles
        reached = server.get(path)["state"]["joint_states"]
        assert reached["names"] == joints["names"]
        assert reached["positions"][0] == pytest.approx(target[0], abs=0.02)
        status, refused = server.request("POST", f"{path}/move_to", {"args": [target[:2], 1.0]})
        assert status == 422 and refused["field"] == "args" and "joint" in refused["error"]
