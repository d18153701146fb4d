"""Drive stack: differential-drive robots, the drive service and sensors, in real MuJoCo worlds."""

import math
from pathlib import Path

import numpy as np
import pytest

from simrun import Box, EntityError, Ground, Pose, World, load_scene
from simrun.drive import BoeBot, IRobotCreate, LegoNxtTribot, Pioneer3DX
from simrun.drive_service import DriveLimits, DriveService
from simrun.sensors import GPS, IMU, Bumper, Encoders, LaserRangeFinder

SCENES = Path(__file__).resolve().parent.parent / "fixtures" / "scenes"


def heading(world, name):
    q = world.body(name).xquat
    return math.degrees(2 * math.atan2(q[3], q[0]))


def boebot_world():
    world = World()
    world.insert(Ground(name="ground"))
    world.insert(BoeBot(name="bot", pose=Pose((0, 0, 0.001))))
    drive = DriveService(world, "bot")
    world.run(0.3)
    return world, drive


@pytest.mark.parametrize("robot", [BoeBot, Pioneer3DX, IRobotCreate, LegoNxtTribot])
def test_ready_robots_stand_still_on_the_ground(robot):
    world = World()
    world.insert(Ground(name="ground"))
    entity = world.insert(robot(name="r", pose=Pose((0, 0, 0.001))))
    world.run(1.0)
    assert world.warnings() == {}
    assert abs(world.body("r").xpos[2]) < 2e-3 and np.abs(world.body("r").cvel).max() < 1e-2
    total = world.model.body_subtreemass[world.model.body("r").id]
    assert total == pytest.approx(entity.mass + 2 * entity.wheel_mass + 0.001)


def test_drive_one_metre_stops_within_two_centimetres():
    world, drive = boebot_world()
    start = world.body("bot").xpos.copy()
    drive.drive_distance(1.0, power=0.6)
    assert drive.busy
    assert world.run_until(lambda: not drive.busy, timeout=20)
    world.run(0.5)
    travelled = world.body("bot").xpos - start
    assert abs(np.linalg.norm(travelled[:2]) - 1.0) < 0.02
    assert abs(travelled[1]) < 0.02  # straight
    odometry = drive.odometry()
    assert abs(odometry.x - travelled[0]) < 0.02 and abs(odometry.y) < 0.01


@pytest.mark.parametrize("degrees", [90.0, -90.0])
def test_rotate_ninety_degrees_within_two(degrees):
    world, drive = boebot_world()
    before = heading(world, "bot")
    drive.rotate_degrees(degrees, power=0.5)
    assert world.run_until(lambda: not drive.busy, timeout=20)
    world.run(0.5)
    assert abs((heading(world, "bot") - before) - degrees) < 2.0


def test_cmd_vel_arc_matches_its_radius():
    world, drive = boebot_world()
    points = []
    for k in range(3000):
        if k % 50 == 0:
            drive.cmd_vel(0.1, 0.5)  # radius 0.2 m
        world.step()
        if k > 1000 and k % 10 == 0:
            points.append(world.body("bot").xpos[:2].copy())
    p = np.array(points)
    a = np.c_[2 * p, np.ones(len(p))]
    cx, cy, c = np.linalg.lstsq(a, (p**2).sum(axis=1), rcond=None)[0]
    radius = math.sqrt(c + cx * cx + cy * cy)
    assert radius == pytest.approx(0.2, rel=0.05)


def test_cmd_vel_limits_and_timeout():
    world, drive = boebot_world()
    drive.limits = DriveLimits(max_linear=0.2, command_timeout=0.5)
    drive.cmd_vel(5.0, 0.0)  # far above the limit
    world.run(0.4)
    assert world.body("bot").cvel[3] == pytest.approx(0.2, abs=0.03)
    world.run(2.0)  # no new command: it stops
    assert abs(world.body("bot").cvel[3]) < 0.01


def test_stop_disable_and_encoders():
    world, drive = boebot_world()
    drive.drive_speed(0.2, 0.2)
    world.run(1.0)
    left, right = drive.encoders()
    assert left > 0.1 and right > 0.1
    drive.all_stop()
    world.run(1.0)
    assert abs(world.body("bot").cvel[3]) < 0.005
    drive.reset_encoders()
    assert drive.encoders() == (0.0, 0.0)
    drive.enable(False)
    with pytest.raises(EntityError, match="disabled"):
        drive.drive_distance(1.0)
    with pytest.raises(EntityError, match="not a differential-drive robot"):
        world.insert(Box(name="crate"))
        DriveService(world, "crate")


def test_driving_into_a_box_is_stopped_and_the_bumper_fires():
    world = World()
    world.insert(Ground(name="ground"))
    world.insert(BoeBot(name="bot", pose=Pose((0, 0, 0.001))))
    world.insert(Box(name="wall", dimensions=(0.1, 1.0, 0.3), pose=Pose((0.4, 0, 0.15))))
    drive = DriveService(world, "bot")
    bumper = Bumper(world, "bot")
    drive.drive_distance(1.0, power=0.6)
    world.run(6.0)
    assert world.body("bot").xpos[0] < 0.4 - 0.05 - 0.065 + 0.01  # front face stopped at the wall
    assert bumper.reading.pressed and bumper.reading.touching == ("wall/geom",)


def test_laser_sees_the_walls_at_the_right_distances():
    world = World()
    world.insert(Ground(name="ground"))
    for name, pos, dims in (
        ("n", (0, 2, 0.25), (4, 0.1, 0.5)),
        ("s", (0, -2, 0.25), (4, 0.1, 0.5)),
        ("e", (2, 0, 0.25), (0.1, 4, 0.5)),
        ("w", (-2, 0, 0.25), (0.1, 4, 0.5)),
    ):
        world.insert(Box(name=f"wall_{name}", dimensions=dims, pose=Pose(pos)))
    world.insert(Pioneer3DX(name="p3dx", pose=Pose((0.5, 0.0, 0.001))))
    laser = LaserRangeFinder(world, "p3dx", fov_deg=360, rays=360, rate=10, points=True)
    world.run(0.55)
    scan = laser.reading
    assert laser.samples == 6  # 10 Hz on the simulation clock: t = 0.002, 0.1, ..., 0.5
    expected = {0: 1.45, 90: 1.95, 180: 2.45, -90: 1.95}
    for angle, distance in expected.items():
        k = int(np.argmin(np.abs(np.degrees(scan.angles) - angle)))
        assert scan.ranges[k] == pytest.approx(distance, abs=0.005)
    assert np.nanmax(np.abs(scan.points[:, :2])) <= 1.95 + 1e-6 + 0.0  # every hit on a wall face
    assert scan.ranges.min() > 1.4  # the robot's own body is excluded


def test_sensor_noise_is_seeded_and_deterministic():
    readings = []
    for _ in range(2):
        world = World()
        world.insert(Ground(name="ground"))
        world.insert(BoeBot(name="bot", pose=Pose((0, 0, 0.001))))
        gps = GPS(world, "bot", rate=10, noise=0.05, seed=7, origin=(47.6, -122.3))
        enc = Encoders(world, "bot", noise=0.01, seed=3)
        world.run(1.0)
        readings.append((gps.reading, enc.reading))
    assert readings[0] == readings[1]
    assert readings[0][0].latitude is not None and abs(readings[0][0].position[0]) < 0.3


def test_imu_at_rest_reads_gravity_up():
    world, _ = boebot_world()
    imu = IMU(world, "bot")
    world.run(0.5)
    assert imu.reading.accelerometer[2] == pytest.approx(9.81, abs=0.05)
    assert np.abs(imu.reading.gyro).max() < 1e-3


def test_boebot_scene_drives_a_square_from_the_scene_file():
    world = load_scene(SCENES / "boebot.toml")
    world.remove("box")
    drive = world.service("DriveService", "boebot")
    start = world.body("boebot").xpos[:2].copy()
    world.run(0.3)
    for _ in range(4):
        drive.drive_distance(0.3, power=0.5)
        assert world.run_until(lambda: not drive.busy, timeout=20)
        drive.rotate_degrees(90, power=0.5)
        assert world.run_until(lambda: not drive.busy, timeout=20)
    world.run(0.5)
    assert np.linalg.norm(world.body("boebot").xpos[:2] - start) < 0.05  # back where it started
    with pytest.raises(EntityError, match="no DriveService is bound"):
        world.service("DriveService", "ground")


@pytest.mark.parametrize("scene", ["boebot.toml", "pioneer_room.toml", "arm_on_base.toml"])
def test_robot_scenes_check_and_round_trip(scene, tmp_path):
    from click.testing import CliRunner

    from simrun import save_scene, scene_text
    from simrun.cli import main

    result = CliRunner().invoke(main, ["check", str(SCENES / scene)])
    assert result.exit_code == 0, result.output
    world = load_scene(SCENES / scene)
    saved = tmp_path / scene
    save_scene(world, saved)
    assert scene_text(load_scene(saved)) == saved.read_text()


def test_pioneer_room_scene_laser_from_the_file():
    world = load_scene(SCENES / "pioneer_room.toml")
    laser = world.sensors["laser"]
    world.run(0.25)
    scan = laser.reading
    for angle, distance in {0: 1.45, 90: 1.95, 180: 2.45}.items():
        k = int(np.argmin(np.abs(np.degrees(scan.angles) - angle)))
        assert scan.ranges[k] == pytest.approx(distance, abs=0.005)


def test_arm_on_base_scene_drives_and_moves():
    world = load_scene(SCENES / "arm_on_base.toml")
    drive = world.service("DriveService", "base")
    arm = world.service("ArmService", "base/arm")
    world.run(0.3)
    start = world.body("base").xpos.copy()
    drive.drive_distance(0.3, power=0.5)
    arm.move_to([0.4, 0.2, 0.5, -0.3, 0.1, 0.01], duration=1.5)
    assert world.run_until(lambda: not drive.busy and not arm.busy, timeout=20)
    world.run(0.5)
    assert np.linalg.norm(world.body("base").xpos - start) == pytest.approx(0.3, abs=0.02)
    np.testing.assert_allclose(arm.joint_states().positions, [0.4, 0.2, 0.5, -0.3, 0.1, 0.01], atol=0.01)


def test_sensor_specs_are_checked(tmp_path):
    from simrun import SceneError

    path = tmp_path / "s.toml"
    base = (SCENES / "pioneer_room.toml").read_text()
    path.write_text(base.replace('type = "LaserRangeFinder"', 'type = "Lidar"'))
    with pytest.raises(SceneError, match=r"sensors\[0\]: unknown sensor type 'Lidar'"):
        load_scene(path)
    path.write_text(base.replace("rays = 360", "rays = 360\nbeams = 3"))
    with pytest.raises(SceneError, match=r"sensors\[0\]: sensor 'laser': .*beams"):
        load_scene(path)


def test_robot_with_a_visual_mesh_keeps_its_mass_and_drives():
    world = World(base_dir=SCENES)
    world.insert(Ground(name="ground"))
    world.insert(BoeBot(name="bot", visual_mesh="head.mbin", visual_offset=(0.0, 0.0, 0.105), pose=Pose((0, 0, 0.001))))
    drive = DriveService(world, "bot")
    model = world.model
    visual = model.geom("bot/visual0")
    assert (visual.group[0], visual.contype[0], visual.conaffinity[0]) == (2, 0, 0)
    assert model.body_subtreemass[model.body("bot").id] == pytest.approx(0.454 + 0.02 + 0.001)
    world.run(0.3)
    drive.drive_distance(0.3, power=0.5)
    assert world.run_until(lambda: not drive.busy, timeout=20)
