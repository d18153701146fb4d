"""Drive stack: differential-drive robots, the drive service and sensors, in real MuJoCo worlds.

Ground truth is the simulator's body poses (``data.xpos`` / ``data.xquat``) and the published numbers the
robots are built from, never the drive service's own estimates.
"""

import dataclasses
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from simrun import Box, EntityError, Ground, Pose, World, load_scene
from simrun.robots.catalogue import BoeBot, IRobotCreate, LegoNxtTribot, Pioneer3DX
from simrun.robots.diff_drive import DifferentialDrive
from simrun.sensors.laser import LaserRangeFinder
from simrun.sensors.robot_state import GPS, IMU, Bumper, Encoders
from simrun.services.drive_service import DriveLimits, DriveService, Odometry

SCENES = Path(__file__).resolve().parent.parent / "fixtures" / "scenes"


def custom(name="r", pose=None):
    """A user-built robot unlike the ready ones: 3 kg, 0.05 m wheels, a 2 N m / 10 rad/s motor."""
    return DifferentialDrive(
        name=name,
        pose=pose or Pose(),
        mass=2.8,
        chassis_dimensions=(0.3, 0.2, 0.1),
        chassis_clearance=0.02,
        wheel_radius=0.05,
        wheel_width=0.03,
        wheel_mass=0.1,
        track=0.26,
        axle_offset=0.05,
        caster_radius=0.025,
        caster_offset=None,
        stall_torque=2.0,
        no_load_speed=10.0,
    )


# Published full-power speed of each robot, m/s (docs/robots.md names the sources): Parallax servo 50 rpm on the
# seed's 0.025 m wheels, Pioneer 3-DX 1.2 m/s, Create 500 mm/s, NXT motor 170 rpm on 0.028 m wheels.
PUBLISHED_TOP_SPEED = {
    "BoeBot": 50 * 2 * math.pi / 60 * 0.025,
    "Pioneer3DX": 1.2,
    "IRobotCreate": 0.5,
    "LegoNxtTribot": 170 * 2 * math.pi / 60 * 0.028,
    "DifferentialDrive": 10.0 * 0.05,
}
ROBOTS = [BoeBot, Pioneer3DX, IRobotCreate, LegoNxtTribot, custom]
IDS = ["BoeBot", "Pioneer3DX", "IRobotCreate", "LegoNxtTribot", "custom"]


def make(robot, settle=0.3, name="r"):
    world = World()
    world.insert(Ground(name="ground"))
    entity = world.insert(robot(name=name, pose=Pose((0, 0, 0.001))))
    drive = DriveService(world, name)
    world.run(settle)
    return world, drive, entity


def heading(world, name):
    q = world.body(name).xquat
    return math.degrees(2 * math.atan2(q[3], q[0]))


def boebot_world():
    world, drive, _ = make(BoeBot, name="bot")
    return world, drive


@pytest.mark.parametrize("robot", ROBOTS, ids=IDS)
def test_robots_stand_still_with_their_published_mass(robot):
    world = World()
    world.insert(Ground(name="ground"))
    entity = world.insert(robot(name="r", pose=Pose((0, 0, 0.001))))
    world.run(1.0)
    assert world.warnings() == {}
    assert abs(world.body("r").xpos[2]) < 2e-3 and np.abs(world.body("r").cvel).max() < 1e-2
    total = world.model.body_subtreemass[world.model.body("r").id]
    casters = 1 if entity.second_caster_offset is None else 2
    assert total == pytest.approx(entity.mass + 2 * entity.wheel_mass + casters * entity.caster_mass)
    published = {"Pioneer3DX": 9.0, "IRobotCreate": 2.2, "LegoNxtTribot": 0.6, "BoeBot": 0.454 + 0.02 + 0.001}
    if entity.TYPE in published:
        assert total == pytest.approx(published[entity.TYPE], abs=1e-9)


@pytest.mark.parametrize("robot", ROBOTS, ids=IDS)
def test_full_power_reaches_the_published_top_speed_and_no_more(robot):
    world, drive, entity = make(robot)
    drive.set_drive_power(1.0, 1.0)
    world.run(2.0)
    x1 = world.body("r").xpos.copy()
    world.run(1.0)
    x2 = world.body("r").xpos.copy()
    world.run(1.0)
    x3 = world.body("r").xpos.copy()
    speed, later = np.linalg.norm((x2 - x1)[:2]), np.linalg.norm((x3 - x2)[:2])
    assert speed == pytest.approx(PUBLISHED_TOP_SPEED[entity.TYPE], rel=0.10)
    assert later == pytest.approx(speed, rel=0.01)  # a top speed: no longer accelerating
    assert abs(x3[1]) < 0.01 * x3[0]  # straight
    drive.set_drive_power(0.5, 0.5)
    world.run(2.0)
    x4 = world.body("r").xpos.copy()
    world.run(1.0)
    half = np.linalg.norm((world.body("r").xpos - x4)[:2])
    assert half == pytest.approx(speed / 2, rel=0.1)  # power is the motor's voltage fraction


@pytest.mark.parametrize("robot", ROBOTS, ids=IDS)
@pytest.mark.parametrize("settle", [0.3, 0.0], ids=["settled", "at_t0"])
def test_drive_one_metre_within_two_centimetres_and_odometry_agrees(robot, settle):
    world, drive, _ = make(robot, settle)
    start = world.body("r").xpos.copy()
    drive.drive_distance(1.0, power=0.6)
    assert drive.busy
    assert world.run_until(lambda: not drive.busy, timeout=30)
    world.run(0.5)
    travelled = world.body("r").xpos - start
    assert np.linalg.norm(travelled[:2]) == pytest.approx(1.0, abs=0.02)
    assert travelled[0] > 0.98 and abs(travelled[1]) < 0.005  # forward and straight
    odometry = drive.odometry()
    assert math.hypot(odometry.x - travelled[0], odometry.y - travelled[1]) < 0.02


@pytest.mark.parametrize("robot", ROBOTS, ids=IDS)
def test_short_drive_at_t0_behaves_as_after_settling(robot):
    results = []
    for settle in (0.0, 0.5):
        world, drive, _ = make(robot, settle)
        start = world.body("r").xpos.copy()
        drive.drive_distance(0.2, power=0.5)
        assert world.run_until(lambda d=drive: not d.busy, timeout=20)
        world.run(0.3)
        results.append(np.linalg.norm((world.body("r").xpos - start)[:2]))
    assert results[0] == pytest.approx(0.2, abs=0.01) and results[1] == pytest.approx(0.2, abs=0.01)
    assert abs(results[0] - results[1]) < 0.005


@pytest.mark.parametrize("robot", ROBOTS, ids=IDS)
@pytest.mark.parametrize("degrees", [90.0, -90.0])
def test_rotate_ninety_degrees_within_two_about_the_body_origin(robot, degrees):
    world, drive, _ = make(robot)
    before, start = heading(world, "r"), world.body("r").xpos.copy()
    drive.rotate_degrees(degrees, power=0.5)
    assert world.run_until(lambda: not drive.busy, timeout=20)
    world.run(0.5)
    assert abs((heading(world, "r") - before) - degrees) < 2.0
    # the body origin is the axle midpoint (docs/robots.md): a turn in place leaves it where it was
    assert np.linalg.norm((world.body("r").xpos - start)[:2]) < 0.01
    odometry = drive.odometry()
    assert math.degrees(odometry.theta) == pytest.approx(degrees, abs=2.0)
    assert math.hypot(odometry.x, odometry.y) < 0.01


@pytest.mark.parametrize("robot", ROBOTS, ids=IDS)
def test_cmd_vel_arc_matches_its_radius(robot):
    world, drive, entity = make(robot)
    speed = 0.4 * min(entity.top_speed, 0.5)
    radius = max(0.2, 1.5 * entity.separation)
    points = []
    for k in range(4000):
        if k % 50 == 0:
            drive.cmd_vel(speed, speed / radius)
        world.step()
        if k > 1500 and k % 10 == 0:
            points.append(world.body("r").xpos[:2].copy())
    p = np.array(points)
    a = np.c_[2 * p, np.ones(len(p))]
    cx, cy, c = np.linalg.lstsq(a, (p**2).sum(axis=1), rcond=None)[0]
    assert math.sqrt(c + cx * cx + cy * cy) == pytest.approx(radius, rel=0.05)
    assert cy > 0  # a positive turn rate curves left (+Y)


@pytest.mark.parametrize("robot", ROBOTS, ids=IDS)
def test_the_service_moves_the_robot_only_through_its_actuators(robot):
    """Replaying the controls the service wrote, with bare mj_step, gives bit-identical motion."""
    world, drive, _ = make(robot, settle=0.0)
    model, data = world.model, world.data
    initial = (data.qpos.copy(), data.qvel.copy())
    controls = []
    drive.cmd_vel(0.1, 0.5)
    for _ in range(300):
        world.step()
        controls.append(data.ctrl.copy())
    replay = mujoco.MjData(model)
    replay.qpos[:], replay.qvel[:] = initial
    mujoco.mj_forward(model, replay)
    for ctrl in controls:
        replay.ctrl[:] = ctrl  # the controls were in place for the step just taken
        mujoco.mj_step(model, replay)
    assert np.linalg.norm(data.qpos[:3] - initial[0][:3]) > 0.005  # it did move
    np.testing.assert_array_equal(replay.qpos, data.qpos)
    np.testing.assert_array_equal(replay.qvel, data.qvel)


@pytest.mark.parametrize("call", ["set_drive_power", "drive_speed", "drive_distance", "rotate_degrees", "cmd_vel"])
@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_commands_are_refused_and_nothing_moves(call, bad):
    world, drive = boebot_world()
    start = world.body("bot").xpos.copy()
    with pytest.raises(EntityError, match=f"^{call}: .* must be a finite number"):
        getattr(drive, call)(bad, 0.5) if call != "drive_distance" else drive.drive_distance(bad)
    if call in ("drive_distance", "rotate_degrees"):
        with pytest.raises(EntityError, match="power"):
            getattr(drive, call)(0.1, bad)
    world.run(0.5)
    assert np.linalg.norm(world.body("bot").xpos - start) < 1e-4 and not drive.busy


@pytest.mark.parametrize(
    "params",
    [
        {"mass": 0.15, "wheel_radius": 0.02, "stall_torque": 0.05, "no_load_speed": 30.0},  # light, fast motor
        {"mass": 0.15, "wheel_radius": 0.02, "stall_torque": 0.08, "no_load_speed": 3.0},  # light, stiff servo
        {"mass": 20.0, "wheel_radius": 0.15, "stall_torque": 40.0, "no_load_speed": 10.0},  # heavy
        {"mass": 20.0, "wheel_radius": 0.15, "stall_torque": 5.0, "no_load_speed": 3.0},  # heavy, weak motor
    ],
    ids=["light-fast", "light-stiff", "heavy", "heavy-weak"],
)
def test_custom_robots_across_the_documented_range_hold_a_speed(params):
    size = 4 * params["wheel_radius"]
    robot = DifferentialDrive(
        name="r",
        pose=Pose((0, 0, 0.001)),
        chassis_dimensions=(2.5 * size, size, size / 2),
        chassis_clearance=params["wheel_radius"] / 3,
        caster_radius=params["wheel_radius"] / 2,
        caster_offset=None,
        wheel_width=params["wheel_radius"] / 2,
        wheel_mass=params["mass"] / 40,
        **params,
    )
    world = World()
    world.insert(Ground(name="ground"))
    world.insert(robot)
    drive = DriveService(world, "r")
    target = 0.5 * robot.top_speed
    drive.drive_speed(target, target)
    world.run(3.0)
    speeds = []
    for _ in range(50):
        before = world.body("r").xpos.copy()
        world.run(0.02)
        speeds.append(np.linalg.norm((world.body("r").xpos - before)[:2]) / 0.02)
    assert np.mean(speeds) == pytest.approx(target, rel=0.03)
    assert np.std(speeds) < 0.02 * target  # steady: no limit cycle
    assert world.warnings() == {}


def test_boebot_has_the_seed_articles_dimensions():
    world = World()
    world.insert(BoeBot(name="b"))
    model = world.model
    left, right = (model.body(f"b/{side}_wheel").pos for side in ("left", "right"))
    caster, chassis = model.geom("b/caster").pos, model.geom("b/chassis")
    assert left[1] - right[1] == pytest.approx(0.090)  # wheels at +-X/2 of the 0.09 m chassis
    assert model.geom("b/left_tyre").size[1] == pytest.approx(0.010 / 2)  # wheel width 0.010
    assert left[0] - chassis.pos[0] == pytest.approx(0.02)  # axle 0.02 ahead of the chassis centre
    assert left[0] - caster[0] == pytest.approx(0.055)  # axle to caster
    assert chassis.pos[2] - chassis.size[2] == pytest.approx(0.015)  # clearance
    np.testing.assert_allclose(2 * chassis.size, [0.13, 0.09, 0.09])
    assert (left[0], left[2]) == pytest.approx((0.0, 0.025))  # body origin: axle midpoint on the ground
    assert model.geom("b/caster").size[0] == pytest.approx(0.0125)
    assert model.body_mass[model.body("b/left_wheel").id] == pytest.approx(0.01)
    assert BoeBot(name="x", motor_torque_scaling=30).top_speed == pytest.approx(30 * 0.025)  # the seed's MSRS speed


def test_published_dimensions_of_the_other_robots():
    world = World()
    world.insert(Pioneer3DX(name="p"))
    world.insert(IRobotCreate(name="c", pose=Pose((2, 0, 0))))
    world.insert(LegoNxtTribot(name="t", pose=Pose((4, 0, 0))))
    model = world.model
    tyre = model.geom("p/left_tyre").size
    outer = model.body("p/left_wheel").pos[1] - model.body("p/right_wheel").pos[1] + 2 * tyre[1]
    assert outer == pytest.approx(0.381)  # Adept: 381 mm wide over the wheels
    assert 2 * tyre[0] == pytest.approx(0.195)
    disc = model.geom("c/chassis")
    assert disc.type[0] == mujoco.mjtGeom.mjGEOM_CYLINDER and 2 * disc.size[0] == pytest.approx(0.33)
    assert 2 * disc.size[1] == pytest.approx(0.06) and disc.pos[2] == pytest.approx(0.012 + 0.03)
    np.testing.assert_allclose(model.site("c/centre").pos, disc.pos)  # a site at the chassis centre
    np.testing.assert_allclose(model.geom("c/caster").rgba, [0.3, 0.3, 0.3, 1.0])  # a grey caster
    assert model.body("c/left_wheel").pos[1] * 2 == pytest.approx(0.258)
    assert model.geom("t/left_tyre").size[0] == pytest.approx(0.028)
    bad = World()
    bad.insert(IRobotCreate(name="x", chassis_dimensions=(0.3, 0.2, 0.05)))
    with pytest.raises(EntityError, match="disc chassis needs length == width"):
        bad.compile()


def test_speed_loop_gains_come_from_the_motor_and_inertia():
    designs = {}
    for robot in (BoeBot, Pioneer3DX):
        _, drive, _ = make(robot, settle=0.0)
        designs[robot.TYPE] = drive.speed_loop()
    # the Pioneer's motor is slow under its 9 kg (a 0.09 s time constant): it needs a proportional term;
    # the Boe-Bot's servo is faster than the 20 ms control period: the integral alone
    assert designs["Pioneer3DX"]["time_constant"] == pytest.approx(0.09, rel=0.1)
    assert designs["Pioneer3DX"]["gain"] > 0 and designs["BoeBot"]["gain"] == 0
    assert designs["BoeBot"]["integral_gain"] != designs["Pioneer3DX"]["integral_gain"]


def test_cmd_vel_limits_and_timeout():
    world, drive, _ = make(Pioneer3DX)
    drive.limits = DriveLimits(max_linear=0.2, command_timeout=0.5)
    drive.cmd_vel(5.0, 0.0)  # far above the limit
    world.run(0.4)  # 0.2 m/s reached at 0.3 m/s^2 after 0.67 s
    moved = world.body("r").xpos[0]
    assert moved == pytest.approx(0.5 * 0.3 * 0.4**2, abs=0.006)  # the acceleration limit
    drive.cmd_vel(5.0, 0.0)
    world.run(0.4)
    before = world.body("r").xpos.copy()
    world.run(0.1)
    assert (world.body("r").xpos[0] - before[0]) / 0.1 == pytest.approx(0.2, abs=0.02)
    world.run(2.0)  # no new command: it stops
    before = world.body("r").xpos.copy()
    world.run(0.1)
    assert abs(world.body("r").xpos[0] - before[0]) < 1e-3


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
    front = world.body("bot").xpos[0] - 0.02 + 0.065  # the axle (origin) is 0.02 ahead of the chassis centre
    assert 0.35 - 0.01 < front < 0.35 + 0.002  # stopped at the wall's face
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


def test_a_low_laser_does_not_see_its_own_wheels_or_mounted_arm():
    from simrun.robots.arm import LynxL6

    world = World()
    world.insert(Ground(name="ground"))
    world.insert(BoeBot(name="bot", pose=Pose((0, 0, 0.001))))
    world.insert(Pioneer3DX(name="p3dx", pose=Pose((3, 0, 0.001))))
    world.insert(LynxL6(name="arm", parent="p3dx", pose=Pose((0.1, 0, 0.237))))
    low = LaserRangeFinder(world, "bot", height=0.03, fov_deg=360, rays=360, max_range=2.0)
    own = LaserRangeFinder(world, "bot", height=0.03, fov_deg=360, rays=360, max_range=2.0, exclude="body")
    arm_level = LaserRangeFinder(world, "p3dx", height=0.3, fov_deg=360, rays=360, max_range=2.0)
    world.step(1)
    assert np.all(low.reading.ranges == 2.0)  # 360 rays at 3 cm: nothing of its own robot
    assert np.sum(own.reading.ranges < 0.06) > 20  # only the body excluded: the wheels are in the way
    assert np.all(arm_level.reading.ranges == 2.0)  # the Pioneer's laser does not see its arm
    with pytest.raises(EntityError, match="exclude must be one of"):
        LaserRangeFinder(world, "bot", exclude="wheels")


@pytest.mark.parametrize("robot", ROBOTS, ids=IDS)
@pytest.mark.parametrize("height", [0.01, 0.03, 0.05, 0.08])
def test_a_laser_inside_the_robot_sees_past_it_and_returns(robot, height):
    """Where two of the robot's bodies meet (wheel and chassis), a continued ray once bounced between them forever.

    Ground truth: the box's near face is at x = 0.5 m (centre 0.6, half size 0.1), the ray straight ahead starts
    at the simulator's body position plus ``height`` along the body's z axis.
    """
    world = World()
    world.insert(Ground(name="ground"))
    world.insert(robot(name="r", pose=Pose((0, 0, 0.001))))
    world.insert(Box(name="box", dimensions=(0.2, 0.2, 0.4), pose=Pose((0.6, 0, 0.2))))
    laser = LaserRangeFinder(world, "r", height=height, fov_deg=360, rays=36, max_range=3.0)
    world.step(1)
    body = world.body("r")
    origin = body.xpos + body.xmat.reshape(3, 3)[:, 2] * height
    ahead = int(np.argmin(np.abs(laser.angles)))
    assert laser.reading.ranges[ahead] == pytest.approx(0.5 - origin[0], abs=1e-6)
    assert np.all(laser.reading.ranges[np.abs(laser.angles) > 1.0] == 3.0)  # nothing else within 3 m


def test_a_ray_leaving_the_chassis_where_a_wheel_begins_is_continued_through_the_wheel():
    """Wheels whose inner faces lie on the chassis sides (track = chassis width + wheel width): the sideways ray at
    axle height leaves the chassis exactly where the wheel starts, a zero-length step that only the 1 um nudge
    gets past. Ground truth: the wall's near face at y = 1 m, the ray from the simulator's body position."""
    world = World()
    world.insert(Ground(name="ground"))
    robot = custom(pose=Pose((0, 0, 0.001)))  # a 0.2 m wide chassis, 0.03 m wide wheels
    robot = dataclasses.replace(robot, track=robot.chassis_dimensions[1] + robot.wheel_width)
    world.insert(robot)
    world.insert(Box(name="wall", dimensions=(4.0, 0.1, 1.0), pose=Pose((0, 1.05, 0.5))))
    axle = world.body("r/left_wheel").xpos[2] - world.body("r").xpos[2]
    laser = LaserRangeFinder(world, "r", height=axle, fov_deg=360, rays=4, max_range=3.0, rate=0)
    world.step(1)
    left = int(np.argmin(np.abs(laser.angles - math.pi / 2)))
    assert laser.reading.ranges[left] == pytest.approx(1.0 - world.body("r").xpos[1], abs=1e-5)


def test_a_ray_still_inside_the_robot_after_the_continuation_cap_sees_nothing(monkeypatch):
    """With no continuation allowed, every ray that meets its own robot first reports nothing (max range)."""
    import simrun.sensors.base

    world = World()
    world.insert(Ground(name="ground"))
    world.insert(BoeBot(name="r", pose=Pose((0, 0, 0.001))))
    world.insert(Box(name="box", dimensions=(0.2, 0.2, 0.4), pose=Pose((0.6, 0, 0.2))))
    laser = LaserRangeFinder(world, "r", height=0.01, fov_deg=360, rays=36, max_range=3.0, exclude="robot")
    wheels = LaserRangeFinder(world, "r", height=0.01, fov_deg=360, rays=36, max_range=3.0, exclude="body")
    world.step(1)
    assert (wheels.reading.ranges < 0.1).sum() >= 4  # at this height the wheels are in the way of some rays
    assert laser.reading.ranges.min() > 0.1  # continued past the robot: the box at 0.5 m at the nearest
    monkeypatch.setattr(simrun.sensors.base, "MAX_CONTINUATIONS", 0)
    world.run(0.1)  # the next scan (10 Hz)
    assert laser.samples == 2
    assert laser.reading.ranges.min() > 0.1  # no continuation: those rays see nothing, never the robot itself


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
    from simrun.cli.main import main

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
    with pytest.raises(SceneError, match=r"sensors\[0\].*: unknown sensor type 'Lidar'"):
        load_scene(path)
    path.write_text(base.replace("rays = 360", "rays = 360\nbeams = 3"))
    with pytest.raises(SceneError, match=r"sensors\[0\].*: sensor 'laser': .*beams"):
        load_scene(path)


def test_robot_with_a_visual_mesh_keeps_its_mass_and_drives():
    world = World(base_dir=SCENES)
    world.insert(Ground(name="ground"))
    world.insert(BoeBot(name="bot", visual_mesh="head.mbin", visual_offset=(0.0, 0.0, 0.105), pose=Pose((0, 0, 0.001))))
    drive = DriveService(world, "bot")
    model = world.model
    visual = model.geom("bot/visual0")
    assert (visual.group[0], visual.contype[0], visual.conaffinity[0]) == (2, 0, 0)
    assert visual.type[0] == mujoco.mjtGeom.mjGEOM_MESH
    vertices = model.mesh_vert[model.mesh_vertadr[visual.dataid[0]] :][: model.mesh_vertnum[visual.dataid[0]]]
    extent = vertices.max(axis=0) - vertices.min(axis=0)
    np.testing.assert_allclose(sorted(extent), [0.16, 0.2, 0.24], atol=1e-3)  # the packed head at scale 1
    # MuJoCo centres a mesh on its geom: the head (its base at its origin) stands on the 0.105 m offset
    assert visual.pos[2] + vertices[:, 2].min() == pytest.approx(0.105, abs=1e-3)
    assert model.body_subtreemass[model.body("bot").id] == pytest.approx(0.454 + 0.02 + 0.001)
    world.run(0.3)
    drive.drive_distance(0.3, power=0.5)
    assert world.run_until(lambda: not drive.busy, timeout=20)
    named = World(base_dir=SCENES)
    named.assets["head"] = "head.mbin"  # a scene's [assets] name
    named.insert(BoeBot(name="bot", visual_mesh="head"))
    assert named.model.geom("bot/visual0").type[0] == mujoco.mjtGeom.mjGEOM_MESH


def test_default_caster_sits_at_the_chassis_end_away_from_the_axle():
    world = World()
    world.insert(Pioneer3DX(name="p"))  # axle 0.05 ahead of the 0.455 m chassis' centre: caster at the rear
    world.insert(
        DifferentialDrive(name="front", axle_offset=-0.03, caster_offset=None, pose=Pose((2, 0, 0)))
    )  # axle behind the centre: caster in front
    model = world.model
    assert model.geom("p/caster").pos[0] == pytest.approx(-0.05 - (0.455 / 2 - 0.038))
    assert model.geom("front/caster").pos[0] == pytest.approx(0.03 + (0.13 / 2 - 0.0125))
    assert model.geom("front/caster").pos[2] == pytest.approx(0.0125)  # on the ground
    assert model.geom("front/chassis").pos[0] == pytest.approx(0.03)  # the chassis centre, from the axle


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"mass": -1.0}, "mass must be a positive number"),
        ({"mass": math.nan}, "mass must be a positive number"),
        ({"chassis_dimensions": (0.0, 0.09, 0.09)}, "length must be"),
        ({"chassis_dimensions": (0.13, -0.09, 0.09)}, "width must be"),
        ({"chassis_dimensions": (0.13, 0.09, 0.0)}, "height must be"),
        ({"wheel_radius": 0.0}, "wheel_radius must be"),
        ({"wheel_width": -0.01}, "wheel_width must be"),
        ({"wheel_mass": 0.0}, "wheel_mass must be"),
        ({"track": 0.0}, "track must be"),
        ({"caster_radius": 0.0}, "caster_radius must be"),
        ({"caster_mass": -0.001}, "caster_mass must be"),
        ({"stall_torque": 0.0}, "stall_torque must be"),
        ({"no_load_speed": math.inf}, "no_load_speed must be"),
        ({"motor_torque_scaling": -30.0}, "motor_torque_scaling must be"),
        ({"wheel_friction": 0.0}, "wheel_friction must be"),
        ({"chassis_shape": "triangle"}, "chassis_shape must be one of box, disc"),
        ({"chassis_shape": "disc"}, "a disc chassis needs length == width"),
        ({"axle_offset": 0.065}, r"axle_offset must lie within the chassis length \(\|offset\| < 0.065\)"),
        ({"axle_offset": -0.07}, "axle_offset must lie within the chassis length"),
        ({"axle_offset": math.nan}, "axle_offset must lie within"),
        ({"chassis_clearance": -0.001}, "chassis_clearance must be >= 0"),
        ({"caster_offset": 0.01}, "caster_offset must put the caster away from the axle"),
        ({"caster_offset": -0.0125}, "caster_offset must put the caster away from the axle"),  # at the axle's edge
        ({"caster_offset": math.nan}, "caster_offset must put"),
        ({"track": 0.01}, "the track must be wider than a wheel"),
    ],
)
def test_bad_robot_parameters_are_refused_naming_the_parameter(change, message):
    world = World()
    world.insert(DifferentialDrive(name="bad", **change))
    with pytest.raises(EntityError, match=f"DifferentialDrive 'bad': {message}"):
        world.compile()


def test_good_edge_parameters_build():
    world = World()
    world.insert(
        DifferentialDrive(name="a", chassis_clearance=0.0, axle_offset=0.064, caster_offset=-(0.0125 + 1e-6))
    )  # the caster just clear of the axle
    world.insert(DifferentialDrive(name="b", track=0.0101, pose=Pose((1, 0, 0))))
    world.insert(
        DifferentialDrive(name="c", chassis_shape="disc", chassis_dimensions=(0.2, 0.2, 0.05), pose=Pose((2, 0, 0)))
    )
    world.compile()
    assert world.model.geom("c/chassis").size[0] == pytest.approx(0.1)


@pytest.mark.parametrize("robot", ROBOTS, ids=IDS)
def test_motor_actuators_are_the_published_dc_motor(robot):
    world = World()
    entity = world.insert(robot(name="r"))
    model = world.model
    for side in ("left", "right"):
        motor = model.actuator(f"r/{side}_motor")
        assert motor.gainprm[0] == pytest.approx(entity.stall_torque)
        assert motor.biasprm[2] == pytest.approx(-entity.stall_torque / entity.no_load_speed)
        np.testing.assert_allclose(motor.ctrlrange, [-1, 1])
        np.testing.assert_allclose(motor.forcerange, [-entity.stall_torque, entity.stall_torque])
        assert motor.ctrllimited[0] and motor.forcelimited[0]
        tyre = model.geom(f"r/{side}_tyre")
        assert tyre.friction[0] == pytest.approx(entity.wheel_friction)
    left, right = (model.body(f"r/{side}_wheel").pos for side in ("left", "right"))
    assert left[1] == pytest.approx(entity.separation / 2) and right[1] == pytest.approx(-entity.separation / 2)
    assert model.geom("r/caster").friction[0] == 0.0 and model.geom("r/caster").condim[0] == 1


# -- sensors: frames, rates, noise and state, against simulator poses -------------------------------------------


def test_sensor_rates_and_noise_are_validated():
    world, _ = boebot_world()
    with pytest.raises(EntityError, match="rate and noise must be >= 0"):
        GPS(world, "bot", rate=-1.0)
    with pytest.raises(EntityError, match="rate and noise must be >= 0"):
        Encoders(world, "bot", noise=-0.1)
    with pytest.raises(EntityError, match="no entity named 'ghost'"):
        IMU(world, "ghost")
    for bad in ({"rays": 0}, {"max_range": 0.0}, {"fov_deg": 0.0}, {"fov_deg": 361.0}):
        with pytest.raises(EntityError, match="laser: rays >= 1, max_range > 0, 0 < fov <= 360"):
            LaserRangeFinder(world, "bot", **bad)


def test_sensor_noise_reseed_snapshot_restore_and_reset():
    world, _ = boebot_world()
    gps = GPS(world, "bot", rate=0, noise=0.1, seed=5)
    world.step(1)
    first = gps.reading.position
    state = gps.snapshot()
    world.step(1)
    after = gps.reading.position
    gps.restore(state)
    world.step(1)
    assert gps.reading.position != first and gps.samples == state["samples"] + 1
    np.testing.assert_allclose(gps.reading.position, after, atol=1e-4)  # same noise draws again
    gps.reseed(5)
    other = GPS(world, "bot", rate=0, noise=0.1, seed=5)
    world.step(1)
    np.testing.assert_array_equal(gps.reading.position, other.reading.position)
    truth = world.body("bot").xpos
    assert 0.01 < np.abs(np.array(gps.reading.position) - truth).max() < 0.5  # noisy around the truth
    world.reset()
    assert gps.reading is None and gps.samples == 0


def test_sensors_sample_at_their_rate_on_the_simulation_clock():
    world, _ = boebot_world()
    start = world.time
    imu, enc = IMU(world, "bot", rate=100.0), Encoders(world, "bot", rate=25.0)
    every = GPS(world, "bot", rate=0.0)
    world.run(1.0)
    assert imu.samples == 100 and enc.samples == 25 and every.samples == 500
    assert imu.reading.time == pytest.approx(start + 0.99, abs=0.003)


def test_gps_latitude_longitude_from_the_body_position():
    world = World()
    world.insert(Ground(name="ground"))
    world.insert(BoeBot(name="bot", pose=Pose((1.0, 2.0, 0.001))))
    gps = GPS(world, "bot", rate=0, origin=(47.6, -122.3))  # every step: the reading is of the current pose
    plain = GPS(world, "bot", rate=10)
    world.run(0.5)
    x, y, _ = world.body("bot").xpos
    reading = gps.reading
    np.testing.assert_allclose(reading.position, world.body("bot").xpos, atol=1e-6)
    metres_per_degree = 111_319.490793  # WGS84 equatorial radius 6378137 m: 2 pi R / 360
    assert reading.latitude - 47.6 == pytest.approx(y / metres_per_degree, rel=1e-6)  # north = +Y
    assert reading.longitude + 122.3 == pytest.approx(x / (metres_per_degree * math.cos(math.radians(47.6))), rel=1e-6)
    assert plain.reading.latitude is None and plain.reading.longitude is None


def test_imu_reads_in_the_body_frame():
    world = World()
    world.insert(Ground(name="ground"))
    tilted = (math.cos(math.pi / 4), math.sin(math.pi / 4), 0.0, 0.0)  # 90 degrees about +X: body +Y is world up
    world.insert(Box(name="brick", dimensions=(0.2, 0.1, 0.1), free=True, pose=Pose((0, 0, 0.1), tilted)))
    imu = IMU(world, "brick")
    world.run(0.5)
    np.testing.assert_allclose(imu.reading.accelerometer, [0.0, 9.81, 0.0], atol=0.05)
    np.testing.assert_allclose(imu.reading.orientation, world.body("brick").xquat, atol=1e-9)
    # turning in place: the gyro's z is the yaw rate of the simulator's body pose
    world, drive, _ = make(Pioneer3DX)
    imu = IMU(world, "r", rate=0)
    drive.drive_speed(-0.2, 0.2)
    world.run(2.0)
    before = heading(world, "r")
    world.run(0.1)
    rate = math.radians(heading(world, "r") - before) / 0.1
    assert imu.reading.gyro[2] == pytest.approx(rate, rel=0.02)
    assert rate == pytest.approx(0.4 / 0.3335, rel=0.03)  # wheel speeds over the track
    assert abs(imu.reading.gyro[0]) < 0.05 and abs(imu.reading.gyro[1]) < 0.05


def test_encoders_read_the_wheel_angles_of_the_distance_driven():
    world, drive, _ = make(BoeBot)
    enc = Encoders(world, "r", rate=50)
    start, angles = world.body("r").xpos.copy(), None
    world.step(1)
    angles = np.array(enc.reading.angles)
    drive.drive_speed(0.1, 0.05)
    world.run(2.0)
    turned = np.array(enc.reading.angles) - angles
    assert turned[0] > 0 and turned[1] > 0 and turned[0] == pytest.approx(2 * turned[1], rel=0.05)
    assert enc.reading.velocities[0] == pytest.approx(0.1 / 0.025, rel=0.03)
    drive.drive_speed(0.1, 0.1)
    world.run(0.5)
    a0, x0 = np.array(enc.reading.angles), world.body("r").xpos.copy()
    world.run(1.0)
    travelled = np.linalg.norm((world.body("r").xpos - x0)[:2])
    assert np.mean(np.array(enc.reading.angles) - a0) * 0.025 == pytest.approx(travelled, rel=0.02)
    noisy = Encoders(world, "r", noise=0.01, seed=1, joints=("left_wheel",))
    world.step(1)
    assert len(noisy.reading.angles) == 1 and noisy.reading.angles[0] != enc.reading.angles[0]
    del start


def test_laser_angles_noise_and_points():
    world = World()
    world.insert(Ground(name="ground"))
    world.insert(Box(name="wall", dimensions=(0.1, 4.0, 1.0), pose=Pose((2.05, 0, 0.5))))
    world.insert(Pioneer3DX(name="p", pose=Pose((0, 0, 0.001))))
    laser = LaserRangeFinder(world, "p", height=0.3, fov_deg=90, rays=7, max_range=5.0, points=True)
    noisy = LaserRangeFinder(world, "p", fov_deg=90, rays=7, max_range=5.0, noise=0.05, seed=2)
    world.step(1)
    np.testing.assert_allclose(np.degrees(laser.angles), np.linspace(-45, 45, 7))
    scan = laser.reading
    np.testing.assert_allclose(scan.ranges, 2.0 / np.cos(laser.angles), rtol=1e-3)  # a flat wall 2 m ahead
    np.testing.assert_allclose(scan.points[:, 0], 2.0, atol=1e-3)
    np.testing.assert_allclose(scan.points[:, 2], 0.3 + world.body("p").xpos[2], atol=1e-6)
    assert 0 < np.abs(noisy.reading.ranges - scan.ranges).max() < 0.25
    back = LaserRangeFinder(world, "p", fov_deg=360, rays=4, max_range=5.0, points=True)
    world.step(1)
    np.testing.assert_allclose(np.degrees(back.angles), [-180, -90, 0, 90])
    assert back.reading.ranges[2] == pytest.approx(2.0, abs=1e-3)
    assert back.reading.ranges[0] == 5.0 and np.isnan(back.reading.points[0]).all()  # nothing behind


def test_bumper_reads_nothing_when_free_and_ignores_its_own_robot():
    world = World()
    world.insert(Ground(name="ground"))
    world.insert(BoeBot(name="bot", pose=Pose((0, 0, 0.001))))
    world.insert(Box(name="crate", dimensions=(0.2, 0.2, 0.2), free=True, pose=Pose((0.3, 0, 0.1))))
    bumper = Bumper(world, "bot")
    caster = Bumper(world, "bot", geom="caster")
    world.run(0.3)
    assert not bumper.reading.pressed and bumper.reading.touching == ()
    assert caster.reading.touching == ("ground/plane",)  # the floor is not its robot; its wheels are


# -- drive service details ----------------------------------------------------------------------------------


def test_backwards_and_clockwise_commands_go_the_other_way():
    world, drive, _ = make(LegoNxtTribot)
    start = world.body("r").xpos.copy()
    drive.drive_distance(-0.3, power=0.5)
    assert world.run_until(lambda: not drive.busy, timeout=20)
    world.run(0.3)
    assert world.body("r").xpos[0] - start[0] == pytest.approx(-0.3, abs=0.01)
    assert drive.odometry().x == pytest.approx(-0.3, abs=0.01)
    before = heading(world, "r")
    drive.rotate_degrees(-45, power=1.0)
    assert world.run_until(lambda: not drive.busy, timeout=20)
    world.run(0.3)
    assert heading(world, "r") - before == pytest.approx(-45, abs=1.0)
    left, right = drive.encoders()
    assert left - right == pytest.approx(math.radians(45) * 0.112, abs=0.003)  # the left wheel went forward


def test_power_sets_the_cruising_speed_of_a_distance():
    speeds = {}
    for power in (0.25, 1.0):
        world, drive, _ = make(LegoNxtTribot)
        drive.drive_distance(3.0, power=power)
        world.run(2.0)
        before = world.body("r").xpos[0]
        world.run(0.2)
        speeds[power] = (world.body("r").xpos[0] - before) / 0.2
    assert speeds[0.25] == pytest.approx(0.25 * 0.498, rel=0.05)
    assert speeds[1.0] == pytest.approx(0.5, rel=0.05)  # capped by limits.max_linear 0.5 m/s


def test_drive_speed_all_stop_and_wheel_speed_limits():
    world, drive, _ = make(IRobotCreate)
    drive.drive_speed(0.3, -0.1)
    world.run(3.0)
    enc = world.data
    left = enc.joint("r/left_wheel").qvel[0] * 0.036
    right = enc.joint("r/right_wheel").qvel[0] * 0.036
    assert (left, right) == pytest.approx((0.3, -0.1), abs=0.005)
    drive.all_stop()
    world.run(1.5)
    before = world.body("r").xpos.copy()
    world.run(0.1)
    assert np.linalg.norm(world.body("r").xpos - before) < 1e-4
    assert not drive.busy
    drive.drive_speed(2.0, 2.0)  # beyond the motor: full power
    world.run(2.0)
    assert world.data.ctrl[0] == 1.0 and world.data.ctrl[1] == 1.0


def test_enable_reset_and_snapshot_restore_continue_identically():
    world, drive, _ = make(BoeBot)
    drive.enable(False)
    assert not drive.enabled and not drive.busy
    for call, args in (("set_drive_power", (0.5, 0.5)), ("drive_speed", (0.1, 0.1)), ("cmd_vel", (0.1, 0.0))):
        with pytest.raises(EntityError, match="disabled"):
            getattr(drive, call)(*args)
    with pytest.raises(EntityError, match="disabled"):
        drive.rotate_degrees(90)
    drive.enable(True)
    drive.drive_distance(0.5, power=0.8)
    world.run(1.0)
    state = drive.snapshot()
    spec = mujoco.mjtState.mjSTATE_INTEGRATION
    physics = np.zeros(mujoco.mj_stateSize(world.model, spec))
    mujoco.mj_getState(world.model, world.data, physics, spec)
    next_time = drive.next_time
    world.run(1.0)
    expected = world.data.qpos.copy()
    mujoco.mj_setState(world.model, world.data, physics, spec)
    drive.restore(state)
    assert drive.next_time == next_time
    world.run(1.0)
    np.testing.assert_array_equal(world.data.qpos, expected)
    world.reset()
    assert not drive.busy and drive.encoders() == (0.0, 0.0)
    assert drive.odometry().x == 0.0 and world.time == 0.0


def test_odometry_twist_and_calibration_scales():
    world, drive, _ = make(Pioneer3DX)
    drive.drive_speed(0.3, 0.3)
    world.run(2.0)
    odometry = drive.odometry()
    assert odometry.linear == pytest.approx(0.3, rel=0.02) and abs(odometry.angular) < 0.01
    assert odometry.time == pytest.approx(world.time, abs=0.021)
    drive.reset_encoders()
    assert drive.odometry().x == 0.0 and drive.encoders() == (0.0, 0.0)
    world2, _, _ = make(Pioneer3DX)
    scaled = DriveService(world2, "r", radius_scale=1.1, separation_scale=0.5)
    assert scaled.radius == pytest.approx(0.0975 * 1.1) and scaled.separation == pytest.approx(0.3335 * 0.5)
    with pytest.raises(EntityError, match="rate must be a positive finite number"):
        DriveService(world2, "r", rate=0.0)
    with pytest.raises(EntityError, match="gain must be a finite number"):
        DriveService(world2, "r", gain=math.nan)
    fixed = DriveService(world2, "r", gain=0.3, integral_gain=2.0)
    world2.step(1)
    assert (fixed.gain, fixed.ki) == (0.3, 2.0)


def test_cmd_vel_angular_limit_and_turn_direction():
    world, drive, _ = make(Pioneer3DX)
    drive.limits = DriveLimits(max_angular=0.5, max_angular_accel=10.0)
    before = heading(world, "r")
    for _ in range(15):
        drive.cmd_vel(0.0, 5.0)  # far above the 0.5 rad/s limit, counter-clockwise
        world.run(0.1)
    turned = heading(world, "r") - before
    assert turned > 0 and math.radians(turned) == pytest.approx(0.5 * 1.5, rel=0.15)


def test_wheels_and_tyres_are_as_documented():
    """docs/robots.md: hinge wheels about +Y with bearing damping; stiff ellipsoid tyres, a cylinder drawn."""
    world = World()
    world.insert(BoeBot(name="b"))
    model = world.model
    for side in ("left", "right"):
        joint = model.joint(f"b/{side}_wheel")
        assert joint.type[0] == mujoco.mjtJoint.mjJNT_HINGE and tuple(joint.axis) == (0, 1, 0)
        assert model.dof_damping[joint.dofadr[0]] == pytest.approx(0.0001)
        tyre = model.geom(f"b/{side}_tyre")
        assert tyre.type[0] == mujoco.mjtGeom.mjGEOM_ELLIPSOID and tyre.group[0] == 3
        np.testing.assert_allclose(tyre.size, [0.025, 0.005, 0.025])
        np.testing.assert_allclose(tyre.friction, [1.2, 0.005, 0.0001])
        np.testing.assert_allclose(tyre.solref, [0.005, 1.0])
        np.testing.assert_allclose(tyre.solimp, [0.99, 0.999, 0.001, 0.5, 2.0])
        assert tyre.solmix[0] == 1000.0
        np.testing.assert_allclose(tyre.rgba, [0.1, 0.1, 0.1, 1.0])
        drawn = model.geom(f"b/{side}_wheel_visual")
        assert drawn.type[0] == mujoco.mjtGeom.mjGEOM_CYLINDER and (drawn.contype[0], drawn.conaffinity[0]) == (0, 0)
        np.testing.assert_allclose(drawn.size[:2], [0.025, 0.005])
        np.testing.assert_allclose(drawn.quat, [math.cos(math.pi / 4), math.sin(math.pi / 4), 0, 0])  # axis along Y
        assert drawn.group[0] == 2  # drawn by default (groups 0-2), the ellipsoid in group 3 is not
        np.testing.assert_allclose(drawn.rgba, [0.1, 0.1, 0.1, 1.0])
        assert model.body_mass[model.body(f"b/{side}_wheel").id] == pytest.approx(0.01)  # the drawn one is massless
    np.testing.assert_allclose(model.geom("b/chassis").rgba, BoeBot(name="x").color)


def test_service_settings_are_checked():
    world, _, _ = make(BoeBot)
    for bad in ({"radius_scale": math.nan}, {"separation_scale": 0.0}, {"rate": -50.0}):
        with pytest.raises(EntityError, match=r"drive service: .* must be a positive finite number"):
            DriveService(world, "r", **bad)
    for bad in ({"gain": math.inf}, {"integral_gain": math.nan}):
        with pytest.raises(EntityError, match=r"drive service: .* must be a finite number"):
            DriveService(world, "r", **bad)
    with pytest.raises(EntityError, match="cmd_vel: linear must be a finite number"):
        DriveService(world, "r").cmd_vel(math.nan, 0.0)
    fresh = DriveService(world, "r")
    assert fresh.odometry() == Odometry(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@pytest.mark.parametrize("robot", ROBOTS, ids=IDS)
def test_speed_loop_poles_are_where_the_design_puts_them(robot):
    """The closed loop of the sampled first-order motor with feed-forward + PI, solved independently."""
    _, drive, entity = make(robot, settle=0.0)
    design = drive.speed_loop()
    h, w0 = drive.period, entity.wheel_speed_limit
    a = math.exp(-h / design["time_constant"])
    g = (1 - a) * w0
    kp, ki = design["gain"], design["integral_gain"]
    # e[k+1] = a e[k] - g (kp e[k] + ki h S[k]),  S[k] = S[k-1] + e[k]
    poles = np.roots([1.0, -(1 + a - g * kp - g * ki * h), a - g * kp])
    assert np.all(np.abs(poles.imag) < 1e-6)  # no oscillation
    assert np.abs(poles).max() == pytest.approx(0.8, abs=1e-6)  # the slowest at the design's pole
    assert design["time_constant"] == pytest.approx(design["inertia"] * w0 / entity.stall_torque)


def test_speed_loop_inertia_is_the_robots_share_per_wheel():
    world, drive, _ = make(custom, settle=0.0)
    model = world.model
    wheel = model.body("r/left_wheel").id
    mass = model.body_subtreemass[model.body("r").id]
    share = mass * 0.05**2 / 2  # going straight each wheel drives half the robot (its yaw share is smaller here)
    assert drive.speed_loop()["inertia"] == pytest.approx(share + model.body_inertia[wheel][1], rel=0.02)


def test_integrals_do_not_wind_up_while_saturated():
    for direction in (1.0, -1.0):
        world, drive, _ = make(Pioneer3DX)
        drive.drive_speed(2.0 * direction, 2.0 * direction)  # beyond the 1.2 m/s motors: saturated
        world.run(3.0)
        drive.drive_speed(0.0, 0.0)
        world.run(4.5)  # 1.2 m/s at 0.3 m/s^2: 4 s to stop
        before = world.body("r").xpos.copy()
        world.run(0.2)
        assert np.linalg.norm(world.body("r").xpos - before) < 0.002, direction


def test_a_finished_distance_stays_stopped_and_stop_overrides_cmd_vel():
    world, drive, _ = make(IRobotCreate)
    drive.limits = DriveLimits(command_timeout=100.0)
    drive.cmd_vel(0.2, 0.0)
    world.run(0.5)
    drive.drive_distance(0.2)
    assert world.run_until(lambda: not drive.busy, timeout=10)
    before = world.body("r").xpos.copy()
    world.run(1.0)
    assert np.linalg.norm(world.body("r").xpos - before) < 0.001  # the old cmd_vel does not come back
    drive.cmd_vel(0.2, 0.0)
    world.run(0.5)
    drive.all_stop()
    world.run(1.5)
    before = world.body("r").xpos.copy()
    world.run(1.0)
    assert np.linalg.norm(world.body("r").xpos - before) < 0.001
    drive.cmd_vel(0.2, 0.0)
    world.run(0.5)
    drive.enable(False)
    drive.enable(True)  # re-enabled: idle until the next command
    world.run(1.0)
    before = world.body("r").xpos.copy()
    world.run(0.3)
    assert np.linalg.norm(world.body("r").xpos - before) < 0.001


def test_odometry_restarts_cleanly_after_reset_encoders_and_world_reset():
    world, drive, _ = make(LegoNxtTribot)
    drive.drive_speed(0.2, 0.1)  # an arc: the wheels turn by different angles
    world.run(1.0)
    drive.all_stop()
    world.run(1.0)
    drive.reset_encoders()
    assert drive.odometry() == Odometry(world.time, 0.0, 0.0, 0.0, 0.0, 0.0)
    start, start_heading = world.body("r").xpos.copy(), heading(world, "r")
    drive.drive_distance(0.3)
    assert world.run_until(lambda: not drive.busy, timeout=10)
    world.run(0.2)
    odometry = drive.odometry()
    moved = world.body("r").xpos - start
    assert math.hypot(moved[0], moved[1]) == pytest.approx(0.3, abs=0.01)
    assert math.hypot(odometry.x, odometry.y) == pytest.approx(0.3, abs=0.01)
    assert math.degrees(odometry.theta) == pytest.approx(heading(world, "r") - start_heading, abs=0.5)
    world.reset()
    assert drive.odometry() == Odometry(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    origin = world.body("r").xpos.copy()  # and from the initial pose it tracks the next motions
    for command in (lambda: drive.drive_distance(0.2), lambda: drive.rotate_degrees(30.0)):
        command()
        assert world.run_until(lambda: not drive.busy, timeout=10)
    odometry, moved = drive.odometry(), world.body("r").xpos - origin
    assert odometry.x == pytest.approx(moved[0], abs=0.01) and odometry.y == pytest.approx(moved[1], abs=0.01)
    assert math.degrees(odometry.theta) == pytest.approx(heading(world, "r"), abs=0.5)


def test_service_follows_its_robot_when_the_world_is_rebuilt():
    world = World()
    world.insert(Ground(name="ground"))
    world.insert(Box(name="crate", dimensions=(0.2, 0.2, 0.2), free=True, pose=Pose((3, 0, 0.1))))
    world.insert(BoeBot(name="bot", pose=Pose((0, 0, 0.001))))
    drive = DriveService(world, "bot")
    world.run(0.3)
    world.remove("crate")  # the robot's joints and motors get new ids in the new model
    world.run(0.3)
    start = world.body("bot").xpos.copy()
    drive.drive_distance(0.2, power=1.0)
    assert world.run_until(lambda: not drive.busy, timeout=10)
    assert world.body("bot").xpos[0] - start[0] == pytest.approx(0.2, abs=0.01)


def test_bumper_ignores_its_own_mounted_arm():
    from simrun.robots.arm import LynxL6
    from simrun.robots.arm_service import ArmService

    world = World()
    world.insert(Ground(name="ground"))
    world.insert(Pioneer3DX(name="base", pose=Pose((0, 0, 0.001))))
    world.insert(LynxL6(name="arm", parent="base", pose=Pose((0.1, 0, 0.237))))
    bumper = Bumper(world, "base")
    ArmService(world, "base/arm").set_joint_targets([0, -1.5, -1.2, 0, 0, 0])  # fold back onto the chassis
    world.run(3.0)
    model, data = world.model, world.data
    pairs = {tuple(sorted((model.geom(c.geom1).name, model.geom(c.geom2).name))) for c in data.contact[: data.ncon]}
    assert ("base/arm/finger_left/geom", "base/chassis") in pairs  # the gripper does rest on the chassis
    assert not bumper.reading.pressed and bumper.reading.touching == ()


def test_ray_exclusion_modes_and_continuation_past_the_robot():
    world = World()
    world.insert(Ground(name="ground"))
    world.insert(Box(name="wall", dimensions=(0.1, 4.0, 1.0), pose=Pose((1.05, 0, 0.5))))
    world.insert(Box(name="side", dimensions=(0.5, 0.1, 1.0), pose=Pose((0, 1.05, 0.5))))
    world.insert(BoeBot(name="bot", pose=Pose((0, 0, 0.001))))
    # 3 cm up, looking back through the robot's own chassis, caster and wheels, and ahead at the wall
    robot = LaserRangeFinder(world, "bot", height=0.03, fov_deg=360, rays=8, max_range=3.0)
    none = LaserRangeFinder(world, "bot", height=0.03, fov_deg=360, rays=8, max_range=3.0, exclude="none")
    world.run(0.1)
    ahead = int(np.argmin(np.abs(robot.angles)))
    x = world.body("bot").xpos[0]
    assert robot.reading.ranges[ahead] == pytest.approx(1.0 - x, abs=2e-3)
    assert none.reading.ranges[ahead] == pytest.approx(0.045, abs=1e-3)  # from inside: its own chassis' front face
    left = int(np.argmin(np.abs(robot.angles - np.pi / 2)))
    y = world.body("bot").xpos[1]
    assert robot.reading.ranges[left] == pytest.approx(1.0 - y, abs=2e-3)  # on past its own wheel to the wall
    assert none.reading.ranges[left] < 0.06
    clean = LaserRangeFinder(world, "bot", height=0.3, fov_deg=60, rays=5, max_range=3.0)
    noisy = LaserRangeFinder(world, "bot", height=0.3, fov_deg=60, rays=5, max_range=3.0, noise=0.01)
    world.step(1)
    offsets = noisy.reading.ranges - clean.reading.ranges
    assert len(set(np.round(offsets, 9))) == 5 and np.abs(offsets).max() < 0.05  # each ray its own draw


def test_laser_defaults_and_default_noise_seed():
    world, _ = boebot_world()
    laser = LaserRangeFinder(world, "bot")
    np.testing.assert_allclose(np.degrees(laser.angles), np.arange(-90, 91))  # 181 rays over 180 degrees
    assert (laser.max_range, laser.rate, laser.seed) == (8.0, 10.0, 0)
    chassis = world.model.geom("bot/chassis")  # the default height: the chassis top, from MuJoCo's compiled geom
    assert chassis.bodyid[0] == world.model.body("bot").id
    assert laser.height == pytest.approx(chassis.pos[2] + chassis.size[2], abs=1e-12)
    single = LaserRangeFinder(world, "bot", rays=1)
    assert list(single.angles) == [0.0] or single.angles.shape == (1,)
    a, b = GPS(world, "bot", noise=0.1), GPS(world, "bot", noise=0.1, seed=0)
    c, d = Encoders(world, "bot", noise=0.1), Encoders(world, "bot", noise=0.1, seed=0)
    e, f = (LaserRangeFinder(world, "bot", noise=0.1, rays=5, seed=s) for s in (0, 0))
    g = LaserRangeFinder(world, "bot", noise=0.1, rays=5)
    world.step(1)
    assert a.reading.position == b.reading.position and c.reading.angles == d.reading.angles
    np.testing.assert_array_equal(e.reading.ranges, g.reading.ranges)
    del f


def test_negative_power_drives_backwards_and_turns_run_at_half_the_drive_speed():
    world, drive, _ = make(Pioneer3DX)
    drive.set_drive_power(-0.5, -0.5)
    world.run(2.0)
    before = world.body("r").xpos[0]
    world.run(0.5)
    assert (world.body("r").xpos[0] - before) / 0.5 == pytest.approx(-0.6, rel=0.1)  # half of 1.2 m/s, backwards
    world, drive, _ = make(Pioneer3DX)
    drive.rotate_degrees(180, power=0.5)  # wheels at half of 0.5 x min(0.5 m/s limit, 1.2 m/s motor)
    world.run(2.0)
    before = heading(world, "r")
    world.run(0.2)
    rate = math.radians(heading(world, "r") - before) / 0.2
    assert rate == pytest.approx(2 * 0.125 / 0.3335, rel=0.05)


def test_world_reset_forgets_a_running_cmd_vel():
    world, drive, _ = make(BoeBot)
    drive.cmd_vel(0.1, 0.0)
    world.run(0.3)
    world.reset()
    start = world.body("r").xpos.copy()
    world.run(0.5)
    assert np.linalg.norm(world.body("r").xpos[:2] - start[:2]) < 1e-3


def test_switching_to_cmd_vel_keeps_the_speed_the_robot_has():
    world, drive, _ = make(Pioneer3DX)
    drive.drive_speed(0.4, 0.4)
    world.run(3.0)
    drive.cmd_vel(0.4, 0.0)
    for _ in range(5):
        before = world.body("r").xpos[0]
        world.run(0.1)
        assert (world.body("r").xpos[0] - before) / 0.1 == pytest.approx(0.4, rel=0.03)  # no dip, no ramp from 0


def test_checkpoint_in_an_arc_continues_bit_for_bit():
    world, drive, _ = make(LegoNxtTribot)
    drive.limits = DriveLimits(command_timeout=10.0)
    drive.cmd_vel(0.2, 1.0)
    world.run(0.3)  # still ramping: the two wheels' targets differ
    state = drive.snapshot()
    spec = mujoco.mjtState.mjSTATE_INTEGRATION
    physics = np.zeros(mujoco.mj_stateSize(world.model, spec))
    mujoco.mj_getState(world.model, world.data, physics, spec)
    world.run(0.5)
    expected = world.data.qpos.copy()
    mujoco.mj_setState(world.model, world.data, physics, spec)
    drive.restore(state)
    world.run(0.5)
    np.testing.assert_array_equal(world.data.qpos, expected)


def test_sensor_defaults_and_downward_ranges_see_the_floor():
    from simrun.sensors.range_cone import IRDistance, Sonar

    world, drive, _ = make(Pioneer3DX)
    bumper, imu = Bumper(world, "r"), IMU(world, "r", rate=0)
    assert bumper.rate == 50.0 and imu.rate == 0.0 and IMU(world, "r").rate == 100.0
    down = Sonar(world, "r", offset=(0.3, 0.0, 0.3), direction=(0.0, 0.0, -1.0), rate=0)  # past the chassis front
    a, b = IRDistance(world, "r", noise=0.01), IRDistance(world, "r", noise=0.01)
    drive.drive_speed(-0.2, 0.2)
    world.run(1.0)
    assert down.reading.distance == pytest.approx(0.3 + world.body("r").xpos[2], abs=0.01)  # the ground plane
    assert a.reading.distance == b.reading.distance  # the default seed is fixed
    # sampled before the last step (controllers tick before each step): one step of turning behind
    assert imu.reading.time == pytest.approx(world.time - 0.002)
    np.testing.assert_allclose(imu.reading.orientation, world.body("r").xquat, atol=2e-3)  # turned about Z


def test_services_and_sensors_rebind_on_every_rebuild():
    """Ids cached for one model are not used for the next, even where the new model lands at the freed one's
    address (``id()`` of a freed object is reused): ground truth is the simulator's own joint and body state."""
    world = World()
    world.insert(Ground(name="ground"))
    for k in range(8):  # free crates ahead of the robot in the model: removing one moves every address after it
        world.insert(Box(name=f"crate{k}", dimensions=(0.2, 0.2, 0.2), free=True, pose=Pose((1.0, k, 0.1))))
    world.insert(BoeBot(name="bot", pose=Pose((0, 0, 0.001))))
    drive = DriveService(world, "bot")
    encoders, gps, bumper = Encoders(world, "bot"), GPS(world, "bot"), Bumper(world, "bot")
    laser = LaserRangeFinder(world, "bot", fov_deg=10, rays=3)
    for k in range(8):
        world.step()
        world.remove(f"crate{k}")
        model, data = world.model, world.data  # rebuilt; the previous model is freed
        mujoco.mj_forward(model, data)
        wheel = model.joint("bot/left_wheel")
        reading = encoders.sample(model, data)
        assert reading.angles[0] == data.qpos[wheel.qposadr[0]]
        assert reading.velocities[0] == data.qvel[wheel.dofadr[0]]
        assert gps.sample(model, data).position == tuple(data.body("bot").xpos)
        assert laser.caster.bind(model) == model.body("bot").id
        assert not bumper.sample(model, data).pressed
        left, _ = drive.encoders()
        assert left == (data.qpos[wheel.qposadr[0]] - drive._encoder_zero[0]) * drive.radius
        drive.tick(model, data)  # the motor controls land on this model's actuators
        del model, data, wheel  # nothing holds this model but the world (and, fixed, the bindings)
