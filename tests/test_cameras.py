"""Range cones and cameras. Rendering tests skip, with the reason, only where no OpenGL context starts."""

import numpy as np
import pytest
from conftest import needs_gl

from simrun import Box, Camera, Ground, Pose, World
from simrun.cameras import IRDistance, Sonar, StereoCamera, StereoRig, Webcam
from simrun.drive import BoeBot
from simrun.errors import SimrunError


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
