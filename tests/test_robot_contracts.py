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
from simrun.arm import ArmJoint, ArmService, ArticulatedArm, KukaLBR3, LynxL6, Segment
from simrun.cameras import RangeCone, StereoRig, Webcam
from simrun.drive import BoeBot, IRobotCreate, LegoNxtTribot, Pioneer3DX
from simrun.drive_service import DriveService
from simrun.sensors import Encoders, LaserRangeFinder, RayCaster

ROBOTS = [BoeBot, Pioneer3DX, IRobotCreate, LegoNxtTribot]


def _world(robot=BoeBot, name="r"):
    world = World()
    world.insert(Ground(name="ground"))
    entity = world.insert(robot(name=name, pose=Pose((0, 0, 0.001))))
    return world, entity


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
    world = World()
    world.insert(KukaLBR3(name="a"))
    service = ArmService(world, "a")
    goal = [0.3, -0.2, 0.1, 0.4, -0.1, 0.2, 0.05]
    service.move_to(goal, duration=0.1234)
    world.run(0.5)
    assert not service.busy
    np.testing.assert_array_equal(world.data.ctrl[: len(goal)], goal)


def test_ready_arms_have_their_joint_limits():
    """The ranges docs/robots.md ("Arms") states: KUKA +-170 degrees on the roll axes, +-120 on the pitch axes;
    Lynx +-90 but +-135 at the elbow, fingers 0 to 15 mm."""
    for arm, limits in ((KukaLBR3, [170, 120, 170, 120, 170, 120, 170]), (LynxL6, [90, 90, 135, 90, 90])):
        world = World()
        world.insert(arm(name="a"))
        model = world.model
        for j, degrees in enumerate(limits):
            assert model.jnt_limited[j], (arm.__name__, j)
            np.testing.assert_allclose(model.jnt_range[j], np.radians([-degrees, degrees]))
        if arm is LynxL6:
            for finger in ("a/finger_left", "a/finger_right"):
                np.testing.assert_allclose(model.joint(finger).range, [0.0, 0.015])


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"duration": 0.0}, "move duration must be a positive number of seconds"),
        ({"duration": -1.0}, "move duration must be a positive number of seconds"),
    ],
)
def test_move_to_refusals_say_what_is_wrong(change, message):
    world = World()
    world.insert(LynxL6(name="a"))
    service = ArmService(world, "a")
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
    world.insert(StereoRig(name="rig", fovy=-10.0))
    with pytest.raises(EntityError, match="fovy"):
        world.compile()
    world = World()
    world.insert(StereoRig(name="rig"))
    webcam = Webcam(world, "rig/left")
    assert (webcam.eye.width, webcam.eye.height, webcam.rate) == (320, 240, 15.0)
