"""MjcfRobot roots for models without a free joint (dm_control's walkers): ``free`` and ``root_slides``.

Ground truth: MuJoCo's state (body poses, contacts), analytic free fall and rest heights from the fixtures'
geometry, MuJoCo's own load of the same files.
"""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import mujoco
import numpy as np
import pytest
from click.testing import CliRunner

from simrun import EntityError, Ground, Pose, World, load_scene, scene_text
from simrun.cli.main import main
from simrun.export.mjcf_builder import export_world_mjcf
from simrun.robots.mjcf_robot import MjcfRobot
from simrun.run.session import PlayOptions, run_play, run_resim
from simrun.services.joint_service import JointService

FIXTURES = Path(__file__).resolve().parent.parent / "fixtures"
WALKERS = FIXTURES / "mjcf" / "walker"
SCENE = FIXTURES / "scenes" / "mjcf_walkers.toml"
COMMANDS = FIXTURES / "scenes" / "mjcf_walkers.commands.toml"
G = 9.81
HALF_HEIGHT = 0.05  # the walker's torso box: it rests on its bottom face (fixtures/mjcf/walker/walker.xml)
BALL_DROP = 0.3  # the ballbot's ball bottom below its head's origin (ballbot.xml)


def _world(file: str, **kw: object) -> World:
    world = World(base_dir=WALKERS)
    world.insert(Ground(name="ground"))
    world.insert(MjcfRobot(name="bot", file=file, **kw))  # type: ignore[arg-type]
    return world


def _flipper_contacts(model: mujoco.MjModel, data: mujoco.MjData) -> int:
    names = {(model.geom(c.geom1).name, model.geom(c.geom2).name) for c in data.contact[: data.ncon]}
    return sum(1 for pair in names if "bot/torso" in pair)


def test_free_walker_falls_freely_then_rests_on_its_torso() -> None:
    """Free: z follows z0 - g t^2 / 2 until it lands (Euler steps: within g dt t), then rests at the half height."""
    world = _world("walker.xml", free=True, pose=Pose((0.3, -0.2, 0.5)))
    model, data = world.compile()
    dt = model.opt.timestep
    assert int(model.jnt_type[model.joint("bot/free").id]) == int(mujoco.mjtJoint.mjJNT_FREE)
    assert model.body_parentid[model.body("bot/root").id] == model.body("bot").id  # the model hangs from it
    root = data.body("bot/root")
    for t in (0.1, 0.2, 0.3):  # the torso's bottom (0.45 m up) lands at t = sqrt(0.9 / g) = 0.303 s
        world.run(t - world.time)
        assert root.xpos[2] == pytest.approx(0.5 - G * t * t / 2, abs=G * dt * t)
        assert data.qvel[model.joint("bot/free").dofadr[0] + 2] == pytest.approx(-G * t, abs=G * dt)
    world.run(2.0)
    assert root.xpos[2] == pytest.approx(HALF_HEIGHT, abs=1e-3)  # measured 0.04989: MuJoCo's soft contact
    np.testing.assert_allclose(root.xpos[:2], [0.3, -0.2], atol=1e-4)
    np.testing.assert_allclose(abs(root.xquat[0]), 1.0, atol=1e-6)  # flat on the ground
    assert world.warnings() == {}


def test_without_a_root_the_walker_stays_welded_where_it_is_put() -> None:
    world = _world("walker.xml", pose=Pose((0.0, 0.0, 0.5)))
    model, data = world.compile()
    world.run(1.0)
    np.testing.assert_array_equal(data.body("bot/root").xpos, [0.0, 0.0, 0.5])
    assert model.njnt == 2  # the two hips: nothing carries the root


def test_free_lets_mujoco_filter_the_models_parent_child_overlaps() -> None:
    """The flippers start 1.5 cm inside the torso: welded to the world MuJoCo's parent filter does not apply
    (the root's parent is the world) and the pairs collide; on a free joint they are filtered, as in dm_control."""
    for free, expected in ((False, 2), (True, 0)):
        world = _world("walker.xml", free=free, pose=Pose((0.0, 0.0, 0.5)))
        model, data = world.compile()
        mujoco.mj_forward(model, data)
        assert _flipper_contacts(model, data) == expected


def test_free_keeps_the_keyframes_and_the_joint_service_drives_the_hips() -> None:
    world = _world("walker.xml", free=True, pose=Pose((0.0, 0.0, 0.2)))
    model, data = world.compile()
    key = model.key("bot/spread")
    for joint, value in (("bot/left_hip", 0.3), ("bot/right_hip", -0.3)):
        assert key.qpos[model.joint(joint).qposadr[0]] == value
    JointService(world, "bot").set_positions(["left_hip", "right_hip"], [0.5, -0.5])
    world.run(2.0)
    assert data.joint("bot/left_hip").qpos[0] == pytest.approx(0.5, abs=0.02)
    assert data.joint("bot/right_hip").qpos[0] == pytest.approx(-0.5, abs=0.02)


def test_root_slides_translate_along_the_entity_axes_and_keep_the_orientation() -> None:
    """The head is turned 90 degrees in the file; root_x still moves it along the entity's x. It falls 0.2 m and
    rests on its ball at 0.3 m, not tilted; the model's own joints keep MuJoCo's settings and keyframe values."""
    turn = Pose((1.0, 2.0, 0.2), (math.cos(0.3), 0.0, 0.0, math.sin(0.3)))  # 0.6 rad about z
    world = _world("ballbot.xml", root_slides=True, pose=turn)
    model, data = world.compile()
    names = [model.joint(j).name for j in range(model.njnt)]
    assert names == ["bot/root_x", "bot/root_y", "bot/root_z", "bot/steer", "bot/roll"]
    for k in range(3):
        slide = model.joint(f"bot/root_{'xyz'[k]}").id
        assert int(model.jnt_type[slide]) == int(mujoco.mjtJoint.mjJNT_SLIDE) and not model.jnt_limited[slide]
        assert model.dof_damping[slide] == model.dof_armature[slide] == model.jnt_stiffness[slide] == 0.0
    ref = mujoco.MjModel.from_xml_path(str(WALKERS / "ballbot.xml"))
    for j in range(ref.njnt):
        mine = model.joint(f"bot/{ref.joint(j).name}").id
        np.testing.assert_array_equal(model.jnt_axis[mine], ref.jnt_axis[j])
        assert model.dof_damping[model.jnt_dofadr[mine]] == ref.dof_damping[ref.jnt_dofadr[j]]
    key = model.key("bot/turned")
    assert key.qpos[model.joint("bot/steer").qposadr[0]] == 0.5 and not any(key.qpos[:3])
    rotation = np.zeros(9)
    mujoco.mju_quat2Mat(rotation, np.asarray(turn.orientation))
    head = data.body("bot/head")
    mujoco.mj_kinematics(model, data)
    start, orientation = head.xpos.copy(), head.xquat.copy()
    for k in range(3):
        data.qpos[:] = model.qpos0
        data.qpos[model.joint(f"bot/root_{'xyz'[k]}").qposadr[0]] = 0.1
        mujoco.mj_kinematics(model, data)
        np.testing.assert_allclose(head.xpos - start, 0.1 * rotation.reshape(3, 3)[:, k], atol=1e-12)
    mujoco.mj_resetData(model, data)
    world.run(2.0)
    assert head.xpos[2] == pytest.approx(BALL_DROP, abs=1e-3)  # measured 0.2996
    np.testing.assert_allclose(head.xpos[:2], [1.0, 2.0], atol=1e-6)
    np.testing.assert_allclose(head.xquat, orientation, atol=1e-9)  # translation only
    assert world.warnings() == {}


@pytest.mark.parametrize(
    ("file", "kw", "expected"),
    [
        ("ballbot.xml", {"free": True}, r"every top-level body has joints of its own: head \(steer\).*root_slides"),
        ("walker.xml", {"free": True, "root_slides": True}, "cannot also be free or kinematic"),
        ("../mjcf/diffbot/diffbot.xml", {"root_slides": True}, "one top-level body without a free joint"),
    ],
)
def test_roots_that_cannot_work_are_refused_in_one_line(file: str, kw: dict[str, bool], expected: str) -> None:
    world = _world(file, **kw)
    if file.startswith(".."):
        world = World(base_dir=FIXTURES / "mjcf" / "diffbot")
        world.insert(MjcfRobot(name="bot", file="diffbot.xml", **kw))  # type: ignore[arg-type]
    with pytest.raises(EntityError, match=expected) as info:
        world.compile()
    assert "\n" not in str(info.value)


def test_scene_keys_check_test_recording_resim_and_export(tmp_path: Path) -> None:
    """The scene's free and root_slides round-trip; it passes simrun check and simrun test (landing heights);
    a recorded run re-simulates bit for bit; the MJCF export loads from its folder alone with the same joints."""
    runner = CliRunner()
    check = runner.invoke(main, ["check", str(SCENE)])
    assert check.exit_code == 0, check.output
    test = runner.invoke(main, ["test", str(SCENE), "-j", "1"])
    assert test.exit_code == 0 and "1 passed, 0 failed" in test.output, test.output
    world = load_scene(SCENE)
    text = scene_text(world)
    assert "free = true" in text and "root_slides = true" in text
    log = tmp_path / "run.simlog"
    run_play(SCENE, PlayOptions(duration=2.0, commands=COMMANDS, record=log))
    compared, mismatch = run_resim(log, 1.0)
    assert compared > 0 and mismatch is None
    export_world_mjcf(world, tmp_path / "out" / "scene.xml")
    moved = tmp_path / "elsewhere"
    shutil.copytree(tmp_path / "out", moved)
    loaded = mujoco.MjModel.from_xml_path(str(moved / "scene.xml"))
    model = world.model
    assert [loaded.joint(j).name for j in range(loaded.njnt)] == [model.joint(j).name for j in range(model.njnt)]
    assert (loaded.nq, loaded.nkey) == (model.nq, model.nkey)
    data = mujoco.MjData(loaded)
    for _ in range(500):
        mujoco.mj_step(loaded, data)
    assert data.body("walker/root").xpos[2] < 0.5 - 0.1  # it falls there too


def test_root_slides_refuse_a_model_that_has_a_root_x_already(tmp_path: Path) -> None:
    (tmp_path / "m.xml").write_text(
        '<mujoco><worldbody><body name="b"><joint name="root_x" type="slide"/><geom size=".1"/></body>'
        "</worldbody></mujoco>"
    )
    world = World(base_dir=tmp_path)
    world.insert(MjcfRobot(name="m", file="m.xml", root_slides=True))
    with pytest.raises(EntityError, match=r"root_slides adds root_x, already a joint of .*m\.xml"):
        world.compile()
