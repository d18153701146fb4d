"""Articulated arms and the arm service, including an arm on a driving mobile base."""

import numpy as np
import pytest

from simrun import EntityError, Ground, Pose, World
from simrun.arm import ArmJoint, ArmService, ArticulatedArm, KukaLBR3, LynxL6, Segment
from simrun.drive import Pioneer3DX
from simrun.drive_service import DriveService


def test_kuka_moves_to_a_joint_target():
    world = World()
    world.insert(Ground(name="ground"))
    world.insert(KukaLBR3(name="kuka"))
    arm = ArmService(world, "kuka")
    assert arm.joints == [f"kuka/link{k}" for k in range(1, 8)]
    target = [0.5, 0.4, -0.3, -0.8, 0.2, 0.5, 0.1]
    arm.move_to(target, duration=2.0)
    world.run(1.0)
    halfway = np.array(arm.joint_states().positions)
    assert np.all(np.abs(halfway) < np.abs(target) + 1e-6) and arm.busy  # still on its way
    assert world.run_until(lambda: not arm.busy, timeout=5.0)
    world.run(1.0)
    np.testing.assert_allclose(arm.joint_states().positions, target, atol=0.005)
    assert world.warnings() == {}


def test_locked_free_spring_and_limits():
    arm = ArticulatedArm(
        name="arm",
        segments=(
            Segment("fixed", 0.1, joint=ArmJoint(locked=True)),
            Segment("passive", 0.2, joint=ArmJoint(axis=(0, 1, 0), drive="none", spring=20.0, spring_ref=0.3)),
            Segment("limited", 0.1, joint=ArmJoint(axis=(0, 1, 0), limits=(-0.2, 0.2), kp=20)),
        ),
    )
    world = World()
    world.insert(arm)
    service = ArmService(world, "arm")
    assert service.joints == ["arm/passive", "arm/limited"]
    assert world.model.nu == 1  # only the limited joint has a servo
    service.set_joint_targets([0.0, 1.0])  # beyond the limit
    world.run(3.0)
    passive, limited = service.joint_states().positions
    assert passive == pytest.approx(0.3, abs=0.02)  # the spring pulls it to its rest angle
    assert limited == pytest.approx(0.2, abs=0.01)  # clamped by the joint limit
    with pytest.raises(EntityError, match="has 2 joints, got 3"):
        service.set_joint_targets([0, 0, 0])


def test_arm_on_a_mobile_base_and_the_base_still_drives():
    world = World()
    world.insert(Ground(name="ground"))
    world.insert(Pioneer3DX(name="base", pose=Pose((0, 0, 0.001))))
    world.insert(LynxL6(name="arm", parent="base", pose=Pose((0.1, 0, 0.22))))
    drive = DriveService(world, "base")
    arm = ArmService(world, "base/arm")
    world.run(0.5)
    start = world.body("base").xpos.copy()
    target = [0.5, 0.3, 0.6, -0.4, 0.2, 0.01]
    drive.drive_distance(0.5, power=0.5)
    arm.move_to(target, duration=2.0)
    assert world.run_until(lambda: not drive.busy and not arm.busy, timeout=20)
    world.run(1.0)
    assert np.linalg.norm(world.body("base").xpos - start) == pytest.approx(0.5, abs=0.02)
    np.testing.assert_allclose(arm.joint_states().positions, target, atol=0.01)
    assert world.model.body("base/arm").parentid[0] == world.model.body("base").id
    with pytest.raises(EntityError, match="not an articulated arm"):
        ArmService(world, "base")
