"""JointService holds the joints it does not command (``hold = "all"``, the default) or leaves them to the model
(``hold = "commanded"``); wheel joints stay the DriveService's. Ground truth: the simulator's joint positions."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from simrun import EntityError, Ground, Pose, UrdfRobot, World
from simrun.robots.mjcf_robot import MjcfRobot
from simrun.services.drive_service import DriveService
from simrun.services.joint_service import JointService

FIXTURES = Path(__file__).resolve().parent.parent / "fixtures"
#: The tiny URDF arm raised 0.3 m and started bent, so gravity pulls each joint away from where it is.
BENT = {"shoulder": 0.7, "elbow": -0.6}


def _urdf_arm() -> World:
    world = World(base_dir=FIXTURES / "urdf")
    world.insert(Ground(name="ground"))
    arm = UrdfRobot(name="arm", urdf="tiny_arm_description/urdf/tiny_arm.urdf", actuators=True, pose=Pose((0, 0, 0.3)))
    world.insert(arm)
    return world


def _bend(world: World) -> None:
    model, data = world.model, world.data
    for joint, value in BENT.items():
        data.qpos[model.joint(f"arm/{joint}").qposadr[0]] = value


def _kinds_world(tmp_path: Path) -> World:
    from test_joint_service import KINDS_XML

    (tmp_path / "kinds.xml").write_text(KINDS_XML)
    world = World(base_dir=tmp_path)
    world.insert(Ground(name="ground"))
    world.insert(MjcfRobot(name="k", file="kinds.xml", pose=Pose((0, 0, 0.5))))
    return world


def test_a_urdf_arm_holds_every_joint_it_is_not_told_to_move() -> None:
    """Only the slide is commanded; shoulder and elbow stay where they were (1 mrad) instead of folding."""
    for hold, folds in (("all", False), ("commanded", True)):
        world = _urdf_arm()
        _bend(world)
        service = JointService(world, "arm", hold=hold)
        service.set_positions(["slide"], [0.02])
        world.run(3.0)
        for joint, start in BENT.items():
            moved = abs(float(world.joint(f"arm/{joint}").qpos[0]) - start)
            if not folds:
                assert moved < 1e-3, (hold, joint)
            elif joint == "elbow":  # the shoulder turns about z: gravity does not move it
                assert moved > 0.5, (hold, joint)  # limp: gravity takes it (measured: 2.03 rad)
        if not folds:  # folded, the arm's weight bears on the slide too
            assert world.joint("arm/slide").qpos[0] == pytest.approx(0.02, abs=0.002)
        assert math.isnan(service.state().targets[0])  # held, not commanded
        assert world.warnings() == {}


def test_every_actuator_kind_holds_its_joint_under_gravity(tmp_path: Path) -> None:
    """Nothing commanded: motor, velocity servo, position servo, integrated velocity servo and slide stay put."""
    world = _kinds_world(tmp_path)
    model, data = world.compile()
    starts = {"motor": 0.4, "vel": -0.3, "pos": 0.2, "intvel": 0.5, "slide": 0.05}
    for joint, value in starts.items():
        data.qpos[model.joint(f"k/{joint}").qposadr[0]] = value
    service = JointService(world, "k")
    world.run(4.0)
    for joint, value in starts.items():
        assert float(world.joint(f"k/{joint}").qpos[0]) == pytest.approx(value, abs=0.005), joint
    world.reset()  # held again from the reset's state (all at 0)
    world.run(2.0)
    for joint in starts:
        assert float(world.joint(f"k/{joint}").qpos[0]) == pytest.approx(0.0, abs=0.005), joint
    assert service.hold_mode == "all"


def test_a_joint_commanded_later_leaves_the_hold() -> None:
    world = _urdf_arm()
    service = JointService(world, "arm")
    world.run(0.5)
    service.set_positions(["shoulder"], [-0.5])
    world.run(3.0)
    assert world.joint("arm/shoulder").qpos[0] == pytest.approx(-0.5, abs=0.005)
    assert world.joint("arm/elbow").qpos[0] == pytest.approx(0.0, abs=1e-3)  # still held at its start


def test_wheels_are_left_to_the_drive_service() -> None:
    world = World(base_dir=FIXTURES / "mjcf" / "diffbot")
    world.insert(Ground(name="ground"))
    world.insert(MjcfRobot(name="bot", file="diffbot.xml", wheels=("left", "right"), stall_torque=2.0))
    drive = DriveService(world, "bot")
    JointService(world, "bot")
    start = world.body("bot/chassis").xpos.copy()
    drive.drive_distance(0.5, 0.5)
    assert world.run_until(lambda: not drive.busy, 20.0)
    moved = world.body("bot/chassis").xpos - start
    assert math.hypot(moved[0], moved[1]) == pytest.approx(0.5, abs=0.01)


def test_an_unknown_hold_mode_is_refused() -> None:
    with pytest.raises(EntityError, match="hold must be one of all, commanded, got 'some'"):
        JointService(_urdf_arm(), "arm", hold="some")


def test_the_wheels_of_a_built_in_drive_are_not_held() -> None:
    """A JointService on a Pioneer leaves its wheels to the DriveService: 0.5 m as the simulator's chassis says."""
    from simrun.robots.catalogue import Pioneer3DX

    world = World()
    world.insert(Ground(name="ground"))
    world.insert(Pioneer3DX(name="base"))
    drive = DriveService(world, "base")
    service = JointService(world, "base")
    start = world.body("base").xpos.copy()
    drive.drive_distance(0.5, 0.5)
    assert world.run_until(lambda: not drive.busy, 20.0)
    moved = world.body("base").xpos - start
    assert math.hypot(moved[0], moved[1]) == pytest.approx(0.5, abs=0.01)
    assert service._wheels == {"left_wheel", "right_wheel"}
