"""simrun worlds: entities on MjSpec, assets from memory, scenes, checks, exports (real MuJoCo)."""

import shutil
from pathlib import Path

import mujoco
import numpy as np
import pytest
from click.testing import CliRunner

from simrun import (
    Box,
    Camera,
    EntityError,
    Ground,
    HeightField,
    Light,
    Material,
    MeshEntity,
    Pose,
    SceneError,
    Sky,
    Sphere,
    World,
    load_scene,
    save_scene,
    scene_text,
)
from simrun.cli.main import main
from simrun.world.archive import load_mjz, mjz_bytes

SCENES = Path(__file__).resolve().parent.parent / "fixtures" / "scenes"


@pytest.mark.parametrize("scene", ["basic.toml", "head_on_table.toml"])
def test_fixture_scenes_compile_and_step_without_warnings(scene):
    result = CliRunner().invoke(main, ["check", str(SCENES / scene)])
    assert result.exit_code == 0, result.output
    assert "stepped 1 s with no warning" in result.stdout


def test_basic_environment_in_ten_lines():
    world = World(base_dir=SCENES)
    world.insert(Sky(name="sky"))
    world.insert(Ground(name="ground"))
    world.insert(Light(name="sun", pose=Pose((0, 0, 4))))
    world.insert(Box(name="box", dimensions=(0.2, 0.2, 0.2), mass=100.0, pose=Pose((0, 0, 0.1)), free=True))
    world.insert(Sphere(name="globe", radius=0.15, mass=10.0, texture="globe.png", pose=Pose((0.6, 0, 0.5)), free=True))
    world.run(1.0)
    assert world.model.body("box").mass[0] == pytest.approx(100.0)
    assert world.model.body("globe").mass[0] == pytest.approx(10.0)
    assert world.body("box").xpos[2] == pytest.approx(0.1, abs=2e-3)  # resting on the ground
    assert world.body("globe").xpos[2] == pytest.approx(0.15, abs=2e-3)
    assert world.warnings() == {}
    assert world.model.ntex == 3  # sky, checker, globe


def test_names_prefixes_and_duplicates():
    world = World()
    world.insert(Box(name="robot", free=True))
    world.insert(Sphere(name="wheel", parent="robot", pose=Pose((0.1, 0, 0))))
    world.insert(Box(name="robot2", free=True))
    world.insert(Sphere(name="wheel", parent="robot2", pose=Pose((0.1, 0, 0))))
    assert [n for n, _ in world] == ["robot", "robot/wheel", "robot2", "robot2/wheel"]
    model = world.model
    assert model.body("robot/wheel").parentid[0] == model.body("robot").id
    assert world.geom("robot2/wheel/geom").xpos is not None
    with pytest.raises(EntityError, match="already exists"):
        world.insert(Sphere(name="wheel", parent="robot"))
    with pytest.raises(EntityError, match="parent 'nobody' does not exist"):
        world.insert(Sphere(name="x", parent="nobody"))
    with pytest.raises(EntityError, match="must match"):
        world.insert(Sphere(name="a/b"))
    world.remove("robot")
    assert [n for n, _ in world] == ["robot2", "robot2/wheel"]
    assert world.model.nbody == 3


def test_kinematic_child_is_refused_with_the_reason():
    world = World()
    world.insert(Box(name="robot", free=True))
    with pytest.raises(EntityError) as info:
        world.insert(Box(name="arm_base", parent="robot", kinematic=True))
    message = str(info.value)
    assert "pin its parent in place" in message and "Make it a top-level entity" in message


def test_kinematic_entity_follows_set_pose():
    world = World()
    world.insert(Ground(name="ground"))
    world.insert(Box(name="paddle", kinematic=True, pose=Pose((0, 0, 0.5))))
    world.step(10)
    for t in range(5):
        target = (0.1 * t, 0.05 * t, 0.5)
        world.set_pose("paddle", target)
        world.step(1)
        np.testing.assert_allclose(world.body("paddle").xpos, target, atol=1e-12)
    with pytest.raises(EntityError, match="not kinematic"):
        world.insert(Box(name="free_box", free=True, pose=Pose((1, 0, 0.5))))
        world.set_pose("free_box", (0, 0, 0))


@pytest.mark.parametrize("e", [0.3, 0.5, 0.6])
def test_restitution_bounces_to_e_squared_h(e):
    world = World()
    world.insert(Ground(name="ground"))
    world.insert(
        Sphere(name="ball", radius=0.05, mass=0.1, pose=Pose((0, 0, 1.05)), free=True, material=Material(restitution=e))
    )
    heights = []
    while world.data.time < 2.5:
        world.step()
        heights.append(world.body("ball").xpos[2] - 0.05)
    z = np.array(heights)
    first = int(np.argmax(z < 0.002))
    rising = first + int(np.argmax(np.diff(z[first:]) > 0))
    bounce = z[rising : rising + 600].max()
    assert bounce == pytest.approx(e * e * 1.0, rel=0.1)


def test_mesh_entity_settles_on_its_hulls_and_assets_are_added_once():
    world = World(base_dir=SCENES)
    world.assets["head"] = "head.mbin"
    world.insert(Ground(name="ground"))
    for k in range(3):
        world.insert(MeshEntity(name=f"head{k}", asset="head", mass=2.0, free=True, pose=Pose((0.5 * k, 0, 0.3))))
    lowest = np.inf
    while world.data.time < 2.0:
        world.step()
        lowest = min(lowest, *(world.body(f"head{k}").xpos[2] for k in range(3)))
    model = world.model
    assert model.nmesh == 2  # one visual mesh and one hull, shared by the three entities
    assert model.ntex == 2  # the head's texture (once) and the ground's checker
    for k in range(3):
        body = world.body(f"head{k}")
        assert model.body(f"head{k}").mass[0] == pytest.approx(2.0)
        assert abs(body.xpos[2]) < 5e-3 and abs(body.cvel[5]) < 0.05  # down on the ground (a round head rocks)
    assert lowest > -0.03  # never fell through (soft contacts give way ~2 cm on impact at 2.4 m/s)
    visual = model.geom("head0/visual0")
    assert (visual.group[0], visual.contype[0], visual.conaffinity[0]) == (2, 0, 0)
    assert model.geom("head0/collision0").group[0] == 3


def test_mesh_texcoords_match_mujoco_loading_the_obj(tmp_path):
    """uvs from memory equal what MuJoCo reads from the normalised OBJ (MuJoCo flips v on OBJ import)."""
    from meshtool import NormaliseOptions, normalise_to

    folder, _ = normalise_to(SCENES.parent / "head" / "Head 1.obj", tmp_path, NormaliseOptions(units="cm"))
    world = World(base_dir=SCENES)
    world.insert(MeshEntity(name="head", asset="head.mbin", collision="none"))
    ours = world.model
    obj = mujoco.MjModel.from_xml_string(
        f'<mujoco><asset><mesh name="m" file="{folder / "head_1.obj"}"/></asset>'
        '<worldbody><geom type="mesh" mesh="m"/></worldbody></mujoco>'
    )
    a = ours.mesh_texcoord[: ours.mesh_texcoordnum[0]]
    b = obj.mesh_texcoord[: obj.mesh_texcoordnum[0]]
    assert sorted(map(tuple, np.round(a, 5))) == sorted(map(tuple, np.round(b, 5)))


def test_scene_round_trip(tmp_path):
    shutil.copytree(SCENES, tmp_path / "scenes")
    world = load_scene(tmp_path / "scenes" / "basic.toml")
    first = tmp_path / "scenes" / "saved.toml"
    save_scene(world, first)
    again = load_scene(first)
    assert scene_text(again) == first.read_text()
    assert [(n, type(e).__name__) for n, e in again] == [(n, type(e).__name__) for n, e in world]
    assert again.entity("globe").texture == "globe.png" and again.entity("box").mass == 100.0
    assert again.entity("view").main is True and isinstance(again.entity("view"), Camera)
    world.run(0.5)
    again.run(0.5)
    assert world.data.qpos.tobytes() == again.data.qpos.tobytes()


POSE = "pose = { position = [0.0, 0.0, 0.1] }"
DIMENSIONS = "dimensions = [0.2, 0.2, 0.2]"


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        (POSE, POSE, None),
        (POSE, "pose = { position = [0.0, 0.1] }", "26: entities[3] 'box': pose.position: expected 3 numbers, got 2"),
        (POSE, "colour = [1.0, 0.0, 0.0, 1.0]", "26: entities[3] 'box': colour: unknown key"),
        (POSE, 'density = "heavy"', "26: entities[3] 'box': density: expected a finite number, got 'heavy'"),
        (DIMENSIONS, "dimensions = [0.2, 0.2]", "24: entities[3] 'box': dimensions: expected 3 numbers, got 2"),
        (
            POSE,
            "material = { restitution = 0.95 }",
            "26: entities[3] 'box': material: restitution must be in [0, 0.65]",
        ),
        (
            POSE,
            "pose = { position = [0.0, 0.0, 0.1], orientation = [1.0, 1.0, 0.0, 0.0] }",
            "26: entities[3] 'box': pose: orientation must be a unit quaternion",
        ),
    ],
)
def test_scene_errors_name_file_and_key(tmp_path, old, new, message):
    text = (SCENES / "basic.toml").read_text()
    assert old in text
    shutil.copy(SCENES / "globe.png", tmp_path / "globe.png")
    path = tmp_path / "bad.toml"
    path.write_text(text.replace(old, new))
    if message is None:
        load_scene(path)
        return
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert str(info.value).startswith(f"{path}:{message}")


SERVICE = '[[entities]]\ntype = "Box"\nname = "b"\n[[services]]\ntype = "DriveService"\nentity = "robot"\n'


def test_scene_structure_errors(tmp_path):
    cases = {
        "[wrold]\ntimestep = 1\n": ":1: wrold: unknown key",
        '[[entities]]\ntype = "Teapot"\nname = "t"\n': ":2: entities[0] 't': type: unknown entity type 'Teapot'",
        SERVICE: ":6: services[0] 'DriveService': entity: no entity named 'robot'",
        "[world]\ntimestep = -1\n": ":2: world.timestep: must be in [1e-05, 0.1] seconds",
        "not toml at all [": ":1: not valid TOML",
    }
    for k, (text, message) in enumerate(cases.items()):
        path = tmp_path / f"s{k}.toml"
        path.write_text(text)
        with pytest.raises(SceneError, match=message.replace("[", r"\[").replace("]", r"\]")):
            load_scene(path)


def test_export_mjcf_and_mjz_reload_bit_identically(tmp_path):
    runner = CliRunner()
    scene = SCENES / "head_on_table.toml"
    result = runner.invoke(
        main, ["export", str(scene), "--mjcf", str(tmp_path / "w.xml"), "--mjz", str(tmp_path / "w.mjz")]
    )
    assert result.exit_code == 0, result.output
    world = load_scene(scene)
    reloaded = load_mjz(tmp_path / "w.mjz")
    data = mujoco.MjData(reloaded)
    for _ in range(500):
        mujoco.mj_step(reloaded, data)
    world.step(500)
    assert world.data.qpos.tobytes() == data.qpos.tobytes()
    xml_model = mujoco.MjModel.from_xml_path(str(tmp_path / "w.xml"))  # meshes and textures beside it
    assert (xml_model.nbody, xml_model.nmesh, xml_model.ntex) == (
        world.model.nbody,
        world.model.nmesh,
        world.model.ntex,
    )
    assert mjz_bytes(world) == mjz_bytes(world)  # deterministic archive
    assert runner.invoke(main, ["export", str(scene)]).exit_code == 2


def test_check_fails_on_a_broken_scene(tmp_path):
    path = tmp_path / "broken.toml"
    path.write_text('[[entities]]\ntype = "MeshEntity"\nname = "m"\nasset = "missing.mbin"\n')
    result = CliRunner().invoke(main, ["check", str(path)])
    assert result.exit_code == 1
    assert result.stderr.startswith("error: ") and "missing.mbin" in result.stderr


def test_height_field_camera_and_lights():
    world = World(base_dir=SCENES)
    bumps = [[0.0, 0.5, 1.0], [0.5, 1.0, 0.5], [1.0, 0.5, 0.0]]
    world.insert(HeightField(name="terrain", heights=bumps, size=(1.0, 1.0, 0.2, 0.05)))
    world.insert(Light(name="spot", kind="spot", pose=Pose((0, 0, 2))))
    world.insert(Camera(name="view", eye=(2.0, 0.0, 1.0), target=(0.0, 0.0, 0.0), main=True, fovy=60.0))
    world.insert(Sphere(name="ball", radius=0.05, pose=Pose((0.9, 0.9, 0.6)), free=True))
    world.run(1.0)
    model = world.model
    assert (model.nhfield, model.hfield_nrow[0], model.hfield_ncol[0]) == (1, 3, 3)
    np.testing.assert_allclose(model.hfield_data, np.array(bumps).ravel())
    assert model.vis.global_.cameraid == model.camera("view").id and model.cam_fovy[0] == 60.0
    # the camera looks at the target: its -Z axis points from the eye to the origin
    forward = -world.data.cam_xmat[0].reshape(3, 3)[:, 2]
    np.testing.assert_allclose(forward, -np.array([2.0, 0, 1.0]) / np.sqrt(5), atol=1e-9)
    assert model.light_type[0] == mujoco.mjtLightType.mjLIGHT_SPOT
    assert world.body("ball").xpos[2] < 0.6  # it fell onto the terrain
    with pytest.raises(EntityError, match="exactly one of heights and image"):
        bad = World()
        bad.insert(HeightField(name="t"))
        bad.compile()


def test_a_world_of_thousands_of_bodies_gets_the_arena_mujoco_needs():
    """3,000 static boxes: MuJoCo's automatic arena refuses the broadphase (mj_stackAlloc), simrun sizes it.

    The bodies rest on nothing and touch nothing; after stepping, every box is where it was put.
    """
    from simrun.world.world import ARENA_DEFAULT, arena_bytes

    n = 3000
    world = World()
    for k in range(n):
        world.insert(Box(name=f"b{k}", dimensions=(0.1, 0.1, 0.1), pose=Pose((0.3 * (k % 100), 0.3 * (k // 100), 1.0))))
    bare = world.build_spec()
    bare.memory = -1  # MuJoCo's automatic size, as an MJCF without <size memory> gets
    model = bare.compile()
    with pytest.raises(mujoco.FatalError, match="mj_stackAlloc"):
        mujoco.mj_forward(model, mujoco.MjData(model))
    model, data = world.compile()
    assert model.nbody == n + 1 and model.narena == arena_bytes(n + 1) > ARENA_DEFAULT
    before = data.xpos.copy()
    world.run(0.01)
    assert np.array_equal(data.xpos, before)
    assert arena_bytes(100) is None  # a small world keeps MuJoCo's automatic arena
