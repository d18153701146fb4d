"""Range cones and cameras. Rendering tests skip, with the reason, only where no OpenGL context starts."""

import numpy as np
import pytest
from conftest import needs_gl

from simrun import Box, Camera, Ground, Pose, World
from simrun.errors import EntityError, SimrunError
from simrun.robots.catalogue import BoeBot
from simrun.sensors.cameras import StereoCamera, StereoRig, Webcam
from simrun.sensors.range_cone import IRDistance, RangeCone, Sonar


def robot_facing_wall(distance):
    world = World()
    world.insert(Ground(name="ground"))
    world.insert(BoeBot(name="bot", pose=Pose((0, 0, 0.001))))
    world.insert(Box(name="wall", dimensions=(0.1, 2.0, 0.5), pose=Pose((distance + 0.05, 0, 0.25))))
    return world


@pytest.mark.parametrize("distance", [0.3, 0.6])
def test_ir_and_sonar_measure_the_wall(distance):
    world = robot_facing_wall(distance)
    ir = IRDistance(world, "bot", offset=(0.0, 0.0, 0.05))
    sonar = Sonar(world, "bot", offset=(0.0, 0.0, 0.3))  # a 30 degree cone lower down would see the floor
    world.run(0.2)
    assert ir.reading.distance == pytest.approx(distance, abs=2e-3)
    assert sonar.reading.distance == pytest.approx(distance, abs=2e-3)


def test_ir_range_limits_and_response_curve():
    world = robot_facing_wall(2.0)
    ir = IRDistance(world, "bot", response=((0.1, 2.6), (0.8, 0.4)))  # volts, Sharp GP2D12-like
    world.run(0.1)
    assert ir.reading.distance == 0.8 and ir.reading.value == pytest.approx(0.4)
    near = robot_facing_wall(0.05)
    ir = IRDistance(near, "bot", response=((0.1, 2.6), (0.8, 0.4)))
    near.run(0.1)
    assert ir.reading.distance == 0.1 and ir.reading.value == pytest.approx(2.6)


@needs_gl
def test_webcam_renders_what_is_in_front():
    world = World()
    world.insert(Ground(name="ground"))
    world.insert(Box(name="red", dimensions=(0.5, 0.5, 0.5), color=(1, 0, 0, 1), pose=Pose((1.5, 0, 0.25))))
    world.insert(Camera(name="cam", eye=(0.0, 0.0, 0.25), target=(1.5, 0.0, 0.25)))
    cam = Webcam(world, "cam", width=64, height=48, depth=True, rate=0)
    world.step(1)
    frame = cam.reading
    assert frame.rgb.shape == (48, 64, 3) and frame.rgb.dtype == np.uint8
    centre = frame.rgb[24, 32].astype(int)
    assert centre[0] > 120 and centre[0] > 2 * centre[1] and centre[0] > 2 * centre[2]  # the red box
    assert frame.depth[24, 32] == pytest.approx(1.25, abs=0.02)  # its front face


@needs_gl
def test_stereo_rig_sees_with_parallax():
    world = World()
    world.insert(Ground(name="ground"))
    world.insert(Box(name="post", dimensions=(0.1, 0.1, 1.0), color=(0, 0, 1, 1), pose=Pose((1.0, 0, 0.5))))
    world.insert(StereoRig(name="eyes", baseline=0.2, resolution=(96, 64), pose=Pose((0, 0, 0.5))))
    stereo = StereoCamera(world, "eyes", rate=0)
    world.step(1)
    frame = stereo.reading
    blue = [np.flatnonzero((f.rgb[32, :, 2] > 100) & (f.rgb[32, :, 0] < 60)).mean() for f in (frame.left, frame.right)]
    assert blue[0] > blue[1] + 5  # the post appears further right in the left eye


def test_camera_without_gl_reports_how_to_fix(monkeypatch):
    import mujoco

    def broken(*args, **kwargs):
        raise RuntimeError("gladLoadGL error")

    world = World()
    world.insert(Camera(name="cam"))
    cam = Webcam(world, "cam", rate=0)
    monkeypatch.setattr(mujoco, "Renderer", broken)
    with pytest.raises(SimrunError, match="MUJOCO_GL=egl"):
        world.step(1)
    assert cam.reading is None and cam.samples == 0


def test_range_cone_validation_defaults_noise_and_min_range():
    world = robot_facing_wall(0.5)
    with pytest.raises(EntityError, match="range cone: 0 <= min_range < max_range"):
        IRDistance(world, "bot", min_range=1.0, max_range=0.5)
    with pytest.raises(EntityError, match="range cone"):
        Sonar(world, "bot", rays=0)
    with pytest.raises(EntityError, match="range cone"):
        Sonar(world, "bot", cone_deg=-1.0)
    with pytest.raises(EntityError, match="exclude must be one of"):
        IRDistance(world, "bot", exclude="chassis")
    assert world.controllers == []  # a refused sensor is not left running
    ir, sonar = IRDistance(world, "bot"), Sonar(world, "bot")
    assert (ir.min_range, ir.max_range, len(ir._local)) == (0.1, 0.8, 9)  # 3 x 3 rays over 2 degrees
    assert (sonar.min_range, sonar.max_range, len(sonar._local)) == (0.02, 4.0, 49)
    noisy = IRDistance(world, "bot", noise=0.01, seed=4)
    world.run(0.1)
    assert noisy.reading.distance != ir.reading.distance
    assert noisy.reading.distance == pytest.approx(0.5, abs=0.05)


def test_range_cone_direction_offset_and_cone_in_the_body_frame():
    world = World()
    world.insert(Ground(name="ground"))
    world.insert(BoeBot(name="bot", pose=Pose((0, 0, 0.001), (np.cos(np.pi / 4), 0, 0, np.sin(np.pi / 4)))))  # faces +Y
    world.insert(Box(name="north", dimensions=(2.0, 0.1, 1.0), pose=Pose((0, 1.05, 0.5))))
    world.insert(Box(name="post", dimensions=(0.05, 0.05, 1.0), pose=Pose((0.25, 0.6, 0.5))))
    ahead = IRDistance(world, "bot", offset=(0.0, 0.0, 0.2), max_range=2.0, min_range=0.0, cone_deg=0.0, rays=1)
    left = RangeCone(world, "bot", offset=(0.1, 0.0, 0.2), direction=(0.0, 1.0, 0.0), max_range=3.0)
    wide = RangeCone(world, "bot", offset=(0.0, 0.0, 0.6), cone_deg=60.0, rays=9, max_range=2.0)  # high: no floor
    world.run(0.1)
    y = world.body("bot").xpos[1]
    assert ahead.reading.distance == pytest.approx(1.0 - y, abs=5e-3)  # the north wall, straight ahead (+Y)
    assert left.reading.distance == 3.0  # the robot's left is world -X: nothing there
    # the post 0.25 m to the side is 22.6 degrees off the heading: inside the 60 degree cone, nearer than the wall
    assert wide.reading.distance == pytest.approx(np.hypot(0.25 - 0.025, 0.6 - y), abs=0.03)


def test_stereo_rig_cameras_sit_a_baseline_apart_and_look_along_x():
    world = World()
    world.insert(
        StereoRig(name="eyes", baseline=0.2, fov=50.0, fov_axis="vertical", resolution=(64, 48), pose=Pose((0, 0, 0.5)))
    )
    model, data = world.model, world.data
    left, right = model.camera("eyes/left"), model.camera("eyes/right")
    np.testing.assert_allclose(left.pos, [0, 0.1, 0])
    np.testing.assert_allclose(right.pos, [0, -0.1, 0])
    assert left.fovy[0] == 50.0 and right.fovy[0] == 50.0 and tuple(model.cam_resolution[left.id]) == (64, 48)
    view = data.cam_xmat[left.id].reshape(3, 3)
    np.testing.assert_allclose(-view[:, 2], [1, 0, 0], atol=1e-9)  # MuJoCo cameras look along their -Z
    np.testing.assert_allclose(view[:, 1], [0, 0, 1], atol=1e-9)  # image up is world up
    with pytest.raises(EntityError, match="is not a StereoRig"):
        world.insert(Box(name="crate"))
        StereoCamera(world, "crate")
    with pytest.raises(EntityError, match="baseline must be a positive number"):
        bad = World()
        bad.insert(StereoRig(name="x", baseline=0.0))
        bad.compile()


def test_cone_rays_spread_over_the_cone():
    world = World()
    world.insert(Ground(name="ground"))
    world.insert(BoeBot(name="bot", pose=Pose((0, 0, 0.001))))
    world.insert(Box(name="wall", dimensions=(0.1, 4.0, 2.0), pose=Pose((2.05, 0, 1.0))))
    azimuth = np.radians(10.0)
    post = (np.cos(azimuth), np.sin(azimuth))
    world.insert(Box(name="post", dimensions=(0.02, 0.02, 2.0), pose=Pose((post[0], post[1], 1.0))))
    straight = RangeCone(world, "bot", offset=(0.0, 0.0, 0.5), max_range=3.0, rate=0)  # one ray, dead ahead
    three = RangeCone(world, "bot", offset=(0.0, 0.0, 0.5), cone_deg=20.0, rays=3, max_range=3.0, rate=0)
    two = RangeCone(world, "bot", offset=(0.0, 0.0, 0.5), cone_deg=20.0, rays=2, max_range=3.0)
    assert len(straight._local) == 1 and len(three._local) == 9 and len(two._local) == 4
    world.run(0.1)
    body = world.body("bot")
    rotation = body.xmat.reshape(3, 3)
    origin, ahead = body.xpos + rotation @ [0.0, 0.0, 0.5], rotation[:, 0]
    assert straight.reading.distance == pytest.approx((2.0 - origin[0]) / ahead[0], abs=1e-3)  # the wall's face
    # the ray at +10 degrees in the horizontal plane meets the post's near face
    assert three.reading.distance == pytest.approx((post[0] - 0.01 - origin[0]) / np.cos(azimuth), abs=0.01)
    assert two.reading.distance < 1.2  # the corner rays at +-10 degrees: one finds the post
    assert straight.seed == 0 and IRDistance(world, "bot").seed == 0


def test_webcam_on_a_rig_camera_takes_the_rig_as_its_entity():
    world = World()
    world.insert(StereoRig(name="eyes", pose=Pose((0, 0, 0.5))))
    cam = Webcam(world, "eyes/left", rate=0)
    assert cam.entity == "eyes" and cam.eye.camera == "eyes/left" and cam.eye.depth is False


@needs_gl
def test_cameras_reuse_their_renderer_and_render_depth_for_both_eyes():
    world = World()
    world.insert(Ground(name="ground"))
    world.insert(Box(name="post", dimensions=(0.1, 0.1, 1.0), pose=Pose((1.0, 0, 0.5))))
    world.insert(StereoRig(name="eyes", baseline=0.2, resolution=(32, 24), pose=Pose((0, 0, 0.5))))
    stereo = StereoCamera(world, "eyes", depth=True, rate=0)
    plain = Webcam(world, "eyes/left", width=32, height=24, rate=0)
    world.step(1)
    renderer = stereo.left._renderer
    world.step(1)
    assert stereo.left._renderer is renderer  # one context per camera, not one per frame
    assert stereo.rate == 0.0 and StereoCamera(world, "eyes").rate == 15.0
    assert stereo.reading.left.time == pytest.approx(world.time - 0.002)  # taken before the last step
    assert plain.reading.time == pytest.approx(world.time - 0.002)
    assert stereo.reading.left.depth is not None and stereo.reading.right.depth is not None
    for eye in (stereo.reading.left, stereo.reading.right):
        assert eye.depth[12].min() == pytest.approx(0.95, abs=0.05)  # the post's near face, in both eyes
    assert plain.reading.depth is None


@needs_gl
def test_a_webcam_follows_its_world_through_rebuilds_and_nested_rigs():
    """A rig mounted on a robot: camera ``bot/rig/left`` belongs to entity ``bot/rig``. After the world is
    rebuilt (a red box added in view) the next frame shows the new scene, from a renderer for the new model."""
    world = World()
    world.insert(Ground(name="ground"))
    world.insert(BoeBot(name="bot", pose=Pose((0, 0, 0.001))))
    world.insert(StereoRig(name="rig", parent="bot", pose=Pose((0.0, 0.0, 0.15))))
    cam = Webcam(world, "bot/rig/left", width=32, height=24, rate=0)
    assert cam.entity == "bot/rig"
    world.step(1)
    before = cam.reading.rgb[12, 16].astype(int)
    world.insert(Box(name="red", dimensions=(0.2, 1.0, 0.5), color=(1, 0, 0, 1), pose=Pose((0.6, 0, 0.25))))
    world.step(1)
    after = cam.reading.rgb[12, 16].astype(int)
    assert not (before[0] > 2 * before[1]) and after[0] > 120 and after[0] > 2 * after[1]


@needs_gl
def test_stereo_camera_defaults():
    world = World()
    world.insert(Ground(name="ground"))
    world.insert(StereoRig(name="rig", pose=Pose((0, 0, 0.3)), resolution=(32, 24)))
    stereo = StereoCamera(world, "rig", rate=0)
    world.step(1)
    frame = stereo.reading
    assert frame.time == 0.0 and frame.left.depth is None and frame.right.depth is None
