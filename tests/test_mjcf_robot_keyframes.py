"""Keyframes of MJCF robots follow the entity's pose (issue 37): ``World.reset("NAME/key")``.

Ground truth: MuJoCo's own load of the fixture reset to the same keyframe (the body poses in the model's
frame), composed with the entity's pose by the quaternion product written out here (Hamilton, ``w x y z``).
"""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from simrun import EntityError, Ground, Pose, World
from simrun.robots.mjcf_robot import MjcfRobot

FIXTURES = Path(__file__).resolve().parent.parent / "fixtures" / "mjcf"
FREEBOT = FIXTURES / "keyframe" / "freebot.xml"
POSES = (
    Pose((1.0, -0.5, 0.0)),
    Pose((-0.7, 2.0, 0.4), (math.cos(0.6), 0.0, 0.0, math.sin(0.6))),  # 1.2 rad about z
    Pose((0.3, 0.3, 1.0), (math.cos(0.3), math.sin(0.3) / math.sqrt(2), math.sin(0.3) / math.sqrt(2), 0.0)),
)


def _mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ]
    )


def _rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    return _mul(_mul(q, np.array([0.0, *v])), q * np.array([1.0, -1.0, -1.0, -1.0]))[1:]


def _same_rotation(a: np.ndarray, b: np.ndarray) -> None:
    np.testing.assert_allclose(abs(float(np.dot(a, b))), 1.0, atol=1e-12)


def _reference(path: Path, key: str) -> mujoco.MjData:
    ref = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(ref)
    mujoco.mj_resetDataKeyframe(ref, data, ref.key(key).id)
    mujoco.mj_kinematics(ref, data)
    return data


def test_two_free_robots_of_one_model_reset_to_home_where_each_entity_stands() -> None:
    """Every body of each robot at pose * (its pose in MuJoCo's own load at ``home``); the leg's hinge as keyed."""
    world = World(base_dir=FREEBOT.parent)
    world.insert(Ground(name="ground"))
    for k, pose in enumerate(POSES):
        world.insert(MjcfRobot(name=f"bot{k}", file="freebot.xml", pose=pose))
    _, data = world.compile()
    ref = _reference(FREEBOT, "home")
    for k, pose in enumerate(POSES):
        world.reset(f"bot{k}/home")
        p, q = np.asarray(pose.position), np.asarray(pose.orientation)
        for body in ("torso", "leg"):
            mine = data.body(f"bot{k}/{body}")
            np.testing.assert_allclose(mine.xpos, p + _rotate(q, ref.body(body).xpos), atol=1e-12)
            _same_rotation(mine.xquat, _mul(q, ref.body(body).xquat))
        assert data.joint(f"bot{k}/hip").qpos[0] == 0.5
        for other in range(len(POSES)):  # the other robots at their initial poses
            if other != k:
                there = POSES[other]
                start = np.asarray(there.position) + _rotate(np.asarray(there.orientation), np.array([0, 0, 0.2]))
                np.testing.assert_allclose(data.body(f"bot{other}/torso").xpos, start, atol=1e-12)
    world.reset()
    np.testing.assert_allclose(data.body("bot0/torso").xpos, [1.0, -0.5, 0.2], atol=1e-12)
    assert data.time == 0.0


def test_the_pose_is_applied_to_the_keyframe_the_robot_then_runs_from() -> None:
    """After the reset the state is the keyframe's: the controls are the key's and the robot falls from there."""
    world = World(base_dir=FREEBOT.parent)
    world.insert(MjcfRobot(name="bot", file="freebot.xml", pose=POSES[1]))
    _, data = world.compile()
    world.reset("bot/home")
    assert data.ctrl[0] == 0.5
    z0 = float(data.body("bot/torso").xpos[2])
    world.run(0.1)
    assert data.body("bot/torso").xpos[2] < z0


@pytest.mark.parametrize(
    ("folder", "file", "key", "kw", "root"),
    [
        ("arm", "arm.xml", "home", {}, "base"),  # welded to the entity's body
        ("walker", "walker.xml", "spread", {"free": True}, "root"),  # under the entity's free joint
        ("walker", "ballbot.xml", "turned", {"root_slides": True}, "head"),  # slides at 0: at the pose
    ],
)
def test_roots_welded_free_or_slid_by_simrun_stay_at_the_entity_pose(
    folder: str, file: str, key: str, kw: dict[str, bool], root: str
) -> None:
    """The model's root is where the entity puts it, in the initial state and at the keyframe alike."""
    world = World(base_dir=FIXTURES / folder)
    world.insert(MjcfRobot(name="bot", file=file, pose=POSES[1], **kw))  # type: ignore[arg-type]
    _, data = world.compile()
    start = data.body(f"bot/{root}").xpos.copy(), data.body(f"bot/{root}").xquat.copy()
    ref = _reference(FIXTURES / folder / file, key)
    p, q = np.asarray(POSES[1].position), np.asarray(POSES[1].orientation)
    np.testing.assert_allclose(start[0], p + _rotate(q, ref.body(root).xpos), atol=1e-12)
    world.reset(f"bot/{key}")
    np.testing.assert_allclose(data.body(f"bot/{root}").xpos, start[0], atol=1e-12)
    if not kw.get("root_slides"):  # the ball walker's head turns on its own keyed hinge
        _same_rotation(data.body(f"bot/{root}").xquat, start[1])


def test_an_unknown_keyframe_is_refused_with_the_list() -> None:
    world = World(base_dir=FREEBOT.parent)
    world.insert(MjcfRobot(name="bot", file="freebot.xml"))
    with pytest.raises(EntityError, match=r"no keyframe named 'home'; keyframes: bot/home"):
        world.reset("home")


def test_a_keyed_mocap_body_lands_at_pose_times_its_key(tmp_path: Path) -> None:
    """A top-level mocap body's keyed ``mpos``/``mquat`` are composed with the entity's pose too."""
    (tmp_path / "mocap.xml").write_text(
        '<mujoco><worldbody><body name="target" mocap="true" pos="0 0 0.5"><geom size="0.05" contype="0" '
        'conaffinity="0"/></body></worldbody><keyframe><key name="up" mpos="0.2 0 1" '
        'mquat="0.9238795325112867 0 0 0.3826834323650898"/></keyframe></mujoco>'
    )
    world = World(base_dir=tmp_path)
    world.insert(MjcfRobot(name="m", file="mocap.xml", pose=POSES[1]))
    _, data = world.compile()
    world.reset("m/up")
    p, q = np.asarray(POSES[1].position), np.asarray(POSES[1].orientation)
    key_q = np.array([0.9238795325112867, 0.0, 0.0, 0.3826834323650898])
    np.testing.assert_allclose(data.body("m/target").xpos, p + _rotate(q, np.array([0.2, 0.0, 1.0])), atol=1e-12)
    _same_rotation(data.body("m/target").xquat, _mul(q, key_q))
