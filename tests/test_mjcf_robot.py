"""simrun.MjcfRobot: MJCF models attached through MjSpec, checked against MuJoCo's own load of the same file."""

from __future__ import annotations

import math
import shutil
import warnings
from pathlib import Path

import mujoco
import numpy as np
import pytest
from click.testing import CliRunner

from simrun import EntityError, Ground, Pose, UrdfRobot, World, load_scene, scene_text
from simrun.cli.main import main
from simrun.robots.catalogue import Pioneer3DX
from simrun.robots.mjcf_robot import MjcfRobot
from simrun.sensors.laser import LaserRangeFinder
from simrun.sensors.robot_state import GPS
from simrun.services.drive_service import DriveService

FIXTURES = Path(__file__).resolve().parent.parent / "fixtures"
ARM = FIXTURES / "mjcf" / "arm" / "arm.xml"
SCENE = FIXTURES / "scenes" / "mjcf_arm_on_base.toml"
COMMANDS = FIXTURES / "scenes" / "mjcf_arm_on_base.commands.toml"
TURN = Pose((0.5, -0.2, 0.3), (math.cos(0.4), 0.0, 0.0, math.sin(0.4)))  # 0.8 rad about z


def _arm_world(**kw: object) -> World:
    world = World(base_dir=ARM.parent)
    world.insert(Ground(name="ground"))
    world.insert(MjcfRobot(name="arm", file="arm.xml", pose=TURN, **kw))  # type: ignore[arg-type]
    return world


def test_every_element_arrives_under_the_prefix_as_mujoco_loads_it() -> None:
    """Bodies, joints (ranges in radians), actuators, sensors, keyframes, excludes, meshes: as MuJoCo's own load."""
    ref = mujoco.MjModel.from_xml_path(str(ARM))
    model, _ = _arm_world().compile()
    for kind, count in (("body", ref.nbody), ("joint", ref.njnt), ("actuator", ref.nu), ("sensor", ref.nsensor)):
        for k in range(1 if kind == "body" else 0, count):
            name = mujoco.mj_id2name(ref, getattr(mujoco.mjtObj, f"mjOBJ_{kind.upper()}"), k)
            assert mujoco.mj_name2id(model, getattr(mujoco.mjtObj, f"mjOBJ_{kind.upper()}"), f"arm/{name}") >= 0
    for j in range(ref.njnt):
        mine = model.joint(f"arm/{ref.joint(j).name}")
        np.testing.assert_array_equal(model.jnt_range[mine.id], ref.jnt_range[j])
        assert model.dof_damping[mine.dofadr[0]] == ref.dof_damping[ref.jnt_dofadr[j]]  # from <default>
    for a in range(ref.nu):
        mine = model.actuator(f"arm/{ref.actuator(a).name}").id
        np.testing.assert_array_equal(model.actuator_gainprm[mine], ref.actuator_gainprm[a])
        np.testing.assert_array_equal(model.actuator_biasprm[mine], ref.actuator_biasprm[a])
        np.testing.assert_array_equal(model.actuator_ctrlrange[mine], ref.actuator_ctrlrange[a])
    key = model.key("arm/home")
    for j in range(ref.njnt):
        adr = model.joint(f"arm/{ref.joint(j).name}").qposadr[0]
        assert key.qpos[adr] == ref.key_qpos[0][ref.jnt_qposadr[j]]
    assert model.nexclude == ref.nexclude == 1
    assert model.body(int(model.exclude_signature[0]) >> 16).name == "arm/base"
    np.testing.assert_allclose(model.body_mass[model.body("arm/base").id :], ref.body_mass[1:], rtol=1e-12)
    mesh = model.mesh("arm/gripper").id
    assert model.mesh_vertnum[mesh] == ref.mesh_vertnum[0] == 8  # found through meshdir="meshes"


def test_forward_kinematics_match_mujoco_after_the_entity_pose() -> None:
    ref = mujoco.MjModel.from_xml_path(str(ARM))
    ref_data = mujoco.MjData(ref)
    mujoco.mj_resetDataKeyframe(ref, ref_data, 0)
    mujoco.mj_kinematics(ref, ref_data)
    world = _arm_world()
    model, data = world.compile()
    mujoco.mj_resetDataKeyframe(model, data, model.key("arm/home").id)
    mujoco.mj_kinematics(model, data)
    rotation = np.zeros(9)
    mujoco.mju_quat2Mat(rotation, np.asarray(TURN.orientation))
    place = rotation.reshape(3, 3)
    for name in ("turret", "upper", "fore", "wrist"):
        expected = place @ ref_data.body(name).xpos + np.asarray(TURN.position)
        np.testing.assert_allclose(data.body(f"arm/{name}").xpos, expected, atol=1e-12)
    np.testing.assert_allclose(
        data.site("arm/tool").xpos, place @ ref_data.site("tool").xpos + np.asarray(TURN.position), atol=1e-12
    )


def test_two_copies_keep_their_meshes_apart_and_files_are_read() -> None:
    world = _arm_world()
    world.insert(MjcfRobot(name="arm2", file="arm.xml", pose=Pose((2.0, 0.0, 0.0))))
    model, _ = world.compile()
    assert model.nmesh == 2 and model.nkey == 2
    assert {p.name for p in world.files_read()} == {"arm.xml", "gripper.obj"}


def test_a_model_with_a_free_root_goes_into_the_world_at_the_entity_pose() -> None:
    world = World(base_dir=FIXTURES / "mjcf" / "diffbot")
    world.insert(MjcfRobot(name="bot", file="diffbot.xml", pose=Pose((1.0, 2.0, 0.0))))
    model, data = world.compile()
    chassis = model.body("bot/chassis").id
    assert model.body_parentid[chassis] == 0  # a child of the world, its free joint kept
    assert int(model.jnt_type[model.body_jntadr[chassis]]) == int(mujoco.mjtJoint.mjJNT_FREE)
    np.testing.assert_allclose(data.xpos[chassis], [1.0, 2.0, 0.06])
    for bad in ({"free": True}, {"kinematic": True}):
        other = World(base_dir=FIXTURES / "mjcf" / "diffbot")
        other.insert(MjcfRobot(name="bot", file="diffbot.xml", **bad))  # type: ignore[arg-type]
        with pytest.raises(EntityError, match="top level, not free, not kinematic"):
            other.compile()


def test_model_options_flags_and_total_mass_are_kept_for_its_own_bodies(tmp_path: Path) -> None:
    """contact/gravity disabled become per-geom and per-body settings; settotalmass scales like MuJoCo's."""
    (tmp_path / "m.xml").write_text(
        '<mujoco><compiler settotalmass="3"/><option timestep="0.01" integrator="RK4" gravity="0 0 0">'
        '<flag contact="disable"/></option><worldbody><body name="b" pos="0 0 1"><joint type="slide" axis="0 0 1"/>'
        '<geom type="box" size=".1 .1 .1"/><body name="c" pos="0 0 .3"><joint/><geom size=".05" mass="2"/></body>'
        "</body></worldbody></mujoco>"
    )
    with warnings.catch_warnings():  # MuJoCo's own load of the reference warns that settotalmass is deprecated
        warnings.simplefilter("ignore")
        ref = mujoco.MjModel.from_xml_path(str(tmp_path / "m.xml"))
    world = World(base_dir=tmp_path)
    world.insert(Ground(name="ground"))
    world.insert(MjcfRobot(name="m", file="m.xml"))
    model, data = world.compile()
    np.testing.assert_allclose(model.body_mass[model.body("m/b").id :], ref.body_mass[1:], rtol=1e-12)
    assert model.opt.gravity[2] == pytest.approx(-9.81)  # the world's gravity (issue 37: its own timestep and
    assert (model.opt.timestep, model.opt.integrator) == (ref.opt.timestep, ref.opt.integrator)  # integrator kept)
    assert all(model.geom_contype[g] == 0 for g in range(model.ngeom) if model.geom(g).name != "ground/plane")
    world.run(0.5)
    assert data.body("m/b").xpos[2] == pytest.approx(1.0, abs=1e-9)  # it keeps floating: gravity compensated
    assert world.warnings() == {}


def _error(tmp_path: Path, text: str | None, name: str = "m.xml") -> str:
    if text is not None:
        (tmp_path / name).write_text(text)
    world = World(base_dir=tmp_path)
    world.insert(MjcfRobot(name="r", file=name))
    with pytest.raises(EntityError) as info:
        world.compile()
    message = str(info.value)
    assert "\n" not in message and message.startswith("MjcfRobot 'r': ")
    return message


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        (None, "cannot read the MJCF file (No such file or directory); check 'file'"),
        ("<mujoco><worldbody><body></worldbody></mujoco>", ":1: <body>: XML_ERROR_MISMATCHED_ELEMENT; fix"),
        ("<mujoco><worldbody>\n<body name='a'>\n<foo/></body></worldbody></mujoco>", ":3: <foo>: Schema violation"),
        ("<mujoco><worldbody>\n<geom size='x'/></worldbody></mujoco>", ":2: <geom>: bad format in attribute 'size'"),
        (
            "<mujoco><worldbody>\n<body name='a'>\n<joint/>\n</body></worldbody></mujoco>",
            ":2: element named 'a': mass and inertia of moving bodies must be larger than mjMINVAL",
        ),
        (
            "<mujoco><asset><mesh file='nope.stl'/></asset>"
            "<worldbody><geom type='mesh' mesh='nope'/></worldbody></mujoco>",
            "mesh 'nope': cannot read",
        ),
        ("<robot name='x'/>", ":1: <robot> is not an MJCF model; use UrdfRobot for a URDF"),
    ],
)
def test_bad_input_is_one_line_naming_file_line_and_element(tmp_path: Path, text: str | None, expected: str) -> None:
    message = _error(tmp_path, text)
    assert str(tmp_path / "m.xml") in message and expected in message


def test_scene_error_names_the_scene_line(tmp_path: Path) -> None:
    (tmp_path / "m.xml").write_text("<mujoco><worldbody>\n<body name='a'>\n<foo/></body></worldbody></mujoco>")
    (tmp_path / "s.toml").write_text('[[entities]]\ntype = "MjcfRobot"\nname = "r"\nfile = "m.xml"\n')
    with pytest.raises(EntityError, match=r"s\.toml:1: entities\[0\] 'r': .*m\.xml:3: <foo>"):
        load_scene(tmp_path / "s.toml").compile()


def test_wheels_get_dc_motors_and_the_drive_service_drives_the_model() -> None:
    """DriveService on the fixture's MJCF wheels: 0.5 m and 90 degrees, as the simulator's chassis pose says."""
    world = World(base_dir=FIXTURES / "mjcf" / "diffbot")
    world.insert(Ground(name="ground"))
    world.insert(MjcfRobot(name="bot", file="diffbot.xml", wheels=("left", "right"), stall_torque=2.0))
    geometry = world.entity("bot").wheel_geometry(world.base_dir)  # type: ignore[attr-defined]
    assert (geometry.radius, geometry.track, geometry.base) == (0.05, pytest.approx(0.24), "bot/chassis")
    drive = DriveService(world, "bot")
    model = world.model
    assert [model.actuator(a).name for a in range(model.nu)] == ["bot/left_motor", "bot/right_motor"]
    start = world.body("bot/chassis").xpos.copy()
    drive.drive_distance(0.5, 0.5)
    assert world.run_until(lambda: not drive.busy, 20.0)
    moved = world.body("bot/chassis").xpos - start
    assert drive.encoders()[0] == pytest.approx(0.5, abs=0.001)
    assert math.hypot(moved[0], moved[1]) == pytest.approx(0.5, abs=0.01)  # measured 0.497 m
    drive.rotate_degrees(90.0, 0.5)
    assert world.run_until(lambda: not drive.busy, 20.0)
    w, _, _, z = world.body("bot/chassis").xquat
    assert math.degrees(2 * math.atan2(z, w)) == pytest.approx(90.0, abs=2.0)  # measured 89.5 degrees
    assert world.warnings() == {}


def test_a_urdf_robot_gets_the_same_wheels_and_drive_service() -> None:
    """The fixture URDF wheelbot: wheels named, simrun's motors on them, 0.5 m and 90 degrees as the simulator says."""
    world = World(base_dir=FIXTURES / "urdf" / "wheelbot")
    world.insert(Ground(name="ground"))
    wheels = ("left_axle", "right_axle")
    world.insert(UrdfRobot(name="bot", urdf="wheelbot.urdf", free=True, wheels=wheels, stall_torque=2.0))
    geometry = world.entity("bot").wheel_geometry(world.base_dir)  # type: ignore[attr-defined]
    assert (geometry.radius, geometry.track, geometry.base) == (0.05, pytest.approx(0.24), "bot")
    drive = DriveService(world, "bot")
    world.run(1.0)  # settle on the wheels and the caster
    start = world.body("bot").xpos.copy()
    drive.drive_distance(0.5, 0.5)
    assert world.run_until(lambda: not drive.busy, 20.0)
    moved = world.body("bot").xpos - start
    assert math.hypot(moved[0], moved[1]) == pytest.approx(0.5, abs=0.01)  # measured 0.498 m
    drive.rotate_degrees(90.0, 0.5)
    assert world.run_until(lambda: not drive.busy, 20.0)
    w, _, _, z = world.body("bot").xquat
    assert math.degrees(2 * math.atan2(z, w)) == pytest.approx(90.0, abs=2.0)  # measured 89.6 degrees
    no_wheels = World(base_dir=FIXTURES / "urdf" / "wheelbot")
    no_wheels.insert(UrdfRobot(name="bot", urdf="wheelbot.urdf", wheels=("left_axle", "nope")))
    with pytest.raises(EntityError, match=r"wheels names 'nope', not a joint of wheelbot\.urdf"):
        no_wheels.compile()


def test_sensors_mount_on_a_link_of_the_robot() -> None:
    """A laser on the wrist reads the analytic distance to a wall; a GPS on the wrist reads the wrist's position."""
    world = load_scene(SCENE)
    world.check_bindings()
    world.service("JointService", "base/arm").set_positions(["shoulder", "elbow", "wrist"], [-0.5, 1.0, -0.5])
    world.run(2.0)
    gps = GPS(world, "base/arm", body="base/arm/wrist", rate=0.0)
    world.step()
    wrist = world.body("base/arm/wrist")
    np.testing.assert_allclose(gps.reading.position, wrist.xpos, atol=1e-12)
    laser = world.sensors["wrist_laser"]
    assert isinstance(laser, LaserRangeFinder) and laser.mount == "base/arm/wrist"
    world.run(0.1)
    heading = wrist.xmat.reshape(3, 3)[:, 0]
    assert abs(heading[2]) < 0.02  # the wrist is level: the scan plane is horizontal
    expected = (2.9 - wrist.xpos[0]) / heading[0]  # the wall's face is the plane x = 2.9
    assert laser.reading.ranges[15] == pytest.approx(expected, abs=1e-3)
    with pytest.raises(EntityError, match="not a body of 'base/arm'"):
        GPS(world, "base/arm", body="base/left_wheel")


def test_scene_check_test_export_and_resim(tmp_path: Path) -> None:
    """The fixture scene passes simrun check and simrun test; its MJCF export loads from its folder alone."""
    runner = CliRunner()
    check = runner.invoke(main, ["check", str(SCENE)])
    assert check.exit_code == 0, check.output
    test = runner.invoke(main, ["test", str(SCENE), "-j", "1"])
    assert test.exit_code == 0 and "1 passed, 0 failed" in test.output, test.output
    export = runner.invoke(main, ["export", str(SCENE), "--mjcf", str(tmp_path / "out" / "scene.xml")])
    assert export.exit_code == 0, export.output
    moved = tmp_path / "elsewhere"
    shutil.copytree(tmp_path / "out", moved)
    loaded = mujoco.MjModel.from_xml_path(str(moved / "scene.xml"))
    world = load_scene(SCENE)
    model = world.model
    assert (loaded.nbody, loaded.njnt, loaded.nu, loaded.nkey, loaded.nmesh, loaded.nsensor) == (
        model.nbody,
        model.njnt,
        model.nu,
        model.nkey,
        model.nmesh,
        model.nsensor,
    )
    assert 'type = "MjcfRobot"' in scene_text(world) and "arm.xml" in scene_text(world)
    log = tmp_path / "run.simlog"
    play = runner.invoke(
        main, ["play", str(SCENE), "--duration", "10", "--commands", str(COMMANDS), "--record", str(log)]
    )
    assert play.exit_code == 0, play.output
    resim = runner.invoke(main, ["resim", str(log), "--from", "9.5"])
    assert resim.exit_code == 0 and resim.stdout.strip().endswith("bit-identical"), resim.output


def test_arm_rides_the_base_as_a_child_entity() -> None:
    world = World(base_dir=FIXTURES / "scenes")
    world.insert(Ground(name="ground"))
    world.insert(Pioneer3DX(name="base", pose=Pose((0.0, 0.0, 0.001))))
    world.insert(MjcfRobot(name="arm", parent="base", file="../mjcf/arm/arm.xml", pose=Pose((0.1, 0.0, 0.237))))
    model, data = world.compile()
    assert model.body_rootid[model.body("base/arm/wrist").id] == model.body("base").id
    world.run(0.5)
    offset = data.body("base/arm/base").xpos - data.body("base").xpos
    np.testing.assert_allclose(offset, [0.1, 0.0, 0.237], atol=2e-3)


def test_textures_from_the_compilers_texturedir_and_cube_faces_are_mujocos_own(tmp_path: Path) -> None:
    """A 2D texture under ``<compiler texturedir>`` and a cube texture of six face files: the world's texture
    pixels equal what MuJoCo reads from the same folder (``MjModel.from_xml_path``), face for face."""
    from PIL import Image

    tex = tmp_path / "tex"
    tex.mkdir()
    colours = [(255, 0, 0), (0, 255, 0), (0, 0, 255), (255, 255, 0), (0, 255, 255), (255, 0, 255), (40, 80, 120)]
    names = ["right", "left", "up", "down", "front", "back", "plain"]
    for name, colour in zip(names, colours, strict=True):
        Image.new("RGB", (4, 4), colour).save(tex / f"{name} face.png")
    faces = " ".join(
        f'file{side}="{n} face.png"'
        for side, n in zip(("right", "left", "up", "down", "front", "back"), names, strict=False)
    )
    model_xml = tmp_path / "robot.xml"
    model_xml.write_text(
        '<mujoco><compiler texturedir="tex"/><asset>'
        '<texture name="plain" type="2d" file="plain face.png"/>'
        f'<texture name="cube" type="cube" {faces}/>'
        '<material name="m" texture="plain"/><material name="c" texture="cube"/></asset>'
        '<worldbody><body name="b"><joint type="hinge"/><geom size="0.1" material="m"/>'
        '<geom size="0.05" pos="0 0 0.2" material="c"/></body></worldbody></mujoco>'
    )
    reference = mujoco.MjModel.from_xml_path(str(model_xml))
    world = World()
    world.insert(MjcfRobot(name="r", file=str(model_xml)))
    model, _ = world.compile()
    for name in ("plain", "cube"):
        ours, theirs = model.texture(f"r/{name}"), reference.texture(name)
        assert (int(ours.width[0]), int(ours.height[0])) == (int(theirs.width[0]), int(theirs.height[0]))
        size = int(theirs.width[0]) * int(theirs.height[0]) * int(theirs.nchannel[0])
        ours_px = model.tex_data[int(ours.adr[0]) : int(ours.adr[0]) + size]
        theirs_px = reference.tex_data[int(theirs.adr[0]) : int(theirs.adr[0]) + size]
        assert np.array_equal(ours_px, theirs_px)
    assert model.tex_data.size >= reference.tex_data.size and 40 in model.tex_data
