"""Seeds, --vary and jitter: parsed strictly, drawn reproducibly and independently, written into the scene."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from simrun.scene.scene_file import load_scene
from simrun.scenetest.runner import entity_class
from simrun.scenetest.vary import VaryError, apply, check_key, draw, jitter, parse_seeds, parse_vary, variations

SCENE = Path(__file__).parent.parent / "fixtures" / "scenes" / "boebot_square.toml"


def doc() -> dict:
    return tomllib.loads(SCENE.read_text(encoding="utf-8"))


def test_seeds() -> None:
    assert parse_seeds("0:4") == [0, 1, 2, 3]
    assert parse_seeds("7") == [7]
    assert parse_seeds("3,1,2") == [3, 1, 2]
    for bad in ("4:2", "a", "-1", "1,1", "0:1.5"):
        with pytest.raises(VaryError):
            parse_seeds(bad)


def test_vary_forms() -> None:
    grid = parse_vary("box.y=0.5:1.5:11")
    assert grid.kind == "grid" and grid.values == tuple(round(0.5 + 0.1 * k, 12) for k in range(11))
    assert parse_vary("box.mass=uniform(1, 2)").values == (1.0, 2.0)
    assert parse_vary("laser.noise=normal(0.01,0.002)").kind == "normal"
    assert parse_vary("box.mass=choice(1,5,9)").values == (1.0, 5.0, 9.0)
    assert parse_vary("box.mass=3").kind == "value"
    for bad in (
        "box.mass",
        "mass=1:2:3",
        "box.mass=1:2",
        "box.mass=uniform(2,1)",
        "box.mass=normal(0,-1)",
        "box.mass=1:2:0",
        "box.mass=nan",
        "box.mass=gamma(1,2)",
    ):
        with pytest.raises(VaryError):
            parse_vary(bad)


def test_grids_cross_and_distributions_are_per_seed() -> None:
    axes = [parse_vary("box.y=0:1:3"), parse_vary("box.mass=uniform(1,2)"), parse_vary("boebot.x=choice(1,2)")]
    assert variations(axes) == [{"box.y": 0.0}, {"box.y": 0.5}, {"box.y": 1.0}]
    assert variations([parse_vary("box.y=0:1:2"), parse_vary("box.x=1:2:2")]) == [
        {"box.y": 0.0, "box.x": 1.0},
        {"box.y": 0.0, "box.x": 2.0},
        {"box.y": 1.0, "box.x": 1.0},
        {"box.y": 1.0, "box.x": 2.0},
    ]
    first = draw(axes, 3)
    assert first == draw(axes, 3)  # reproducible
    assert draw(axes[1:2], 3)["box.mass"] == first["box.mass"]  # independent of the other keys
    masses = [draw(axes, s)["box.mass"] for s in range(200)]
    assert min(masses) >= 1 and max(masses) <= 2 and len(set(masses)) == 200
    assert {draw(axes, s)["boebot.x"] for s in range(50)} == {1.0, 2.0}
    normal = [draw([parse_vary("box.mass=normal(5,0.5)")], s)["box.mass"] for s in range(2000)]
    assert abs(np.mean(normal) - 5) < 0.05 and abs(np.std(normal) - 0.5) < 0.05


def test_jitter_bounds_and_independence() -> None:
    table = {"boebot": {"xy": 0.005, "yaw": 1.0}, "box": {"xy": 0.01}}
    offsets = [jitter(table, s) for s in range(300)]
    assert all(abs(o["boebot.x"]) <= 0.005 and abs(o["boebot.yaw"]) <= 1.0 and abs(o["box.y"]) <= 0.01 for o in offsets)
    assert "box.yaw" not in offsets[0]
    assert jitter({"boebot": table["boebot"]}, 4) == {
        k: v for k, v in jitter(table, 4).items() if k.startswith("boebot")
    }


def test_apply_writes_what_the_world_then_has(tmp_path: Path) -> None:
    import tomli_w

    values = {"box.y": 0.75, "box.mass": 2.5, "ground.friction": 0.4, "boebot.wheel_friction": 0.9, "boebot.yaw": 90.0}
    out = apply(doc(), values, {"boebot.x": 0.002, "boebot.yaw": 10.0}, entity_class)
    path = tmp_path / "v.toml"
    path.write_text(tomli_w.dumps(out), encoding="utf-8")
    (tmp_path / "square.commands.toml").write_text("", encoding="utf-8")
    world = load_scene(path)
    assert world.body("box").xpos[1] == pytest.approx(0.75)
    assert world.model.body("box").mass[0] == pytest.approx(2.5)
    assert world.body("boebot").xpos[0] == pytest.approx(1.002)
    xmat = np.array(world.body("boebot").xmat).reshape(3, 3)
    assert math.degrees(math.atan2(xmat[1, 0], xmat[0, 0])) == pytest.approx(100.0)
    assert world.model.geom("ground/plane").friction[0] == pytest.approx(0.4)
    assert world.model.geom("boebot/left_tyre").friction[0] == pytest.approx(0.9)


@pytest.mark.parametrize(
    ("key", "message"),
    [
        ("nobody.mass", "no entity or sensor named 'nobody'"),
        ("box.colour", "has no number parameter 'colour'"),
        ("box.name", "has no number parameter 'name'"),
        ("boebot.pose", "has no number parameter 'pose'"),
    ],
)
def test_bad_keys(key: str, message: str) -> None:
    with pytest.raises(VaryError, match=message):
        check_key(doc(), key, entity_class)


def test_motor_and_sensor_noise_keys_reach_the_world(tmp_path: Path) -> None:
    import tomli_w

    room = tomllib.loads((SCENE.parent / "pioneer_room.toml").read_text(encoding="utf-8"))
    values = {"p3dx.stall_torque": 0.5, "p3dx.no_load_speed": 12.0, "laser.noise": 0.02}
    for key in values:
        check_key(room, key, entity_class)
    path = tmp_path / "room.toml"
    path.write_text(tomli_w.dumps(apply(room, values, {}, entity_class)), encoding="utf-8")
    world = load_scene(path)
    assert world.sensors["laser"].noise == 0.02
    robot = world.entity("p3dx")
    assert robot.stall_torque == 0.5 and robot.no_load_speed == 12.0
    forces = [world.model.actuator(k).forcerange for k in range(world.model.nu)]
    assert all(list(f) == [-0.5, 0.5] for f in forces)
