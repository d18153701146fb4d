"""Issue 14 item 5: save_scene keeps relative paths working from another folder, saves services created in code,
and with state="current" a reloaded world continues the motion bit for bit."""

import shutil
import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from simrun import World, load_scene, save_scene, scene_text
from simrun.errors import SceneError, SimrunError
from simrun.sensors.robot_state import GPS
from simrun.services.drive_service import DriveService

SCENES = Path(__file__).resolve().parent.parent / "fixtures" / "scenes"


def test_relative_paths_are_rewritten_for_the_new_folder(tmp_path):
    shutil.copytree(SCENES, tmp_path / "scenes")
    world = load_scene(tmp_path / "scenes" / "head_on_table.toml")
    world.insert(load_scene(tmp_path / "scenes" / "basic.toml").entity("globe"))
    target = tmp_path / "elsewhere" / "deeper" / "saved.toml"
    target.parent.mkdir(parents=True)
    save_scene(world, target)
    text = target.read_text()
    assert 'texture = "../../scenes/globe.png"' in text
    assert "../../scenes/head.mbin" in text
    again = load_scene(target)  # loads from its own folder: the texture and the mesh are found
    assert again.model.ntex == world.model.ntex and again.model.nmesh == world.model.nmesh
    assert 'texture = "globe.png"' in scene_text(world)  # without a folder, paths stay as written


def test_services_created_in_code_are_saved(tmp_path):
    world = load_scene(SCENES / "boebot.toml")
    world.services.clear()
    DriveService(world, "boebot")  # constructed directly, not bound in the scene
    world.add_sensor({"type": "GPS", "name": "gps", "entity": "boebot", "rate": 5.0})
    save_scene(world, tmp_path / "saved.toml")
    again = load_scene(tmp_path / "saved.toml")
    assert again.services == [{"type": "DriveService", "entity": "boebot"}]
    assert again.service("DriveService", "boebot") is not None and set(again.sensors) == {"gps"}
    GPS(world, "boebot")  # a sensor constructed directly: its parameters are unknown, saving it is refused
    with pytest.raises(SimrunError, match="constructed directly"):
        save_scene(world, tmp_path / "refused.toml")
    assert not (tmp_path / "refused.toml").exists()


def run_with_commands(world: World, seconds: float) -> None:
    drive = world.service("DriveService", "boebot")
    steps = round(seconds / world.options.timestep)
    for _ in range(steps):
        if abs(world.data.time - 0.5) < 1e-9:
            drive.drive_distance(1.0, 0.6)  # still driving at t = 2 s
        world.step(1)


def test_save_current_state_and_continue_bit_for_bit(tmp_path):
    shutil.copytree(SCENES, tmp_path / "scenes")
    world = load_scene(tmp_path / "scenes" / "boebot.toml")
    world.add_sensor({"type": "IMU", "name": "imu", "entity": "boebot", "noise": 0.01, "seed": 3})
    run_with_commands(world, 2.0)
    assert world.data.time == pytest.approx(2.0) and world.service("DriveService", "boebot").busy
    saved = tmp_path / "other" / "at2s.toml"
    saved.parent.mkdir()
    save_scene(world, saved, state="current")
    assert "[state]" in saved.read_text() and "qvel = [" in saved.read_text()

    again = load_scene(saved)
    assert again.data.time == world.data.time
    assert again.data.qpos.tobytes() == world.data.qpos.tobytes()
    assert again.data.qvel.tobytes() == world.data.qvel.tobytes()
    assert np.linalg.norm(world.data.qvel) > 0.01  # it is moving
    world.step(1000)
    again.step(1000)
    assert again.data.time == world.data.time
    assert again.data.qpos.tobytes() == world.data.qpos.tobytes()  # the motion continued identically
    assert again.sensors["imu"].reading == world.sensors["imu"].reading  # the noise generator continued too
    moved = world.body("boebot").xpos[:2]
    assert np.linalg.norm(moved - np.array([1.0, 1.0])) > 0.15  # it drove on after the reload

    initial = tmp_path / "other" / "initial.toml"
    save_scene(world, initial)
    assert "[state]" not in initial.read_text() and load_scene(initial).data.time == 0.0


def test_a_state_that_does_not_fit_is_refused_with_its_line(tmp_path):
    world = load_scene(SCENES / "boebot.toml")
    world.step(10)
    save_scene(world, tmp_path / "s.toml", state="current")
    text = (tmp_path / "s.toml").read_text()
    bad = text.replace("qpos = [", "qpos = [1.0, ")
    (tmp_path / "bad.toml").write_text(bad)
    line = bad.splitlines().index(next(x for x in bad.splitlines() if x.startswith("qpos"))) + 1
    with pytest.raises(SceneError, match=rf"bad\.toml:{line}: state\.qpos: expected \d+ number\(s\)"):
        load_scene(tmp_path / "bad.toml")
    doc = tomllib.loads(text)
    doc["state"]["qvel"][0] = float("nan")
    (tmp_path / "nan.toml").write_text(tomli_w.dumps(doc))
    with pytest.raises(SceneError, match=r"state\.qvel: expected finite numbers, got nan"):
        load_scene(tmp_path / "nan.toml")
