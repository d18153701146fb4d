"""The served catalogue is live: a service added or removed by an edit is callable (or gone) over HTTP at once.

Real ``simrun serve --lockstep --edit`` on 127.0.0.1; the effect of each call is read from MuJoCo's own state
(the server's world saved with its ``[state]`` and loaded here, or ``data.qpos`` by joint address).
"""

from __future__ import annotations

import shutil
from pathlib import Path

import mujoco
import pytest
from scene_text import boebot_scene
from serve_helpers import CHECKOUT, serve

from simrun.client import Client, ClientError
from simrun.run.session import prepare
from simrun.scene.scene_file import load_scene

SCENE = boebot_scene(
    drive=False,
    entities="""
[[entities]]
type = "MjcfRobot"
name = "arm"
file = "arm/arm.xml"
pose = { position = [0.0, 2.0, 0.0] }
""",
)


def _scene(tmp_path: Path) -> Path:
    folder = tmp_path / "scene"
    shutil.copytree(CHECKOUT / "fixtures" / "mjcf" / "arm", folder / "arm")
    path = folder / "live.toml"
    path.write_text(SCENE)
    return path


def _mujoco_state(sim: Client, tmp_path: Path) -> mujoco.MjData:
    """The server's world now, loaded here from its saved scene with ``[state]``, and forwarded by MuJoCo."""
    path = tmp_path / "scene" / "now.toml"
    sim.save_scene(str(path), state="current")
    world = load_scene(path)
    prepare(world)
    mujoco.mj_forward(world.model, world.data)
    return world


def test_a_service_added_by_an_edit_is_called_over_http_and_moves_the_world(tmp_path):
    with serve(_scene(tmp_path), "--lockstep", "--edit") as server:
        sim = Client(server.url)
        drive_path = "/api/services/DriveService/boebot/drive_distance"
        status, answer = server.request("POST", drive_path, {"args": [0.3, 0.4]})
        assert status == 404 and answer["field"] == "entity"  # nothing bound yet
        assert drive_path not in server.get("/openapi.json")["paths"]

        sim.add_service({"type": "DriveService", "entity": "boebot"})
        sim.add_service({"type": "JointService", "entity": "arm"})
        listed = {(s["type"], s["entity"]) for s in server.get("/api/services")}
        assert listed == {("DriveService", "boebot"), ("JointService", "arm")}
        assert {(s["type"], s["entity"]) for s in server.get("/api/world")["services"]} == listed
        paths = server.get("/openapi.json")["paths"]
        assert drive_path in paths and "/api/services/JointService/arm/set_positions" in paths

        x0 = sim.pose("boebot")[0]
        sim.service("DriveService", "boebot").drive_distance(0.3, 0.8)
        sim.call("JointService", "arm", "set_positions", ["yaw"], [0.5])
        sim.step(seconds=6.0)
        assert sim.service("DriveService", "boebot").state()["busy"] is False
        odometry = sim.service("DriveService", "boebot").state()["odometry"]
        assert odometry["x"] == pytest.approx(0.3, abs=0.03)

        world = _mujoco_state(sim, tmp_path)
        model, data = world.model, world.data
        root = model.body("boebot").id
        assert float(data.xpos[root][0]) - x0 == pytest.approx(0.3, abs=0.03)  # MuJoCo's own body position
        yaw = model.joint("arm/yaw")
        assert float(data.qpos[yaw.qposadr[0]]) == pytest.approx(0.5, abs=0.02)

        # a number out of the new path's schema range is refused as on any service path
        status, answer = server.request("POST", drive_path, {"args": [1e300, 0.4]})
        assert status == 422 and answer["field"].startswith("args")

        sim.remove_service("DriveService", "boebot")
        with pytest.raises(ClientError) as gone:
            sim.service("DriveService", "boebot").drive_distance(0.3, 0.8)
        assert gone.value.status == 404 and gone.value.field == "entity"
        assert drive_path not in server.get("/openapi.json")["paths"]
        assert [s["type"] for s in server.get("/api/services")] == ["JointService"]


def test_a_sensor_added_by_an_edit_is_read_over_http(tmp_path):
    with serve(_scene(tmp_path), "--lockstep", "--edit") as server:
        sim = Client(server.url)
        status, answer = server.request("GET", "/api/sensors/bump")
        assert status == 404 and answer["field"] == "name"
        sim.add_sensor({"type": "Bumper", "name": "bump", "entity": "boebot", "rate": 50.0})
        assert [s["name"] for s in server.get("/api/sensors")] == ["bump"]
        sim.step(seconds=0.1)
        reading = sim.sensor("bump")
        assert reading["samples"] >= 4 and reading["reading"]["pressed"] is False
        sim.change_sensor("bump", rate=10.0)
        assert server.get("/api/sensors")[0]["rate_hz"] == pytest.approx(10.0)
