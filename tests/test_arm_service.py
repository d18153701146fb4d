"""ArmService is a JointService (issue 37): the built-in arms are served by JointService's code path behind the
arm's own names. Ground truth: the simulator's joints and controls, and a saved scene's bindings."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from simrun import Ground, World, load_scene, save_scene
from simrun.robots.arm import ArmJoint, ArticulatedArm, KukaLBR3, LynxL6, Segment
from simrun.robots.arm_service import ArmService
from simrun.services.joint_service import JointService


def test_the_arm_service_is_a_joint_service_of_the_arm_behind_the_arms_names() -> None:
    world = World()
    world.insert(KukaLBR3(name="kuka"))
    arm = ArmService(world, "kuka")
    inner = arm.joint_service
    assert isinstance(inner, JointService) and inner.name == "kuka"
    assert (inner.profile, inner.integral, inner.hold_mode, inner.period) == ("cosine", False, "all", 0.02)
    assert inner.joints() == tuple(f"link{k}" for k in range(1, 8))
    assert arm in world.controllers and inner not in world.controllers  # one controller: the arm's service
    arm.move_to([0.3, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], 1.0)
    assert arm.busy and inner.busy
    assert inner.state().targets[0] == 0.0  # the move starts from the held pose
    world.run(1.1)
    assert not arm.busy
    assert world.data.ctrl[world.model.actuator("kuka/link1").id] == 0.3
    # the JointService's own commands move the same arm (joints without the prefix)
    inner.set_positions(["link2"], [0.2])
    world.run(1.5)
    assert arm.joint_states().positions[1] == pytest.approx(0.2, abs=0.005)
    assert arm.joint_states().positions[0] == pytest.approx(0.3, abs=0.005)


def test_a_saved_scene_holds_one_arm_service_binding(tmp_path: Path) -> None:
    world = World()
    world.insert(Ground(name="ground"))
    world.insert(LynxL6(name="arm"))
    ArmService(world, "arm")
    save_scene(world, tmp_path / "scene.toml")
    loaded = load_scene(tmp_path / "scene.toml")
    assert loaded.services == [{"type": "ArmService", "entity": "arm"}]


def test_velocity_driven_and_passive_joints_keep_their_meaning() -> None:
    """A velocity joint's value is a speed (in ``set_joint_targets`` and ``move_to``), a passive one's ignored."""
    arm = ArticulatedArm(
        name="a",
        segments=(
            Segment("spin", 0.1, joint=ArmJoint(drive="velocity", kv=20.0, damping=0.0)),
            Segment("swing", 0.1, joint=ArmJoint(axis=(0, 1, 0), drive="none")),
            Segment("lift", 0.1, joint=ArmJoint(axis=(0, 1, 0), kp=30.0)),
        ),
    )
    world = World()
    world.insert(arm)
    service = ArmService(world, "a")
    assert service.joints == ["a/spin", "a/swing", "a/lift"]
    service.move_to([0.5, 9.0, 0.4], 1.0)
    world.run(1.5)
    before = float(world.data.joint("a/spin").qpos[0])
    world.run(1.0)
    assert float(world.data.joint("a/spin").qpos[0]) - before == pytest.approx(0.5, rel=0.02)  # rad/s
    assert float(world.data.joint("a/lift").qpos[0]) == pytest.approx(0.4, abs=0.01)


def test_an_old_style_snapshot_restores_a_move() -> None:
    """``{"move": [t0, duration, start, goal], "next_time": t}`` (the arm service's snapshot before it was a
    JointService) still restores: the move continues from its start time."""
    world = World()
    world.insert(KukaLBR3(name="k"))
    arm = ArmService(world, "k")
    world.run(0.2)
    state = {"move": [0.2, 1.0, [0.0] * 7, [0.5, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]], "next_time": arm.next_time}
    arm.restore(state)
    assert arm.busy
    world.run(0.5)  # the tick at 0.68 s: u = 0.48 of the cosine
    u = (world.time - 0.02 - 0.2) / 1.0
    expected = 0.5 * (0.5 - 0.5 * np.cos(np.pi * u))
    assert world.data.ctrl[world.model.actuator("k/link1").id] == pytest.approx(expected, abs=1e-12)
    assert arm.snapshot()["move"][:2] == [0.2, 1.0]
