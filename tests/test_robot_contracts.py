"""Contracts of the robot modules that the behaviour tests leave open: design inputs against the compiled
model, closed-form geometry, defaults against their documentation, and the messages of refused values.

Written against mutants that survived `make mutants` (docs/testing.md): each test names what it pins down.
Ground truth is the compiled MuJoCo model, analytic geometry or the documented numbers, never the code under test.
"""

import math

import mujoco
import numpy as np
import pytest

from simrun import Box, EntityError, Ground, Pose, World, WorldOptions
from simrun.robots.arm import ArmJoint, ArticulatedArm, KukaLBR3, LynxL6, Segment
from simrun.robots.arm_service import ArmService
from simrun.robots.catalogue import BoeBot, IRobotCreate, LegoNxtTribot, Pioneer3DX
from simrun.sensors.base import RayCaster
from simrun.sensors.cameras import StereoRig, Webcam
from simrun.sensors.laser import LaserRangeFinder
from simrun.sensors.range_cone import IRDistance, RangeCone, Sonar
from simrun.sensors.robot_state import GPS, IMU, Encoders
from simrun.services.drive_service import DriveLimits, DriveService

ROBOTS = [BoeBot, Pioneer3DX, IRobotCreate, LegoNxtTribot]


def _world(robot=BoeBot, name="r"):
    world = World()
    world.insert(Ground(name="ground"))
    entity = world.insert(robot(name=name, pose=Pose((0, 0, 0.001))))
    return world, entity


def _driving(robot=Pioneer3DX, settle=0.3):
    """A robot with its drive service, after ``settle`` seconds standing on its wheels."""
    world, entity = _world(robot)
    drive = DriveService(world, "r")
    world.run(settle)
    return world, drive, entity


def _arm(cls, name="a"):
    world = World()
    world.insert(cls(name=name))
    return world, ArmService(world, name)


# -- drive service ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("robot", ROBOTS, ids=lambda r: r.__name__)
def test_speed_loop_inertia_is_the_wheel_plus_the_parallel_axis_share_of_the_robot(robot):
    """Per wheel: its own axial inertia and armature, plus half the robot's mass (straight) or its yaw inertia
    seen through the track (turning), the larger: summed body by body with the parallel-axis theorem."""
    world, entity = _world(robot)
    drive = DriveService(world, "r")
    model = world.model
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)  # the initial pose, where the design is made
    root = model.body("r").id
    subtree = [b for b in range(model.nbody) if model.body_rootid[b] == root]
    mass = sum(model.body_mass[b] for b in subtree)
    yaw = 0.0
    for b in subtree:
        rotation = data.ximat[b].reshape(3, 3)
        inertia = rotation @ np.diag(model.body_inertia[b]) @ rotation.T
        arm = data.xipos[b] - data.xpos[root]
        yaw += inertia[2, 2] + model.body_mass[b] * (arm[0] ** 2 + arm[1] ** 2)
    wheel = model.joint("r/left_wheel")
    wheel_body = model.jnt_bodyid[wheel.id]
    rotation = data.ximat[wheel_body].reshape(3, 3)
    axis = rotation.T @ (data.xmat[wheel_body].reshape(3, 3) @ model.jnt_axis[wheel.id])  # in the inertia frame
    own = float(axis @ np.diag(model.body_inertia[wheel_body]) @ axis) + model.dof_armature[wheel.dofadr[0]]
    r, s = entity.wheel_radius, entity.separation
    expected = own + max(mass * r * r / 2, 2 * yaw * r * r / (s * s))
    design = drive.speed_loop()
    assert design["inertia"] == pytest.approx(expected, rel=1e-9)
    assert design["pole"] == 0.8  # docs/robots.md, "Speed loop"


def test_the_integral_holds_the_commanded_speed_up_a_slope():
    """Gravity tilted 6 degrees against the motion is a slope: only the integral removes the speed error."""
    tilt = math.radians(6)
    world = World(WorldOptions(gravity=(-9.81 * math.sin(tilt), 0.0, -9.81 * math.cos(tilt))))
    world.insert(Ground(name="ground"))
    world.insert(Pioneer3DX(name="r", pose=Pose((0, 0, 0.001))))
    drive = DriveService(world, "r")
    world.run(0.3)
    drive.drive_speed(0.4, 0.4)
    world.run(4.0)
    before = world.body("r").xpos.copy()
    world.run(1.0)
    speed = float(np.linalg.norm(world.body("r").xpos[:2] - before[:2]))
    assert speed == pytest.approx(0.4, rel=0.01)


def test_odometry_integrates_one_update_along_the_arc_geometry():
    """One update with the wheels turned by known angles: the pose is the chord of that arc (midpoint heading)."""
    world, entity = _world(BoeBot)
    drive = DriveService(world, "r")
    world.run(0.1)
    model, data = world.model, world.data
    drive.reset_encoders()
    left, right = 0.09, 0.11  # wheel travel, metres
    for joint, travel in (("r/left_wheel", left), ("r/right_wheel", right)):
        data.qpos[model.joint(joint).qposadr[0]] += travel / entity.wheel_radius
    data.time += drive.period
    drive.tick(model, data)
    theta = (right - left) / entity.separation
    radius = (left + right) / 2 / theta
    chord = 2 * radius * math.sin(theta / 2)
    odometry = drive.odometry()
    assert odometry.theta == pytest.approx(theta, rel=1e-12)
    # the chord points along the mean heading; the midpoint rule steps the arc length ds instead of the chord,
    # ds theta^2 / 24 longer (to second order): that is the whole allowed difference
    ds = (left + right) / 2
    slack = (ds - chord) * 1.01
    assert abs(odometry.x - chord * math.cos(theta / 2)) <= slack
    assert abs(odometry.y - chord * math.sin(theta / 2)) <= slack


def test_a_restored_snapshot_taken_while_settling_still_waits_for_rest():
    """A command at t = 0 waits for the robot to stand on its wheels, also after a checkpoint from then."""
    world, _ = _world(BoeBot)
    drive = DriveService(world, "r")
    state = drive.snapshot()
    assert state["rested"] is False
    drive.restore(state)
    start = world.body("r").xpos.copy()
    drive.drive_distance(0.2)
    assert world.run_until(lambda: not drive.busy, timeout=10)
    assert world.body("r").xpos[0] - start[0] == pytest.approx(0.2, abs=0.01)


@pytest.mark.parametrize("key", ["radius_scale", "rate", "gain"])
def test_drive_service_settings_that_are_not_numbers_are_named(key):
    world, _ = _world()
    with pytest.raises(EntityError, match=f"drive service: {key} must be a number, got 'x'"):
        DriveService(world, "r", **{key: "x"})


def test_power_beyond_full_is_full():
    """set_drive_power clips to [-1, 1]: -3 drives backwards exactly as fast as -1."""
    speeds = []
    for power in (-1.0, -3.0):
        world, _ = _world(Pioneer3DX)
        drive = DriveService(world, "r")
        world.run(0.3)
        drive.set_drive_power(power, power)
        world.run(2.0)
        before = world.body("r").xpos[0]
        world.run(0.5)
        speeds.append(world.body("r").xpos[0] - before)
    assert speeds[1] == speeds[0] and speeds[0] < 0


# -- arms ------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("arm", [KukaLBR3, LynxL6], ids=["KukaLBR3", "LynxL6"])
def test_servo_inertia_bounds_the_joint_space_inertia_in_every_pose(arm):
    """The design's inertia is an upper bound of the simulator's joint-space inertia (exact for a slide: the
    mass it carries plus the armature), in random poses."""
    world = World()
    world.insert(arm(name="a"))
    service = ArmService(world, "a")
    model = world.model
    design = service.servo_design()
    data = mujoco.MjData(model)
    full = np.zeros((model.nv, model.nv))
    rng = np.random.default_rng(0)
    for _ in range(20):
        for j in range(model.njnt):
            low, high = model.jnt_range[j] if model.jnt_limited[j] else (-math.pi, math.pi)
            data.qpos[model.jnt_qposadr[j]] = rng.uniform(low, high)
        mujoco.mj_forward(model, data)
        mujoco.mj_fullM(model, data, full)
        for name, entry in design.items():
            joint = model.joint(name)
            dof = joint.dofadr[0]
            if model.jnt_type[joint.id] == mujoco.mjtJoint.mjJNT_SLIDE:
                carried = model.body_subtreemass[model.jnt_bodyid[joint.id]] + model.dof_armature[dof]
                assert entry["inertia"] == pytest.approx(carried, rel=1e-9), name
            assert entry["inertia"] >= full[dof, dof] * (1 - 1e-9), name


def test_a_slide_carrying_two_links_designs_for_both():
    world = World()
    arm = ArticulatedArm(
        name="a",
        segments=(
            Segment("carriage", 0.1, 0.02, 0.4, ArmJoint(kind="slide", axis=(1, 0, 0), limits=(-0.1, 0.1), kp=50)),
            Segment("tool", 0.1, 0.02, 0.3, ArmJoint(locked=True)),
        ),
    )
    world.insert(arm)
    model = world.model
    design = ArmService(world, "a").servo_design()["a/carriage"]
    body = model.body("a/carriage").id
    armature = model.dof_armature[model.joint("a/carriage").dofadr[0]]
    assert design["inertia"] == pytest.approx(model.body_subtreemass[body] + armature, rel=1e-9)
    assert model.body_subtreemass[body] == pytest.approx(0.7)  # both segments ride on the slide


def test_a_move_ends_exactly_on_its_goal_between_ticks():
    """A duration that is no multiple of the service's period: the last tick lands past the end, on the goal."""
    world, service = _arm(KukaLBR3, "a")
    goal = [0.3, -0.2, 0.1, 0.4, -0.1, 0.2, 0.05]
    service.move_to(goal, duration=0.1234)
    world.run(0.5)
    assert not service.busy
    np.testing.assert_array_equal(world.data.ctrl[: len(goal)], goal)


def test_ready_arms_have_their_joint_limits():
    """The ranges docs/robots.md ("Arms") states: KUKA +-170 degrees on the roll axes, +-120 on the pitch axes;
    Lynx +-90 but +-135 at the elbow, fingers 0 to 15.875 mm (the Little Grip's 1.25 in opening, less the
    fingers' 8 mm thickness, shared by two fingers 4 mm off the middle)."""
    for arm, limits in ((KukaLBR3, [170, 120, 170, 120, 170, 120, 170]), (LynxL6, [90, 90, 135, 90, 90])):
        world = World()
        world.insert(arm(name="a"))
        model = world.model
        for j, degrees in enumerate(limits):
            assert model.jnt_limited[j], (arm.__name__, j)
            np.testing.assert_allclose(model.jnt_range[j], np.radians([-degrees, degrees]))
        if arm is LynxL6:
            for finger in ("a/finger_left", "a/finger_right"):
                np.testing.assert_allclose(model.joint(finger).range, [0.0, (1.25 * 0.0254 + 2 * 0.004) / 2 - 0.004])


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"duration": 0.0}, "move duration must be a positive number of seconds"),
        ({"duration": -1.0}, "move duration must be a positive number of seconds"),
    ],
)
def test_move_to_refusals_say_what_is_wrong(change, message):
    _, service = _arm(LynxL6, "a")
    with pytest.raises(EntityError, match=message):
        service.move_to([0.0] * len(service.joints), **change)


def test_a_bad_joint_is_refused_naming_the_arm_and_segment():
    world = World()
    world.insert(ArticulatedArm(name="bad", segments=(Segment("upper", 0.1, joint=ArmJoint(kp=-1.0)),)))
    with pytest.raises(EntityError, match=r"ArticulatedArm 'bad': joint of 'upper'"):
        world.compile()


def test_segment_offset_survives_the_scene_table():
    segment = Segment("a", 0.1, offset=(0.02, 0.0, 0.01))
    assert Segment.from_scene(segment.to_scene(), "t").offset == (0.02, 0.0, 0.01)


# -- sensors ---------------------------------------------------------------------------------------------------


def test_ray_caster_excludes_the_whole_robot_by_default():
    """The documented default (docs/robots.md, "Sensors"): a caster built without ``exclude`` skips the robot."""
    assert RayCaster("r").exclude == "robot"


def test_sensor_refusals_say_what_is_wrong():
    world, _ = _world()
    with pytest.raises(EntityError, match="sensor rate and noise must be >= 0"):
        Encoders(world, "r", rate=-1.0)
    with pytest.raises(EntityError, match=r"range cone: 0 <= min_range < max_range, rays >= 1, cone >= 0"):
        RangeCone(world, "r", max_range=0.0)


def test_a_short_laser_sees_within_its_range_and_noise_never_leaves_it():
    """max_range below 1 m is valid; noisy ranges stay within [0, max_range] (a wall 0.4 m ahead)."""
    world, _ = _world(Pioneer3DX)
    world.insert(Box(name="wall", dimensions=(0.1, 4.0, 1.0), pose=Pose((0.4 + 0.05, 0, 0.5))))
    near = LaserRangeFinder(world, "r", fov_deg=10, rays=3, max_range=0.5, rate=0)
    noisy = LaserRangeFinder(world, "r", fov_deg=90, rays=91, max_range=0.5, noise=0.5, rate=0)
    world.step()
    assert near.reading.ranges[1] == pytest.approx(0.4, abs=0.01)
    assert near.reading.points is None
    assert noisy.reading.ranges.max() <= 0.5 and noisy.reading.ranges.min() >= 0.0


def test_laser_points_on_the_ground_plane_are_kept():
    """Rays that hit geom 0 (the ground plane, the model's first geom) give points on the floor, not NaN: a
    laser on a post 1 m up, pitched 45 degrees down, reads sqrt(2) m."""
    world = World()
    world.insert(Ground(name="ground"))
    pitched = Pose((0, 0, 1.0), (math.cos(math.pi / 8), 0, math.sin(math.pi / 8), 0))
    world.insert(Box(name="post", dimensions=(0.05, 0.05, 0.05), pose=pitched))
    down = LaserRangeFinder(world, "post", fov_deg=2, rays=3, height=0.0, rate=0, points=True, exclude="body")
    assert world.model.geom("ground/plane").id == 0
    world.step()
    assert down.reading.points is not None and np.isfinite(down.reading.points).all()
    np.testing.assert_allclose(down.reading.points[:, 2], 0.0, atol=1e-6)
    assert down.reading.ranges[1] == pytest.approx(math.sqrt(2.0), abs=1e-6)


def test_encoder_defaults_and_seed():
    """50 Hz by default (docs/robots.md, "Sensors"); the seed reaches the noise generator."""
    world, _ = _world()
    assert Encoders(world, "r").rate == 50.0
    a = Encoders(world, "r", noise=0.1, seed=7)
    b = Encoders(world, "r", noise=0.1, seed=8)
    c = RangeCone(world, "r", noise=0.1, seed=7)
    assert (a.seed, b.seed, c.seed) == (7, 8, 7)
    world.step()
    assert a.reading.angles != b.reading.angles


# -- range cones and cameras -----------------------------------------------------------------------------------


def test_range_cone_direction_is_normalised_and_a_single_ray_looks_straight():
    """A wall 1 m ahead along +X: a direction of any length, and a one-ray cone of any width, read 1 m."""
    world = World()
    world.insert(Ground(name="ground"))
    world.insert(Box(name="post", dimensions=(0.1, 0.1, 0.1), pose=Pose((0, 0, 0.5))))
    world.insert(Box(name="wall", dimensions=(0.1, 4.0, 4.0), pose=Pose((1.05 + 0.05, 0, 0.5))))
    long = RangeCone(world, "post", offset=(0.05, 0, 0), direction=(3.0, 0, 0), max_range=2.0, rate=0)
    single = RangeCone(world, "post", offset=(0.05, 0, 0), cone_deg=40.0, rays=1, max_range=2.0, rate=0)
    world.step()
    assert long.reading.distance == pytest.approx(1.0, abs=1e-9)
    assert single.reading.distance == pytest.approx(1.0, abs=1e-9)


def test_stereo_rig_refuses_a_bad_field_of_view_and_webcam_defaults():
    world = World()
    world.insert(StereoRig(name="rig", fov=-10.0))
    with pytest.raises(EntityError, match="fov"):
        world.compile()
    world = World()
    world.insert(StereoRig(name="rig"))
    webcam = Webcam(world, "rig/left")
    assert (webcam.eye.width, webcam.eye.height, webcam.rate) == (320, 240, 15.0)


# -- second round: survivors of the full run (docs/testing.md) ------------------------------------------------


@pytest.mark.parametrize(
    ("call", "args"),
    [("set_drive_power", (0.2, math.nan)), ("drive_speed", (0.1, math.inf)), ("cmd_vel", (0.1, -math.inf))],
)
def test_a_non_finite_right_or_angular_value_is_refused_too(call, args):
    world, _ = _world()
    drive = DriveService(world, "r")
    with pytest.raises(EntityError, match=f"{call}: .* must be a finite number"):
        getattr(drive, call)(*args)


@pytest.mark.parametrize("call", ["drive_distance", "rotate_degrees"])
def test_a_bad_power_names_the_command(call):
    world, _ = _world()
    drive = DriveService(world, "r")
    with pytest.raises(EntityError, match=f"{call}: power must be a positive finite number"):
        getattr(drive, call)(0.1, power=0.0)


def test_snapshot_restore_is_the_identity_with_every_field_distinct():
    """Left and right values that differ, mid-command: restoring a snapshot gives the same snapshot back."""
    world, drive, _ = _driving(Pioneer3DX)
    drive.set_drive_power(0.2, 0.4)
    world.run(0.3)
    drive.reset_encoders()  # zeros at two different wheel angles
    world.run(0.2)
    drive.drive_speed(0.1, 0.3)
    world.run(0.3)
    state = drive.snapshot()
    assert state["speed"][0] != state["speed"][1] and state["power"][0] != state["power"][1]
    assert state["encoder_zero"][0] != state["encoder_zero"][1] and state["last"][0] != state["last"][1]
    other = DriveService(world, "r")
    other.restore(state)
    assert other.snapshot() == state


def test_a_second_distance_counts_from_where_the_first_ended():
    """Two drive_distance(0.2) in a row: 0.4 m in all (the goal counts from the encoders at its start)."""
    world, drive, _ = _driving(Pioneer3DX)
    start = world.body("r").xpos[0]
    for _ in range(2):
        drive.drive_distance(0.2)
        assert world.run_until(lambda: not drive.busy, timeout=10)
    assert world.body("r").xpos[0] - start == pytest.approx(0.4, abs=0.01)


def _velocity(world, name="r"):
    """Body linear speed along its heading (m/s) and yaw rate (rad/s) from the simulator's free joint."""
    model, data = world.model, world.data
    dof = model.jnt_dofadr[model.body_jntadr[model.body(name).id]]
    v = data.qvel[dof : dof + 6]
    rotation = data.body(name).xmat.reshape(3, 3)
    return float(rotation[:, 0] @ v[:3]), float(v[5])


def test_cmd_vel_decelerates_and_stops_turning_at_its_limits():
    """Going to zero from 0.4 m/s and from 1 rad/s takes at least speed / limit: no instant stop."""
    world, drive, _ = _driving(Pioneer3DX)
    drive.limits = limits = DriveLimits(command_timeout=100.0, max_angular_accel=1.0)
    cases = [((0.4, 0.0), 0.4, limits.max_linear_accel, 0.03), ((0.0, 1.0), 0.2, limits.max_angular_accel, 0.05)]
    for axis, (command, seconds, accel, tolerance) in enumerate(cases):
        drive.cmd_vel(*command)
        world.run(3.0)
        drive.cmd_vel(0.0, 0.0)
        world.run(seconds)
        assert _velocity(world)[axis] == pytest.approx(command[axis] - seconds * accel, abs=tolerance)


def test_switching_from_a_turn_to_cmd_vel_keeps_the_turn_rate():
    """cmd_vel starts its ramp from the measured (linear, angular) velocity: a turning robot keeps turning."""
    world, _ = _world(Pioneer3DX)
    drive = DriveService(world, "r")
    drive.limits = type(drive.limits)(command_timeout=100.0)
    world.run(0.3)
    drive.drive_speed(-0.2, 0.2)
    world.run(2.0)
    _, before = _velocity(world)
    drive.cmd_vel(0.0, before)
    world.run(0.1)
    _, after = _velocity(world)
    assert before > 0.5 and after == pytest.approx(before, rel=0.05)


def test_switching_from_power_to_a_speed_starts_from_the_measured_speed():
    """From set_drive_power the speed ramp starts at the wheels' speed: no dip while the target ramps up."""
    world, drive, _ = _driving(Pioneer3DX)
    drive.set_drive_power(0.5, 0.5)
    world.run(3.0)
    before, _ = _velocity(world)
    drive.drive_speed(before, before)
    world.run(0.1)
    after, _ = _velocity(world)
    assert after == pytest.approx(before, rel=0.03)


@pytest.mark.parametrize("robot", ROBOTS, ids=lambda r: r.__name__)
def test_half_power_distance_cruises_at_half_the_top_speed(robot):
    """drive_distance(power=0.5) cruises at half the robot's top speed (its motor's no-load speed on its wheel)."""
    world, drive, entity = _driving(robot)
    top = min(drive.limits.max_linear, entity.wheel_speed_limit * entity.wheel_radius)
    drive.drive_distance(0.5 * top * 6, power=0.5)  # six seconds at cruising speed
    world.run(3.0)
    before = world.body("r").xpos.copy()
    world.run(1.0)
    assert float(np.linalg.norm(world.body("r").xpos - before)) == pytest.approx(0.5 * top, rel=0.05)


def test_a_distance_decelerates_within_the_acceleration_limit():
    """The approach to a goal brakes no harder than max_linear_accel (speeds from the simulator, 20 ms apart)."""
    world, drive, _ = _driving(Pioneer3DX)
    drive.drive_distance(1.0)
    speeds = []
    while drive.busy and world.time < 10:
        world.run(0.02)
        speeds.append(_velocity(world)[0])
    braking = -np.diff(speeds).max() / 0.02
    assert max(speeds) > 0.25 and braking <= drive.limits.max_linear_accel * 1.25


def test_odometry_reports_the_turn_rate():
    """Odometry's angular speed is the heading change per second (the simulator's yaw rate when turning)."""
    world, drive, _ = _driving(Pioneer3DX)
    drive.drive_speed(-0.2, 0.2)
    world.run(2.0)
    _, yaw = _velocity(world)
    assert drive.odometry().angular == pytest.approx(yaw, rel=0.05)


def test_a_command_right_after_world_reset_waits_for_the_robot_to_settle():
    world, _ = _world(BoeBot)
    drive = DriveService(world, "r")
    world.run(0.5)
    world.reset()  # back to the initial pose, 1 mm up
    start = world.body("r").xpos.copy()
    drive.drive_distance(0.2)
    assert world.run_until(lambda: not drive.busy, timeout=10)
    assert world.body("r").xpos[0] - start[0] == pytest.approx(0.2, abs=0.01)


def test_disabling_ends_a_running_distance():
    world, drive, _ = _driving(BoeBot)
    drive.drive_distance(1.0)
    world.run(0.2)
    drive.enable(False)
    assert not drive.busy


def test_arm_service_defaults_and_idle_round_trip():
    _, service = _arm(LynxL6, "a")
    assert service.period == pytest.approx(0.02)  # 50 Hz
    state = service.snapshot()
    assert state["move"] is None
    states = service.joint_states()
    assert states.names == tuple(service.joints) and len(states.positions) == len(service.joints)
    service.restore(state)
    assert not service.busy


def test_a_move_started_later_is_half_way_at_half_time():
    """The cosine profile counts from the move's start time (here 0.5 s into the run)."""
    world, service = _arm(KukaLBR3, "k")
    world.run(0.5)
    service.move_to([0.6, 0, 0, 0, 0, 0, 0], 1.0)
    world.run(0.25)
    service.restore(service.snapshot())  # a checkpoint keeps the start time
    world.run(0.25)
    assert world.data.ctrl[world.model.actuator("k/link1").id] == pytest.approx(0.3, abs=0.02)


def test_servo_design_covers_exactly_the_position_servos():
    world = World()
    world.insert(LynxL6(name="a"))
    design = ArmService(world, "a").servo_design()
    assert set(design) == {
        "a/base_rotate",
        "a/shoulder",
        "a/elbow",
        "a/wrist",
        "a/wrist_rotate",
        "a/finger_left",
    }  # finger_right mimics finger_left


def test_segment_tables_leave_defaults_out_and_keep_every_offset():
    assert Segment("a", 0.1).to_scene() == {"name": "a", "length": 0.1}
    joint = Segment("a", 0.1, joint=ArmJoint(kp=30.0)).to_scene()["joint"]
    assert joint == {"kp": 30.0}
    for offset in ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)):
        assert Segment.from_scene(Segment("a", 0.1, offset=offset).to_scene(), "t").offset == offset


@pytest.mark.parametrize("key", ["radius", "mass"])
def test_a_segment_table_with_a_bad_number_names_it(key):
    with pytest.raises(EntityError, match=f"t.{key}: expected a number"):
        Segment.from_scene({"name": "a", "length": 0.1, key: "x"}, "t")


def test_joint_limits_must_span_a_range():
    world = World()
    world.insert(ArticulatedArm(name="bad", segments=(Segment("a", 0.1, joint=ArmJoint(limits=(0.5, 0.5))),)))
    with pytest.raises(EntityError, match="low < high"):
        world.compile()


def test_exclude_none_still_sees_every_other_body():
    """A wall inserted first (the model's body 1) is seen by a laser that excludes nothing."""
    world = World()
    world.insert(Box(name="wall", dimensions=(0.1, 4.0, 1.0), pose=Pose((1.0, 0, 0.5))))
    world.insert(Ground(name="ground"))
    world.insert(Pioneer3DX(name="r", pose=Pose((0, 0, 0.001))))
    laser = LaserRangeFinder(world, "r", fov_deg=2, rays=3, height=0.3, rate=0, exclude="none")
    assert world.model.body("wall").id == 1
    world.step()
    assert laser.reading.ranges[1] == pytest.approx(0.95, abs=1e-6)


def test_a_ray_through_the_robot_reports_the_floor_below_it():
    """A downward cone inside the chassis: its rays pass through the robot and hit the ground plane (geom 0)."""
    world, _ = _world(Pioneer3DX)
    down = RangeCone(world, "r", offset=(-0.05, 0, 0.15), direction=(0, 0, -1), max_range=1.0, rate=0)
    world.run(0.3)
    assert down.reading.distance == pytest.approx(0.15 + world.body("r").xpos[2], abs=1e-3)


def test_noise_is_reproducible_after_a_world_reset_and_present_at_one_metre():
    world, _ = _world()
    gps = GPS(world, "r", noise=1.0, rate=0)
    world.step()
    first = gps.reading.position
    assert first != tuple(world.body("r").xpos)  # noise of 1 m is applied
    world.reset()
    world.step()
    assert gps.reading.position == first


def test_noisy_short_ranges_are_not_lifted():
    """Noise of 1 cm on a wall 0.4 m away reads about 0.4 m (clipped to [0, max_range], nothing more)."""
    world, _ = _world(Pioneer3DX)
    world.insert(Box(name="wall", dimensions=(0.1, 4.0, 1.0), pose=Pose((0.45, 0, 0.5))))
    laser = LaserRangeFinder(world, "r", fov_deg=20, rays=21, noise=0.01, rate=0)
    narrow = LaserRangeFinder(world, "r", fov_deg=0.5, rays=3, rate=0, seed=7)
    world.step()
    assert laser.reading.ranges.mean() == pytest.approx(0.4 / math.cos(math.radians(5)), abs=0.01)
    assert narrow.seed == 7 and narrow.reading.ranges[1] == pytest.approx(0.4, abs=1e-6)


def test_imu_noise_and_seeds():
    world, _ = _world()
    a, b = IMU(world, "r", noise=0.1, rate=0), IMU(world, "r", noise=0.1, rate=0)
    c = IMU(world, "r", noise=0.1, rate=0, seed=3)
    quiet = IMU(world, "r", rate=0)
    world.step()
    assert a.seed == 0 and c.seed == 3
    assert a.reading.gyro == b.reading.gyro != c.reading.gyro
    assert a.reading.gyro != quiet.reading.gyro


def test_range_cone_readings_and_documented_cones():
    """A reading's value is its distance without a response table, at the simulation time; the documented
    cones: IRDistance 2 degrees, Sonar 30 degrees (the outermost ray's angle from the axis is half of it)."""
    world, _ = _world()
    cone, default = RangeCone(world, "r", rate=0), RangeCone(world, "r")
    ir, sonar = IRDistance(world, "r"), Sonar(world, "r")
    world.run(0.1)
    assert cone.reading.value == cone.reading.distance and cone.reading.time == pytest.approx(world.time - 0.002)
    assert (default.rate, default.max_range, default.min_range, len(default._local)) == (20.0, 1.0, 0.0, 1)
    for sensor, degrees in ((ir, 2.0), (sonar, 30.0)):
        spread = math.degrees(math.acos(np.clip(sensor._local @ np.array([1.0, 0.0, 0.0]), -1, 1).min()))
        edge = math.degrees(math.hypot(math.radians(degrees / 2), math.radians(degrees / 2)))
        assert spread == pytest.approx(edge, rel=1e-9)


def test_joint_tables_keep_limits_and_flags():
    table = {"name": "a", "length": 0.1, "joint": {"limits": [-1.0, 1.0], "gravity_compensation": False}}
    joint = Segment.from_scene(table, "t").joint
    assert joint.limits == (-1.0, 1.0) and joint.gravity_compensation is False
    assert Segment.from_scene({"name": "a", "length": 0.1, "joint": {"locked": True}}, "t").joint.locked is True


def test_gps_samples_once_a_second_by_default():
    """docs/robots.md, "Sensors": GPS 1 Hz."""
    world, _ = _world()
    gps = GPS(world, "r")
    world.run(2.5)
    assert gps.rate == 1.0 and gps.samples == 3  # at 0, 1 and 2 s


def test_sensors_sample_at_the_first_step_of_a_rebuilt_world():
    """A rebuilt world starts again at time 0: a 1 Hz GPS last sampled at 5 s samples at once, not 5 s later."""
    world, _ = _world()
    gps = GPS(world, "r")
    world.run(5.5)
    assert gps.samples == 6
    world.insert(Box(name="crate", dimensions=(0.1, 0.1, 0.1), pose=Pose((1.0, 0, 0.05))))
    world.step()
    assert gps.samples == 7 and gps.reading.time == 0.0
    assert gps.reading.position == pytest.approx(tuple(world.body("r").xpos), abs=1e-3)


def test_beyond_full_reverse_is_full_reverse_and_beyond_full_power_cruises_at_full():
    """A speed past the motors' reach saturates at full reverse; a distance at power 3 cruises as at power 1."""
    world, drive, entity = _driving(Pioneer3DX)
    drive.drive_speed(-3.0, -3.0)  # past the 1.2 m/s motors, backwards
    world.run(6.0)
    linear, _ = _velocity(world)
    assert linear == pytest.approx(-entity.wheel_speed_limit * entity.wheel_radius, rel=0.1)
    cruise = []
    for power in (1.0, 3.0):
        world, _ = _world(Pioneer3DX)
        drive = DriveService(world, "r")
        world.run(0.3)
        drive.drive_distance(2.0, power=power)
        world.run(3.0)
        cruise.append(_velocity(world)[0])
    assert cruise[1] == pytest.approx(cruise[0], rel=1e-9) and cruise[0] > 0.3


def test_odometry_restarts_with_a_rebuilt_world():
    """After an arc, adding an entity rebuilds the world (time 0, initial pose): odometry and encoders restart
    there instead of integrating the jump of the wheel angles back to zero."""
    world, drive, _ = _driving(Pioneer3DX)
    drive.drive_speed(0.1, 0.3)
    world.run(2.0)
    drive.all_stop()
    world.run(1.0)
    world.insert(Box(name="crate", dimensions=(0.1, 0.1, 0.1), pose=Pose((2.0, 2.0, 0.05))))
    world.run(0.3)
    odometry = drive.odometry()
    xpos = world.body("r").xpos
    assert odometry.x == pytest.approx(xpos[0], abs=1e-3) and odometry.y == pytest.approx(xpos[1], abs=1e-3)
    assert abs(odometry.linear) < 0.02 and drive.encoders() == pytest.approx((0.0, 0.0), abs=0.005)  # settling


def test_a_move_in_progress_starts_over_in_a_rebuilt_world():
    """A 1 s move started at 0.5 s, rebuilt 0.3 s into it: the world restarts at time 0 and the move runs its
    profile again from there (not from a negative elapsed time on the old clock)."""
    world, service = _arm(KukaLBR3, "k")
    world.run(0.5)
    service.move_to([0.6, 0, 0, 0, 0, 0, 0], 1.0)
    world.run(0.3)
    world.insert(Box(name="crate", dimensions=(0.1, 0.1, 0.1), pose=Pose((1.0, 1.0, 0.05))))
    world.run(0.5)  # half of the move on the new clock
    target = world.data.ctrl[world.model.actuator("k/link1").id]
    assert target == pytest.approx(0.3, abs=0.02) and service.busy
    world.run(0.6)
    assert not service.busy and world.data.ctrl[world.model.actuator("k/link1").id] == 0.6
