"""Issue 37: wheels named in a scene file drive MJCF and URDF robots; the wheel radius is measured from the wheel's
collision geometry; the robot contract reads the compiled model. Ground truth: MuJoCo's compiled model (geom
sizes, mesh vertices) and its simulation state (``data.xpos`` of the root body)."""

import math
import re
from pathlib import Path

import mujoco
import numpy as np
import pytest

from simrun import SceneError, load_scene
from simrun.robots.contract import describe, is_robot

FIXTURES = Path(__file__).resolve().parent.parent / "fixtures"
SCENES = {
    "mjcf-cylinder": (FIXTURES / "mjcf" / "cylbot" / "drive.toml", "left", "bot/chassis"),
    "urdf-mesh": (FIXTURES / "urdf" / "meshbot" / "drive.toml", "left_axle", "bot"),
}


def _geometry_radius(model: mujoco.MjModel, joint: str) -> float:
    """The wheel's radius from MuJoCo's compiled geometry: a cylinder's size, or a mesh's vertices about Y."""
    body = model.joint(joint).bodyid[0]
    radii = []
    for g in range(model.ngeom):
        if model.geom_bodyid[g] != body or not (model.geom_contype[g] or model.geom_conaffinity[g]):
            continue
        if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_CYLINDER:
            radii.append(float(model.geom_size[g][0]))
        elif model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH:
            m = model.geom_dataid[g]
            verts = model.mesh_vert[model.mesh_vertadr[m] : model.mesh_vertadr[m] + model.mesh_vertnum[m]]
            rotation = np.zeros(9)
            mujoco.mju_quat2Mat(rotation, model.geom_quat[g])
            points = verts @ rotation.reshape(3, 3).T + model.geom_pos[g]  # in the wheel body's frame (axis Y)
            radii.append(float(np.hypot(points[:, 0], points[:, 2]).max()))
    return max(radii)


@pytest.mark.parametrize("kind", list(SCENES))
def test_a_scene_with_wheels_drives_one_metre_within_one_percent(kind):
    path, left, root = SCENES[kind]
    world = load_scene(path)
    drive = world.service("DriveService", "bot")
    model = world.model
    truth = _geometry_radius(model, f"bot/{left}")
    assert drive.wheels.radius == pytest.approx(truth, rel=0.01)
    # the bounding sphere MuJoCo computes is larger than the wheel: what the radius used to be
    body = model.joint(f"bot/{left}").bodyid[0]
    assert max(model.geom_rbound[model.geom_bodyid == body]) > 1.02 * truth
    world.run(1.0)  # settle on the wheels and the caster
    start = world.data.xpos[model.body(root).id].copy()
    drive.drive_distance(1.0, 0.5)
    assert world.run_until(lambda: not drive.busy, 30.0)
    moved = world.data.xpos[model.body(root).id] - start
    assert math.hypot(moved[0], moved[1]) == pytest.approx(1.0, rel=0.01)  # measured 0.995 (MJCF), 0.993 (URDF)
    assert world.warnings() == {}


@pytest.mark.parametrize("kind", list(SCENES))
def test_the_contract_reads_the_compiled_model(kind):
    path, left, root = SCENES[kind]
    world = load_scene(path)
    model = world.model
    robot = describe(world, "bot")
    assert is_robot(world.entity("bot")) and not is_robot(world.entity("ground"))
    assert robot.root == root and robot.root_kind == "free" and robot.mobile
    assert robot.wheels is not None and robot.wheels.left == f"bot/{left}"
    named = [model.body(b).name for b in range(model.nbody)]
    assert set(robot.bodies) == {n for n in named if n == "bot" or n.startswith("bot/")}
    driven = {model.joint(model.actuator_trnid[a, 0]).name for a in range(model.nu)}
    assert set(robot.joints) == driven


def test_a_sensor_key_typo_names_the_known_keys_and_the_closest(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(
        '[[entities]]\ntype = "BoeBot"\nname = "bot"\n\n'
        '[[sensors]]\ntype = "LaserRangeFinder"\nname = "l"\nentity = "bot"\nray = 5\n'
    )
    with pytest.raises(
        SceneError,
        match=r"s\.toml:9: sensors\[0\] 'l': ray: sensor 'l': unknown key 'ray' \(known: .*rays.*\); "
        r"did you mean 'rays'\?",
    ):
        load_scene(path)


def test_drive_service_on_a_model_without_wheels_says_how_to_name_them(tmp_path):
    (tmp_path / "s.toml").write_text(
        '[[entities]]\ntype = "MjcfRobot"\nname = "bot"\nfile = "cylbot.xml"\n\n'
        '[[services]]\ntype = "DriveService"\nentity = "bot"\n'
    )
    (tmp_path / "cylbot.xml").write_text((FIXTURES / "mjcf" / "cylbot" / "cylbot.xml").read_text())
    world = load_scene(tmp_path / "s.toml")
    with pytest.raises(Exception, match=r"MjcfRobot 'bot' has no wheels; .*wheels = \[\"left\", \"right\"\]"):
        world.check_bindings()


@pytest.mark.parametrize(
    ("table", "line", "where", "typo", "meant"),
    [
        ('[[entities]]\ntype = "MjcfRobot"\nname = "bot"\nfile = "cylbot.xml"\nwheel = ["left", "right"]\n', 5,
         "entities[0] 'bot'", "wheel", "wheels"),
        ('[[entities]]\ntype = "BoeBot"\nname = "bot"\n\n[[services]]\ntype = "DriveService"\nentity = "bot"\n'
         "rates = 10.0\n", 8, "services[0] 'DriveService'", "rates", "rate"),
    ],
)  # fmt: skip
def test_unknown_entity_and_service_keys_name_the_known_keys_and_the_closest(tmp_path, table, line, where, typo, meant):
    path = tmp_path / "s.toml"
    path.write_text(table)
    known = rf"unknown key \(known: .*\b{meant}\b.*\); did you mean '{meant}'\?"
    pattern = rf"s\.toml:{line}: {re.escape(where)}: {typo}: {known}"
    with pytest.raises(SceneError, match=pattern):
        load_scene(path)


def test_a_sensor_key_typo_in_python_names_the_known_keys_and_the_closest():
    """World.add_sensor (Python) gives the scene file's message, not Python's unexpected-keyword TypeError."""
    from simrun import World
    from simrun.robots.catalogue import BoeBot

    world = World()
    world.insert(BoeBot(name="bot"))
    with pytest.raises(Exception, match=r"sensor 'l': ray: unknown key \(known: .*rays.*\); did you mean 'rays'\?"):
        world.add_sensor({"type": "LaserRangeFinder", "name": "l", "entity": "bot", "ray": 5})
