"""simrun serve --edit: edits over HTTP on a real server on 127.0.0.1 (simrun/serve/edit_routes.py).

Ground truth: MuJoCo's contacts and models of the server's own saved state (its ``[state]`` table, loaded
again in this process), a plain MjModel of the same friction (tests/test_edit.py's), the in-process library
applying the same edit.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import threading
import time
import tomllib
from pathlib import Path

import mujoco
import numpy as np
import pytest
from scene_text import boebot_scene
from serve_helpers import SCENES, serve
from test_edit import _slide

from simrun.client import Client, ClientError
from simrun.scene.scene_file import load_scene
from simrun.world import edit

BUMPER_SCENE = boebot_scene(
    tail="""
[[sensors]]
type = "Bumper"
name = "bump"
entity = "boebot"
rate = 50.0
"""
)
CRATE = {"type": "Box", "name": "crate", "dimensions": [0.2, 0.6, 0.2], "mass": 20.0, "free": True,
         "pose": {"position": [0.35, 0.0, 0.1]}}  # fmt: skip


def _scene(tmp_path: Path, text: str = BUMPER_SCENE) -> Path:
    path = tmp_path / "scene" / "bump.toml"
    path.parent.mkdir(exist_ok=True)
    path.write_text(text)
    return path


def _current(sim: Client, tmp_path: Path, name: str = "now.toml") -> tuple[Path, dict]:
    """The server's world saved with its [state] (the running model exactly), in the scene's folder."""
    path = tmp_path / "scene" / name
    text = sim.save_scene(str(path), state="current")
    return path, tomllib.loads(text)


def test_a_box_inserted_in_front_of_a_driving_robot_presses_its_bumper_and_moved_away_lets_it_pass(tmp_path):
    with serve(_scene(tmp_path), "--lockstep", "--edit") as server:
        sim = Client(server.url)
        sim.service("DriveService", "boebot").drive_distance(1.0, 0.8)
        sim.step(seconds=0.3)
        assert sim.insert(CRATE) == ["crate"]
        pressed = None
        for _ in range(40):
            sim.step(seconds=0.1)
            reading = sim.sensor("bump")["reading"]
            if reading and reading["pressed"]:
                pressed = reading
                break
        assert pressed is not None and "crate/geom" in pressed["touching"]
        path, _ = _current(sim, tmp_path)
        world = load_scene(path)  # the server's state, in MuJoCo here: its own contacts
        from simrun.run.session import prepare

        prepare(world)
        mujoco.mj_forward(world.model, world.data)
        chassis, crate = world.model.geom("boebot/chassis").id, world.model.geom("crate/geom").id
        pairs = {tuple(sorted(map(int, c))) for c in world.data.contact.geom[: world.data.ncon]}
        assert tuple(sorted((chassis, crate))) in pairs
        x_blocked = sim.pose("boebot")[0]
        assert x_blocked < 0.3
        moved = sim.teleport("crate", [0.35, 3.0, 0.1])
        assert moved["pose"][:3] == [0.35, 3.0, 0.1] and not moved["recompiled"]
        sim.step(seconds=4.0)
        assert sim.pose("boebot")[0] > 0.5  # past where the crate stood
        assert not sim.sensor("bump")["reading"]["pressed"]


def test_untouched_state_is_bit_identical_across_an_edit_and_a_refused_edit_changes_nothing(tmp_path):
    with serve(_scene(tmp_path), "--lockstep", "--edit") as server:
        sim = Client(server.url)
        sim.service("DriveService", "boebot").drive_distance(0.5)
        sim.step(seconds=0.7)
        _, before = _current(sim, tmp_path, "a.toml")
        sim.insert({"type": "Sphere", "name": "ball", "radius": 0.05, "free": True,
                    "pose": {"position": [3.0, 3.0, 0.05]}})  # fmt: skip
        _, after = _current(sim, tmp_path, "b.toml")
        n, m = len(before["state"]["qpos"]), len(before["state"]["qvel"])
        assert after["state"]["qpos"][:n] == before["state"]["qpos"]  # floats written as repr: exact
        assert after["state"]["qvel"][:m] == before["state"]["qvel"]
        assert after["state"]["time"] == before["state"]["time"]
        assert json.loads(after["state"]["controllers"]) == json.loads(before["state"]["controllers"])
        refused = [
            ("POST", "/api/entities", {"entity": {"type": "Nope", "name": "x"}}, 422, "entity.type"),
            ("POST", "/api/entities", {"entity": {"type": "Box", "name": "ball"}}, 409, "entity.name"),
            (
                "POST",
                "/api/entities",
                {"entity": {"type": "Box", "name": "k", "kinematic": True, "parent": "ball"}},
                422,
                "entity.parent",
            ),
            (
                "POST",
                "/api/entities",
                {"entity": {"type": "MeshEntity", "name": "m", "asset": "../../etc/x.mbin"}},
                422,
                "entity.asset",
            ),
            (
                "POST",
                "/api/entities",
                {"entities": [{"type": "Box", "name": f"b{k}"} for k in range(101)]},
                422,
                "entities",
            ),
            ("PATCH", "/api/entities/ball", {"radius": -1.0}, 422, None),
            ("PATCH", "/api/entities/ball", {"mass": 1e9}, 422, "mass"),
            ("PATCH", "/api/entities/nobody", {"mass": 1.0}, 404, "name"),
            ("DELETE", "/api/entities/nobody", {}, 404, "name"),
            ("POST", "/api/entities/ball/teleport", {"position": [0, 0]}, 422, "position"),
            ("POST", "/api/entities/ball/force", {"force": [0, 0, 1], "duration": 0}, 422, "duration"),
            ("PATCH", "/api/edit/sensors/bump", {"rate": 1e7}, 422, "rate"),
            ("POST", "/api/edit/world", {"gravity": [0, 0, "down"]}, 422, "gravity[2]"),
        ]
        for method, path, body, status, field in refused:
            got, answer = server.request(method, path, body)
            assert got == status, (path, body, got, answer)
            if field is not None:
                assert answer["field"] == field, (path, answer)
        nan = server.request("POST", "/api/entities", raw=b'{"entity": {"type": "Box", "name": "n", "mass": NaN}}')
        assert nan[0] == 400 and nan[1]["field"] == "body"
        over = {"entities": [{"type": "Box", "name": f"b{k}"} for k in range(3000)]}  # ~90 kB
        assert server.request("POST", "/api/entities", over)[0] == 413
        many = {"entities": [{"type": "Box", "name": f"b{k}"} for k in range(10**6)]}  # ~31 MB
        try:
            status = server.request("POST", "/api/entities", many)[0]
        except OSError:  # refused at 64 kB: the server answers 413 and closes while the rest is being sent
            status = 413
        assert status == 413
        _, again = _current(sim, tmp_path, "c.toml")
        assert again == after  # every refusal left the world exactly as it was
        sim.step(steps=10)


def test_floor_friction_over_http_slides_the_box_as_mujocos_own_model_predicts(tmp_path):
    scene = _scene(
        tmp_path,
        '[world]\ntimestep = 0.002\n[[entities]]\ntype = "Ground"\nname = "floor"\n'
        '[[entities]]\ntype = "Box"\nname = "box"\nmass = 5.0\nfree = true\ndimensions = [0.2, 0.2, 0.2]\n'
        "pose = { position = [0.0, 0.0, 0.1] }\n",
    )
    with serve(scene, "--lockstep", "--edit") as server:
        sim = Client(server.url)
        slides = {}
        for mu in (0.2, 0.5):
            sim.change("floor", {"material": {"dynamic_friction": mu}})
            start = sim.teleport("box", [0.0, 0.0, 0.1], [1.0, 0.0, 0.0, 0.0])["pose"][0]
            sim.apply_force("box", force=[40.0, 0.0, 0.0], duration=0.5)
            sim.step(seconds=1.5)
            slides[mu] = sim.pose("box")[0] - start
            # the box was at rest on the floor before each push, as in the plain model (which starts 0.1 up)
            assert slides[mu] == pytest.approx(_slide(mu, 40.0, 0.5, True, tmp_path), abs=2e-3), mu
        assert slides[0.2] > 2 * slides[0.5] > 0.05


def test_saved_scene_checks_and_compiles_to_the_model_the_library_builds(tmp_path):
    folder = tmp_path / "scene"
    folder.mkdir()
    for item in ("head_on_table.toml", "head.mbin"):
        shutil.copy(SCENES / item, folder / item)
    head2 = {"type": "MeshEntity", "name": "head2", "asset": "head", "free": True, "mass": 1.0,
             "pose": {"position": [0.3, 0.0, 1.0]}}  # fmt: skip
    with serve(folder / "head_on_table.toml", "--lockstep", "--edit") as server:
        sim = Client(server.url)
        sim.step(seconds=0.2)
        sim.insert(head2)
        sim.change("table", color=[0.2, 0.3, 0.4, 1.0])
        listed = {e["name"]: e for e in sim.entities()}
        assert listed["head2"]["values"]["asset"] == "head" and len(listed["head2"]["pose"]) == 7
        assert sim.entity("table")["schema"]["type"] == "Box"
        out = folder / "saved.toml"
        text = sim.save_scene(str(out))
        lid = sim.save_entities(["head2"], str(folder / "head2.toml"))
    assert 'head = "head.mbin"' in text and str(tmp_path) not in text
    for path in (out, folder / "head2.toml"):
        done = subprocess.run([str(Path(sys.executable).parent / "simrun"), "check", str(path)],
                              capture_output=True, text=True, timeout=300)  # fmt: skip
        assert done.returncode == 0, done.stdout + done.stderr
    mine = load_scene(folder / "head_on_table.toml")
    edit.insert(mine, head2)
    edit.change(mine, "table", {"color": [0.2, 0.3, 0.4, 1.0]})
    saved = load_scene(out).model
    for field in ("body_mass", "body_inertia", "geom_type", "geom_size", "geom_rgba", "geom_friction", "nmesh"):
        assert np.array_equal(getattr(saved, field), getattr(mine.model, field)), field
    assert [saved.body(i).name for i in range(saved.nbody)] == [mine.model.body(i).name for i in range(saved.nbody)]
    assert "head2" in lid


def test_edits_are_refused_without_edit_and_an_edit_storm_gets_429(tmp_path):
    with serve(_scene(tmp_path), "--lockstep") as server:
        status, answer = server.request("POST", "/api/entities", {"entity": CRATE})
        assert status == 403 and "--edit" in answer["error"]
        assert server.get("/api/edit")["allowed"] is False
        assert [e["name"] for e in server.get("/api/entities")] == ["ground", "boebot"]  # reading is allowed
        document = server.get("/openapi.json")
        assert {"post", "get"} <= set(document["paths"]["/api/entities"])
        assert "patch" in document["paths"]["/api/entities/{name}"]
    with serve(_scene(tmp_path), "--rate", "1", "--edit") as server:
        sim = Client(server.url)
        sim.insert({"type": "Sphere", "name": "ball", "radius": 0.05, "free": True})
        statuses: list[int] = []
        lock = threading.Lock()
        began = time.monotonic()

        def storm() -> None:
            for k in range(250):
                got, _ = server.request("POST", "/api/entities/ball/teleport", {"position": [1.0, 0.001 * k, 0.05]})
                with lock:
                    statuses.append(got)

        threads = [threading.Thread(target=storm) for _ in range(4)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        took = time.monotonic() - began
        assert set(statuses) <= {200, 429} and statuses.count(429) > 0
        assert statuses.count(200) <= 50 + 50 * took + 1  # the budget: 50 a second after a burst of 50
        t0 = sim.state()["time"]
        time.sleep(0.5)
        assert sim.state()["time"] > t0  # the world runs on
        with pytest.raises(ClientError) as refused:
            sim.insert({"type": "Box", "name": "ball"})
        assert refused.value.status in (409, 429)


def _five_edits(sim: Client, steps: tuple[float, float, float], teleport: list[float]) -> None:
    """Insert the crate, change the floor's friction, push the crate, teleport it, change the bumper's rate:
    ``steps`` are the simulated seconds stepped after the insert, the push and the rate change (lockstep)."""
    sim.insert(CRATE)
    sim.step(seconds=steps[0])
    sim.change("ground", {"material": {"dynamic_friction": 0.5}})
    sim.apply_force("crate", force=[0.0, 300.0, 0.0], duration=0.2)
    sim.step(seconds=steps[1])
    sim.teleport("crate", teleport)
    sim.change_sensor("bump", rate=25.0)
    sim.step(seconds=steps[2])


def test_the_servers_edit_log_replays_to_the_same_state_bit_for_bit(tmp_path):
    from simrun.run.session import prepare
    from simrun.world.edit_apply import EditRecord

    scene = _scene(tmp_path)
    with serve(scene, "--lockstep", "--edit") as server:
        sim = Client(server.url)
        sim.step(seconds=0.2)
        _five_edits(sim, (0.3, 0.4, 0.5), teleport=[1.0, 1.0, 0.3])
        log = server.get("/api/edit/log")["edits"]
        _, saved = _current(sim, tmp_path)
    assert [e["kind"] for e in log] == ["insert", "change", "apply_force", "teleport", "change_sensor"]
    world = load_scene(scene)
    prepare(world)
    dt = world.model.opt.timestep
    records = [EditRecord(e["t"], e["kind"], e["args"]) for e in log]
    while world.time < saved["state"]["time"] - dt / 2:
        while records and records[0].t <= world.time + dt / 2:
            records.pop(0).apply(world)
        world.step(1)
    assert world.time == saved["state"]["time"]
    assert [float(v) for v in world.data.qpos] == saved["state"]["qpos"]
    assert [float(v) for v in world.data.qvel] == saved["state"]["qvel"]


def test_undo_takes_back_the_last_edit_over_http(tmp_path):
    with serve(_scene(tmp_path), "--lockstep", "--edit") as server:
        sim = Client(server.url)
        sim.step(seconds=0.1)
        sim.insert(CRATE)
        sim.change("crate", mass=3.0)
        sim.apply_force("crate", force=[0.0, 0.0, 50.0], duration=0.1)
        status, answer = server.request("POST", "/api/edit/undo", {})
        assert status == 409 and "apply_force" in answer["error"]
        assert server.post("/api/edit/undo", {})["undone"] == "change"
        assert sim.entity("crate")["values"]["mass"] == 20.0
        assert server.post("/api/edit/undo", {})["undone"] == "insert"
        assert [e["name"] for e in sim.entities()] == ["ground", "boebot"]
        assert "crate" not in sim.state()["poses"]
        assert server.request("POST", "/api/edit/undo", {})[0] == 409  # nothing left
        assert [e["kind"] for e in server.get("/api/edit/log")["edits"]] == [
            "insert", "change", "apply_force", "change", "remove",
        ]  # fmt: skip


def test_a_recorded_session_with_five_edits_re_simulates_bit_identically(tmp_path):
    from serve_helpers import SIMRUN

    scene = _scene(tmp_path)
    record = tmp_path / "run.simlog"
    with serve(scene, "--lockstep", "--edit", "--record", str(record)) as server:
        sim = Client(server.url)
        sim.service("DriveService", "boebot").drive_distance(1.0, 0.8)
        sim.step(seconds=0.3)
        _five_edits(sim, (0.4, 0.4, 1.0), teleport=[0.35, 3.0, 0.1])
    env = {"MUJOCO_GL": "egl", "PATH": str(Path(sys.executable).parent)}
    done = subprocess.run([SIMRUN, "resim", str(record)], capture_output=True, text=True, timeout=300, env=env)
    assert done.returncode == 0 and "bit-identical" in done.stdout, done.stdout + done.stderr
    from simrun.record.simlog import Simlog
    from simrun.world.edit_apply import EditRecord

    log = Simlog(record)
    kinds = [r.command.kind for r in log.events() if isinstance(r.command, EditRecord)]
    assert kinds == ["insert", "change", "apply_force", "teleport", "change_sensor"]
    html = tmp_path / "run.html"
    done = subprocess.run([SIMRUN, "replay", str(record), "--html", str(html)], capture_output=True, text=True,
                          timeout=300, env=env)  # fmt: skip
    assert done.returncode == 0 and html.stat().st_size > 0, done.stderr  # the edited world (test_replay_edits)


def test_an_entitys_sensor_and_service_settings_are_read_back_as_changed(tmp_path):
    """GET /api/entities/NAME gives each sensor's and service's table now; the sample count agrees with the rate."""
    with serve(_scene(tmp_path), "--lockstep", "--edit") as server:
        sim = Client(server.url)
        bot = sim.entity("boebot")
        assert bot["sensor_settings"]["bump"]["rate"] == 50.0  # the scene's table
        assert bot["service_settings"]["DriveService"] == {"type": "DriveService", "entity": "boebot"}
        sim.step(seconds=1.0)
        first = sim.sensor("bump")["samples"]
        assert sim.change_sensor("bump", rate=20.0)["sensor"]["rate"] == 20.0
        sim.change_service("DriveService", "boebot", limits={"max_linear": 0.3}, rate=25.0)
        bot = sim.entity("boebot")
        assert bot["sensor_settings"]["bump"]["rate"] == 20.0
        assert bot["service_settings"]["DriveService"]["limits"] == {"max_linear": 0.3}
        assert bot["service_settings"]["DriveService"]["rate"] == 25.0
        sim.step(seconds=2.0)
        after = sim.sensor("bump")
        # ground truth: the sensor's own count over 1 s at 50 Hz, then 2 s at the new 20 Hz
        assert first == 50 and after["samples"] - first == 40, (first, after)
        assert sim.entity("ground")["sensor_settings"] == {} and sim.entity("ground")["service_settings"] == {}
