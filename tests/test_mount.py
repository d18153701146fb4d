"""Mount anything on any body (issue 37 item 3): cameras and sensors follow the body they ride on.

Ground truth is MuJoCo's own state: ``data.xpos``/``data.xmat``/``data.xquat`` of the body, ``data.cam_xpos``/
``data.cam_xmat`` of the cameras, and ``mujoco.mj_ray`` cast in a copy of the model whose robot geoms are made
transparent (``mj_ray`` skips geoms with alpha 0), the robot's geoms picked by their ``walker/`` names.

The walker is ``fixtures/mjcf/freewalker/freewalker.xml``: a free joint on its torso, so the entity's own body
stays a marker at the spawn point while the torso falls, lands and is kicked about by its leg motors.
"""

from __future__ import annotations

import copy
import math
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pytest
from conftest import needs_gl

from simrun import Box, Camera, EntityError, Ground, Pose, World, load_scene
from simrun.robots.catalogue import BoeBot
from simrun.robots.mjcf_robot import MjcfRobot
from simrun.robots.urdf_robot import UrdfRobot
from simrun.sensors.cameras import StereoCamera, StereoRig, Webcam
from simrun.sensors.laser import LaserRangeFinder
from simrun.sensors.mount import root_body
from simrun.sensors.range_cone import IRDistance, RangeCone, Sonar
from simrun.sensors.robot_state import GPS, IMU

FIXTURES = Path(__file__).resolve().parent.parent / "fixtures"
WALKER = FIXTURES / "mjcf" / "freewalker"
OFFSET = (0.1, 0.02, 0.3)  # the camera's mount offset in the torso frame, m
TILT = (math.cos(0.3), 0.0, math.sin(0.3), 0.0)  # and its orientation in it (0.6 rad about y)
SPAWN = Pose((0.5, 0.2, 0.0))


def _walker_world() -> World:
    world = World(base_dir=WALKER)
    world.insert(Ground(name="ground"))
    world.insert(MjcfRobot(name="walker", file="freewalker.xml", pose=SPAWN))
    for k, (x, y) in enumerate(((1.2, 0.2), (0.5, 1.0), (-0.4, 0.0), (0.5, -0.7))):  # crates all round
        world.insert(Box(name=f"crate{k}", dimensions=(0.3, 0.3, 0.6), pose=Pose((x, y, 0.3))))
    return world


def _kick(world: World, step: int) -> None:
    """Drive the four leg motors with sines of different periods (deterministic)."""
    world.data.ctrl[:] = np.sin(0.02 * step * np.arange(1, 5) + np.arange(4))


def _robot_geoms(model: mujoco.MjModel, robot: str = "walker") -> np.ndarray:
    """Geom ids of the robot, by name: the geoms of its bodies named ``robot`` or ``robot/...``, and its geoms
    named ``robot/...`` on other (unnamed) bodies; a model's own floor (on the world body) is not the robot's."""
    names = [model.body(b).name for b in range(model.nbody)]
    mine = [b for b, name in enumerate(names) if name == robot or name.startswith(f"{robot}/")]
    named = [g for g in range(model.ngeom) if model.geom(g).name.startswith(f"{robot}/") and model.geom_bodyid[g]]
    return np.union1d(np.flatnonzero(np.isin(model.geom_bodyid, mine)), np.asarray(named, dtype=int))


def _without(model: mujoco.MjModel, geoms: np.ndarray) -> mujoco.MjModel:
    """A copy of the model in which ``mj_ray`` cannot see ``geoms`` (alpha 0, no material to take it from)."""
    clear = copy.copy(model)
    clear.geom_rgba[geoms, 3] = 0.0
    clear.geom_matid[geoms] = -1
    return clear


def _ray(model: mujoco.MjModel, data: mujoco.MjData, origin: np.ndarray, direction: np.ndarray) -> tuple[float, int]:
    hit = np.zeros(1, dtype=np.int32)
    distance = mujoco.mj_ray(model, data, origin, direction, None, 1, -1, hit)
    return float(distance), int(hit[0])


def _scan_truth(
    clear: mujoco.MjModel, data: mujoco.MjData, body: int, height: float, angles: np.ndarray
) -> list[tuple[float, int]]:
    """(distance, geom) of each ray of a planar scan from ``height`` on the body's Z, in the body's XY plane."""
    rotation = data.xmat[body].reshape(3, 3)
    origin = data.xpos[body] + rotation[:, 2] * height
    return [_ray(clear, data, origin, rotation @ np.array([math.cos(a), math.sin(a), 0.0])) for a in angles]


def _follows(data: mujoco.MjData, body: int, camera: int, offset: Any, quat: Any) -> tuple[float, float]:
    """(position error m, orientation error) of a camera against its body's pose and the mount offset."""
    xmat = data.xmat[body].reshape(3, 3)
    expected = data.xpos[body] + xmat @ np.asarray(offset)
    turn = np.zeros(9)
    mujoco.mju_quat2Mat(turn, np.asarray(quat, dtype=float))
    return (
        float(np.linalg.norm(data.cam_xpos[camera] - expected)),
        float(np.abs(data.cam_xmat[camera].reshape(3, 3) - xmat @ turn.reshape(3, 3)).max()),
    )


def test_a_camera_and_a_laser_on_the_walkers_torso_follow_it_over_2_s() -> None:
    """The camera's world position follows the torso within 1 mm (measured: 2.3e-16 m) while the torso
    travels; the laser on the torso never reports a hit on the walker's own geoms: every range equals
    ``mj_ray`` in the world without the walker, while the same laser without exclusion sees the legs."""
    world = _walker_world()
    world.insert(Camera(name="cam", parent="walker", pose=Pose(OFFSET, TILT)))  # default: the robot's root
    world.insert(Camera(name="eye", body="walker/torso", pose=Pose(OFFSET, TILT)))  # named
    laser = LaserRangeFinder(world, "walker", fov_deg=360, rays=72, height=-0.3, rate=0, points=True)
    blind = LaserRangeFinder(world, "walker", fov_deg=360, rays=72, height=-0.3, rate=0, exclude="none")
    model, data = world.model, world.data
    torso = model.body("walker/torso").id
    assert root_body(model, "walker") == torso == int(model.jnt_bodyid[model.joint("walker/root").id])
    cameras = [model.camera("walker/cam").id, model.camera("eye").id]
    clear = _without(model, _robot_geoms(model))
    start = data.xpos[torso].copy()
    worst, turned, travelled, self_seen = 0.0, 0.0, 0.0, 0
    for step in range(int(2.0 / model.opt.timestep)):
        _kick(world, step)
        truth = _scan_truth(clear, data, torso, -0.3, laser.angles) if step % 10 == 0 else None
        world.step()  # the sensors sample the state the step starts from: the one the truth was cast in
        for camera in cameras:
            position, orientation = _follows(data, torso, camera, OFFSET, TILT)
            worst, turned = max(worst, position), max(turned, orientation)
        travelled = max(travelled, float(np.linalg.norm(data.xpos[torso] - start)))
        if truth is None:
            continue
        scan = laser.reading
        for k, (expected, gid) in enumerate(truth):
            if gid < 0 or expected > laser.max_range:
                assert scan.ranges[k] == laser.max_range and np.isnan(scan.points[k]).all()
            else:
                assert scan.ranges[k] == pytest.approx(expected, abs=1e-9)
                assert not model.geom(gid).name.startswith("walker/")
        self_seen += int(np.sum(blind.reading.ranges < scan.ranges - 1e-6))
    assert travelled > 0.5  # the torso fell and moved (measured 1.08 m)
    assert worst < 1e-3 and turned < 1e-9
    assert self_seen > 100  # the plane cuts the legs: without exclusion they are seen (measured: 1,286 rays)
    assert laser.mount == "walker/torso"


def test_the_spawn_marker_does_not_move_and_was_what_a_child_camera_rode_on() -> None:
    """Control: the entity's own body stays at the spawn point while the torso walks away."""
    world = _walker_world()
    for step in range(500):
        _kick(world, step)
        world.step()
    marker, torso = world.body("walker"), world.body("walker/torso")
    np.testing.assert_allclose(marker.xpos, SPAWN.position, atol=1e-12)
    assert np.linalg.norm(torso.xpos - marker.xpos) > 0.3


SENSOR_KINDS = ["GPS", "IMU", "LaserRangeFinder", "IRDistance", "Sonar", "RangeCone", "Camera", "StereoRig"]
LINK = "walker/left_shin"


def _make(kind: str, world: World, body: str | None) -> Any:
    if kind == "GPS":
        return GPS(world, "walker", rate=0, body=body)
    if kind == "IMU":
        return IMU(world, "walker", rate=0, body=body)
    if kind == "LaserRangeFinder":
        return LaserRangeFinder(world, "walker", fov_deg=360, rays=24, height=0.0, rate=0, points=True, body=body)
    if kind in ("IRDistance", "Sonar", "RangeCone"):
        cls: type[RangeCone] = {"IRDistance": IRDistance, "Sonar": Sonar, "RangeCone": RangeCone}[kind]
        return cls(world, "walker", offset=(0.05, 0.0, -0.1), direction=(1.0, 0.2, 0.0), rate=0, body=body)
    if kind == "Camera":
        return world.insert(Camera(name="cam", parent="walker", body=body, pose=Pose(OFFSET, TILT)))
    return world.insert(StereoRig(name="rig", parent="walker", body=body, baseline=0.08, pose=Pose(OFFSET, TILT)))


def _expected(kind: str, sensor: Any, world: World, body: int) -> Any:
    """What the sensor's next sample must read, from the body's state now (the state the next step samples)."""
    model, data = world.model, world.data
    rotation = data.xmat[body].reshape(3, 3)
    if kind == "GPS":
        return data.xpos[body].copy()
    if kind == "IMU":
        return data.xquat[body].copy()
    clear = _without(model, _robot_geoms(model))
    if kind == "LaserRangeFinder":
        truth = _scan_truth(clear, data, body, 0.0, sensor.angles)
        return np.array([d if gid >= 0 and d <= sensor.max_range else sensor.max_range for d, gid in truth])
    origin = data.xpos[body] + rotation @ sensor.offset
    hits = [_ray(clear, data, origin, rotation @ local) for local in sensor._local]
    seen = [d for d, gid in hits if gid >= 0 and d <= sensor.max_range]
    return float(np.clip(min(seen) if seen else sensor.max_range, sensor.min_range, sensor.max_range))


def _check(kind: str, sensor: Any, world: World, body: int, expected: Any) -> None:
    """The sensor's reading (or camera pose) against the body's state from MuJoCo."""
    model, data = world.model, world.data
    if kind == "GPS":
        np.testing.assert_allclose(sensor.reading.position, expected, atol=1e-12)
    elif kind == "IMU":
        np.testing.assert_allclose(sensor.reading.orientation, expected, atol=1e-12)
    elif kind == "LaserRangeFinder":
        np.testing.assert_allclose(sensor.reading.ranges, expected, atol=1e-9)
    elif kind in ("IRDistance", "Sonar", "RangeCone"):
        assert sensor.reading.distance == pytest.approx(expected, abs=1e-9)
    else:
        look_x = (0.5, 0.5, -0.5, -0.5)  # a rig's eyes look along its +X
        eyes = (
            [("walker/cam", (0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0))]
            if kind == "Camera"
            else [("walker/rig/left", (0.0, 0.04, 0.0), look_x), ("walker/rig/right", (0.0, -0.04, 0.0), look_x)]
        )
        for name, local, quat in eyes:
            offset, turn = np.zeros(3), np.zeros(4)
            mujoco.mju_rotVecQuat(offset, np.asarray(local), np.asarray(TILT))
            mujoco.mju_mulQuat(turn, np.asarray(TILT), np.asarray(quat, dtype=float))
            position, orientation = _follows(data, body, model.camera(name).id, np.asarray(OFFSET) + offset, turn)
            assert position < 1e-9 and orientation < 1e-9
            assert int(model.cam_bodyid[model.camera(name).id]) == body


@pytest.mark.parametrize("kind", SENSOR_KINDS)
@pytest.mark.parametrize("body", [LINK, None], ids=["body=link", "default"])
def test_every_sensor_kind_rides_on_its_body(kind: str, body: str | None) -> None:
    """``body = "walker/left_shin"`` puts each kind on that link; without it, on the root (the torso)."""
    world = _walker_world()
    sensor = _make(kind, world, body)
    model = world.model
    expected = model.body(body or "walker/torso").id
    for step in range(300):  # 0.6 s: the walker has fallen and the shin swings
        _kick(world, step)
        due = step % 60 == 59
        truth = _expected(kind, sensor, world, expected) if due and kind not in ("Camera", "StereoRig") else None
        world.step()
        if due:
            _check(kind, sensor, world, expected, truth)
    if kind == "Camera":
        sensor = Webcam(world, "walker/cam")  # the sensor that renders it says where it rides
    elif kind == "StereoRig":
        sensor = StereoCamera(world, "walker/rig")
    else:
        assert sensor.mounting.id == expected
    assert sensor.mount == (body or "walker/torso")


@needs_gl
def test_webcam_and_stereo_camera_render_from_cameras_on_the_torso() -> None:
    """Cameras on the torso looking at it see its orange after the walker fell and tumbled (1 s); Webcam and
    StereoCamera render the cameras that follow. Control: the same camera left where it started (a top-level
    camera at its initial world pose) no longer sees the torso."""
    world = _walker_world()
    toward = (math.cos(math.pi / 4), 0.0, math.sin(math.pi / 4), 0.0)  # the camera's -Z along the torso's -X
    world.insert(Camera(name="cam", parent="walker", pose=Pose((0.25, 0.0, 0.0), toward), fovy=20.0))
    world.insert(StereoRig(name="rig", body="walker/torso", pose=Pose((-0.25, 0.0, 0.0))))  # looks along +X
    start = Pose((SPAWN.position[0] + 0.25, SPAWN.position[1], 1.0), toward)  # the torso starts 1 m up
    world.insert(Camera(name="left_behind", pose=start, fovy=20.0))
    webcam = Webcam(world, "walker/cam", width=32, height=24, rate=0)
    stereo = StereoCamera(world, "rig", rate=0)
    behind = Webcam(world, "left_behind", width=32, height=24, rate=0)
    for step in range(500):
        _kick(world, step)
        world.step()

    def orange(frame: Any) -> bool:  # the torso's 0.7 0.5 0.3; the ground's checker and the sky are not
        red, green, blue = frame.rgb[frame.rgb.shape[0] // 2, frame.rgb.shape[1] // 2].astype(int)
        return bool(red > green > blue and red - blue > 40)

    assert orange(webcam.reading) and orange(stereo.reading.left) and orange(stereo.reading.right)
    assert not orange(behind.reading)


def test_a_misspelt_body_is_one_line_naming_the_entity_the_key_and_the_bodies() -> None:
    world = _walker_world()
    gps = GPS(world, "walker", body="walker/torsoo", rate=0)
    with pytest.raises(EntityError) as caught:
        gps.sample(world.model, world.data)
    text = str(caught.value)
    assert "\n" not in text and caught.value.key == "body"
    assert "'walker/torsoo' is not a body of 'walker'; did you mean 'walker/torso'?" in text
    assert "bodies of 'walker': walker, walker/torso, walker/left_thigh" in text
    world.insert(Camera(name="cam", body="walker/left_shn"))
    with pytest.raises(
        EntityError, match=r"'walker/left_shn' is not a body of 'walker'; did you mean 'walker/left_shin'"
    ):
        world.compile()


def test_a_scene_mounts_a_camera_and_a_laser_on_a_link(tmp_path: Path) -> None:
    """The ``body`` keys in TOML: a Camera and a LaserRangeFinder on the walker's thigh; the scene check passes."""
    (tmp_path / "s.toml").write_text(
        f'[[entities]]\ntype = "MjcfRobot"\nname = "walker"\nfile = "{(WALKER / "freewalker.xml").as_posix()}"\n\n'
        '[[entities]]\ntype = "Camera"\nname = "knee_cam"\nparent = "walker"\nbody = "walker/left_thigh"\n\n'
        '[[sensors]]\ntype = "LaserRangeFinder"\nname = "lidar"\nentity = "walker"\nbody = "walker/left_thigh"\n'
    )
    world = load_scene(tmp_path / "s.toml")
    world.check_bindings()
    model = world.model
    thigh = model.body("walker/left_thigh").id
    assert int(model.cam_bodyid[model.camera("walker/knee_cam").id]) == thigh
    assert world.sensors["lidar"].caster.bind(model) == thigh


def _boebot_world(box_height: float) -> World:
    world = World()
    world.insert(Ground(name="ground"))
    world.insert(BoeBot(name="bot", pose=Pose((0.0, 0.0, 0.001))))
    world.insert(Box(name="box", dimensions=(0.2, 0.2, box_height), pose=Pose((0.5, 0.0, box_height / 2))))
    return world


def test_the_boebots_default_laser_sees_a_0_2_m_box_in_front_of_it() -> None:
    """At the chassis top (0.105 m) the default laser sees the 0.2 m box; at the former 0.3 m it did not."""
    world = _boebot_world(0.2)
    laser = LaserRangeFinder(world, "bot", rate=0)
    former = LaserRangeFinder(world, "bot", height=0.3, rate=0)
    world.step()
    ahead = int(np.argmin(np.abs(laser.angles)))
    face = 0.5 - 0.1  # the box's near face, x = 0.4 m
    assert laser.reading.ranges[ahead] == pytest.approx(face - world.body("bot").xpos[0], abs=1e-6)
    assert former.reading.ranges[ahead] == former.max_range
    chassis = world.model.geom("bot/chassis")
    assert laser.mount_height(world.model) == pytest.approx(chassis.pos[2] + chassis.size[2], abs=1e-12)
    assert laser.mount_height(world.model) == pytest.approx(0.105, abs=1e-12)


ROBOTS: dict[str, Any] = {
    "BoeBot": lambda: BoeBot(name="r", pose=Pose((0.0, 0.0, 0.001))),
    "MjcfRobot free base": lambda: MjcfRobot(name="r", file=str(WALKER / "freewalker.xml")),
    "MjcfRobot free = true": lambda: MjcfRobot(
        name="r", file=str(FIXTURES / "mjcf" / "walker" / "walker.xml"), free=True, pose=Pose((0.0, 0.0, 0.3))
    ),
    "MjcfRobot root_slides": lambda: MjcfRobot(
        name="r", file=str(FIXTURES / "mjcf" / "walker" / "ballbot.xml"), root_slides=True, pose=Pose((0, 0, 0.2))
    ),
    "MjcfRobot arm": lambda: MjcfRobot(name="r", file=str(FIXTURES / "mjcf" / "arm" / "arm.xml")),
    "UrdfRobot": lambda: UrdfRobot(
        name="r", urdf=str(FIXTURES / "urdf" / "wheelbot" / "wheelbot.urdf"), free=True, pose=Pose((0, 0, 0.06))
    ),
}


def _moving_root(model: mujoco.MjModel) -> int:
    """The body of the robot ``r`` carrying a free joint or the slides ``r/root_x``..., else the body ``r``."""
    for j in range(model.njnt):
        name = model.joint(j).name
        if name.startswith("r") and (int(model.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_FREE) or name == "r/root_x"):
            return int(model.jnt_bodyid[j])
    return int(model.body("r").id)


@pytest.mark.parametrize("robot", list(ROBOTS))
def test_the_default_mount_is_the_body_that_moves_and_the_rays_never_see_the_robot(robot: str) -> None:
    """Over every robot kind: a GPS without ``body`` reads the body carrying the robot's root joint, and a
    360-degree laser in the plane of that body's origin reads the world as ``mj_ray`` does without the robot."""
    world = World()
    world.insert(Ground(name="ground"))
    world.insert(ROBOTS[robot]())
    for k, (x, y) in enumerate(((0.7, 0.0), (0.0, 0.8), (-0.9, 0.1))):
        world.insert(Box(name=f"wall{k}", dimensions=(0.2, 0.6, 1.0), pose=Pose((x, y, 0.5))))
    gps = GPS(world, "r", rate=0)
    laser = LaserRangeFinder(world, "r", fov_deg=360, rays=90, height=0.0, rate=0)
    world.run(0.3)
    model, data = world.model, world.data
    root = _moving_root(model)
    position = data.xpos[root].copy()
    truth = _scan_truth(_without(model, _robot_geoms(model, "r")), data, root, 0.0, laser.angles)
    world.step()  # samples the state the truth was taken from
    np.testing.assert_allclose(gps.reading.position, position, atol=1e-12)
    for k, (expected, gid) in enumerate(truth):
        got = laser.reading.ranges[k]
        assert got == (pytest.approx(expected, abs=1e-9) if gid >= 0 and expected <= laser.max_range else 8.0)


BENCH = Path(__file__).resolve().parent.parent / ".bench-mjcf" / "lib" / "python3.11" / "site-packages"
VENDOR = {
    "dm_control walker": BENCH / "dm_control" / "suite" / "walker.xml",
    "dm_control humanoid": BENCH / "dm_control" / "suite" / "humanoid.xml",
    "gymnasium ant": BENCH / "gymnasium" / "envs" / "mujoco" / "assets" / "ant.xml",
}


@pytest.mark.parametrize("model_name", list(VENDOR))
def test_vendor_walkers_carry_a_camera_and_a_laser_on_the_torso(model_name: str) -> None:
    """Where the bench environment (.bench-mjcf/, ``make bench``) is installed: dm_control's planar walker
    (slides ``rootz``/``rootx`` on its torso), its humanoid and gymnasium's ant (free joints) carry a default-mounted
    camera and laser on the torso for 2 s of sine controls. Measured: the torso travels 1.34, 1.64 and 1.16 m; the
    camera stays within 1.4e-16 m of ``xpos + xmat @ offset``; every range of a 72-ray scan through the legs, every
    40 ms, equals ``mj_ray`` without the robot within 1e-9 m."""
    path = VENDOR[model_name]
    if not path.is_file():
        pytest.skip(f"{path} not installed (the bench environment, .bench-mjcf/)")
    world = World(base_dir=path.parent)
    world.insert(Ground(name="ground"))
    world.insert(MjcfRobot(name="walker", file=path.name))
    world.insert(Box(name="crate", dimensions=(0.3, 0.3, 1.0), pose=Pose((2.0, 0.0, 0.5))))
    world.insert(Camera(name="cam", parent="walker", pose=Pose(OFFSET, TILT)))
    laser = LaserRangeFinder(world, "walker", fov_deg=360, rays=72, height=-0.4, rate=0)
    model, data = world.model, world.data
    torso = model.body("walker/torso").id
    assert root_body(model, "walker") == torso
    clear, camera, start = _without(model, _robot_geoms(model)), model.camera("walker/cam").id, data.xpos[torso].copy()
    worst = 0.0
    for step in range(int(2.0 / model.opt.timestep)):
        data.ctrl[:] = np.sin(0.02 * step * np.arange(1, model.nu + 1))
        truth = _scan_truth(clear, data, torso, -0.4, laser.angles) if step % 20 == 0 else None
        world.step()
        worst = max(worst, _follows(data, torso, camera, OFFSET, TILT)[0])
        if truth is not None:
            expected = [d if gid >= 0 and d <= laser.max_range else laser.max_range for d, gid in truth]
            np.testing.assert_allclose(laser.reading.ranges, expected, atol=1e-9)
    assert worst < 1e-3
    assert np.linalg.norm(data.xpos[torso] - start) > 0.5
