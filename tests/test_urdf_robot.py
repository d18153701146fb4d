"""simrun.UrdfRobot: the fixture URDF arm inside a World and a scene file."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest
import yourdfpy

from simrun import EntityError, Ground, Pose, UrdfRobot, World, load_scene, scene_text
from simrun.export.usd import export_world_usd

FIXTURES = Path(__file__).resolve().parent.parent / "fixtures"
URDF = "tiny_arm_description/urdf/tiny_arm.urdf"
CONFIG = {"shoulder": -0.9, "elbow": 0.6, "slide": 0.02}


def _world(**kw: object) -> World:
    world = World(base_dir=FIXTURES / "urdf")
    world.insert(Ground(name="ground"))
    pose = Pose((0.5, -0.2, 0.3), (np.cos(0.4), 0.0, 0.0, np.sin(0.4)))  # 0.8 rad about z
    world.insert(UrdfRobot(name="arm", urdf=URDF, pose=pose, **kw))  # type: ignore[arg-type]
    return world


def test_links_joints_and_textures_arrive_under_the_entity_prefix() -> None:
    model, _ = _world(actuators=True).compile()
    links = ["arm/base_link", "arm/upper", "arm/fore", "arm/tool", "arm/tip"]
    assert [model.body(b).name for b in range(model.body("arm").id + 1, model.nbody)] == links
    assert [model.joint(j).name for j in range(model.njnt)] == ["arm/shoulder", "arm/elbow", "arm/slide"]
    assert [model.actuator(a).name for a in range(model.nu)] == ["arm/shoulder", "arm/elbow", "arm/slide"]
    texture = int(model.mat_texid[model.material("arm/base_painted").id].max())
    assert texture >= 0 and (model.tex_width[texture], model.tex_height[texture]) == (16, 16)
    assert model.nmesh == 4


def test_world_forward_kinematics_match_yourdfpy_after_the_entity_pose() -> None:
    world = _world()
    model, data = world.compile()
    for name, value in CONFIG.items():
        data.qpos[model.joint(f"arm/{name}").qposadr[0]] = value
    mujoco.mj_kinematics(model, data)
    robot = yourdfpy.URDF.load(str(FIXTURES / "urdf" / URDF), load_meshes=False, build_scene_graph=True)
    robot.update_cfg(CONFIG)
    place = np.eye(4)
    place[:3, 3] = (0.5, -0.2, 0.3)
    place[:2, :2] = [[np.cos(0.8), -np.sin(0.8)], [np.sin(0.8), np.cos(0.8)]]
    for link in ["base_link", "upper", "fore", "tool", "tip"]:
        expected = place @ robot.get_transform(frame_to=link, frame_from="base_link")
        body = model.body(f"arm/{link}").id
        np.testing.assert_allclose(data.xpos[body], expected[:3, 3], atol=1e-6)
        np.testing.assert_allclose(data.xmat[body].reshape(3, 3), expected[:3, :3], atol=1e-6)


def test_motors_drive_the_joints() -> None:
    world = _world(actuators=True)
    model, data = world.compile()
    data.ctrl[model.actuator("arm/shoulder").id] = 2.0
    mujoco.mj_step(model, data, nstep=250)
    assert data.qpos[model.joint("arm/shoulder").qposadr[0]] > 0.3
    assert np.all(np.isfinite(data.qpos))


def test_scene_file_round_trips_and_exports_joints_to_usd(tmp_path: Path) -> None:
    world = load_scene(FIXTURES / "scenes" / "urdf_arm.toml")
    model, _ = world.compile()
    assert model.nu == 3 and model.body("arm/tip").id > 0
    assert 'type = "UrdfRobot"' in scene_text(world) and "tiny_arm.urdf" in scene_text(world)
    export_world_usd(world, tmp_path / "arm.usda")
    from pxr import Usd, UsdPhysics

    stage = Usd.Stage.Open(str(tmp_path / "arm.usda"))
    revolute = [p for p in stage.Traverse() if p.IsA(UsdPhysics.RevoluteJoint)]
    prismatic = [p for p in stage.Traverse() if p.IsA(UsdPhysics.PrismaticJoint)]
    assert (len(revolute), len(prismatic)) == (2, 1)


def test_bad_urdf_is_one_clear_entity_error(tmp_path: Path) -> None:
    world = World(base_dir=FIXTURES / "urdf")
    world.insert(UrdfRobot(name="arm", urdf="tiny_arm_description/urdf/missing_mesh.urdf"))
    with pytest.raises(EntityError, match=r"UrdfRobot 'arm': .*missing_mesh\.urdf:35: mesh .*lower arm\.stl"):
        world.compile()
