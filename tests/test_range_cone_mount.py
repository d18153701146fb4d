"""IRDistance and Sonar mounted on a link of an MJCF robot (``body = "ENTITY/link"``), issue 29 deliver 3.

Ground truth: the link's pose from MuJoCo's kinematics, and a plate placed (a kinematic box) at a chosen
distance along the sensor's axis in the world, facing it: the nearest hit is that distance exactly.
"""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from simrun import Box, EntityError, Pose, World, load_scene
from simrun.robots.mjcf_robot import MjcfRobot
from simrun.sensors.range_cone import IRDistance, RangeCone, Sonar

ARM = Path(__file__).resolve().parent.parent / "fixtures" / "mjcf" / "arm" / "arm.xml"
TURN = Pose((0.5, -0.2, 0.3), (math.cos(0.4), 0.0, 0.0, math.sin(0.4)))  # 0.8 rad about z
HALF = 0.01  # the plate's half thickness, m
POSES = ({"yaw": 0.4, "shoulder": -0.3, "elbow": 0.8, "wrist": -0.2}, {"yaw": -1.1, "shoulder": 0.5, "wrist": 0.7})


def _world() -> World:
    world = World(base_dir=ARM.parent)
    world.insert(MjcfRobot(name="arm", file="arm.xml", pose=TURN))
    world.insert(Box(name="plate", dimensions=(2 * HALF, 1.0, 1.0), kinematic=True, pose=Pose((9.0, 9.0, 9.0))))
    return world


def _facing(axis: np.ndarray) -> tuple[float, float, float, float]:
    """A quaternion turning the box's x axis onto ``axis`` (its large face then faces the sensor)."""
    quat = np.zeros(4)
    mujoco.mju_quatZ2Vec(quat, axis)  # z onto axis; then x onto z: turn by -90 degrees about y first
    turn = np.array([math.cos(-math.pi / 4), 0.0, math.sin(-math.pi / 4), 0.0])
    out = np.zeros(4)
    mujoco.mju_mulQuat(out, quat, turn)
    return (float(out[0]), float(out[1]), float(out[2]), float(out[3]))


def _place(world: World, joints: dict[str, float], sensor: RangeCone, distance: float) -> float:
    """Pose the arm, put the plate ``distance`` ahead of the sensor along its axis; the reading."""
    model, data = world.model, world.data
    mujoco.mj_resetData(model, data)
    for name, value in joints.items():
        data.qpos[model.joint(f"arm/{name}").qposadr[0]] = value
    mujoco.mj_kinematics(model, data)
    link = data.body("arm/wrist")
    rotation = link.xmat.reshape(3, 3)
    origin = link.xpos + rotation @ sensor.offset
    axis = rotation @ (sensor._local.mean(axis=0) / np.linalg.norm(sensor._local.mean(axis=0)))
    world.set_pose("plate", origin + axis * (distance + HALF), _facing(axis))
    mujoco.mj_forward(model, data)
    reading = sensor.sample(model, data)
    assert reading.time == data.time
    return float(reading.distance)


@pytest.mark.parametrize(("kind", "distance"), [(IRDistance, 0.35), (Sonar, 1.7)])
def test_range_cone_on_a_link_reads_the_distance_along_the_turned_link(kind: type[RangeCone], distance: float) -> None:
    world = _world()
    sensor = kind(world, "arm", body="arm/wrist", offset=(0.03, 0.0, 0.02), direction=(1.0, 0.0, -0.3), rate=0.0)
    assert sensor.mount == "arm/wrist"
    world.compile()
    for joints in POSES:  # two link orientations: the cone turns with the link
        assert _place(world, joints, sensor, distance) == pytest.approx(distance, abs=1e-9)


def test_the_same_plate_seen_from_the_entity_body_is_where_its_rays_meet_the_plate() -> None:
    """Control: a cone on the arm's own (entity) body sees the plate along its own rays: ray-plane geometry."""
    world = _world()
    on_link = Sonar(world, "arm", body="arm/wrist", rate=0.0)
    on_entity = Sonar(world, "arm", rate=0.0)
    world.compile()
    assert _place(world, POSES[0], on_link, 0.3) == pytest.approx(0.3, abs=1e-9)
    model, data = world.model, world.data
    plate = data.body("plate")
    normal, centre = plate.xmat.reshape(3, 3)[:, 0], plate.xpos  # the plate's x: its thin axis
    frame = data.body("arm").xmat.reshape(3, 3)
    origin = data.body("arm").xpos + frame @ on_entity.offset
    hits = []
    for ray in on_entity._local @ frame.T:
        for face in (centre - HALF * normal, centre + HALF * normal):
            along = float(np.dot(face - origin, normal) / np.dot(ray, normal))
            point = origin + along * ray - face
            if along > 0 and np.all(np.abs(plate.xmat.reshape(3, 3).T @ point)[1:] <= 0.5):
                hits.append(along)
    expected = min(hits) if hits else on_entity.max_range
    assert abs(expected - 0.3) > 0.05  # it looks elsewhere (measured 0.607 m)
    assert on_entity.sample(model, data).distance == pytest.approx(expected, abs=1e-9)


def test_a_body_of_another_entity_is_refused() -> None:
    world = _world()
    with pytest.raises(EntityError, match="not a body of 'arm'"):
        Sonar(world, "arm", body="plate")


def test_a_scene_mounts_a_range_cone_on_a_link(tmp_path: Path) -> None:
    (tmp_path / "s.toml").write_text(
        f'[[entities]]\ntype = "MjcfRobot"\nname = "arm"\nfile = "{ARM.as_posix()}"\n\n'
        '[[sensors]]\ntype = "Sonar"\nname = "sonar"\nentity = "arm"\nbody = "arm/fore"\n'
    )
    world = load_scene(tmp_path / "s.toml")
    sensor = world.sensors["sonar"]
    assert isinstance(sensor, Sonar) and sensor.mount == "arm/fore"
    world.step()
    assert sensor.reading is not None and sensor.caster.body == world.model.body("arm/fore").id
