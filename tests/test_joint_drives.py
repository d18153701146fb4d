"""Targets within what the robot can do (simrun/services/joint_drives.py, issue 42): on every kind of robot with
joints (a built-in arm, an MJCF robot, a URDF robot, a model of every actuator kind written here), a target
outside the joint's range or what its actuator reaches is refused with one line naming the joint, the value
and the range; a target inside is reached. Ground truth: MuJoCo's compiled model (``jnt_range``,
``actuator_ctrlrange``, ``actuator_actrange``) for the ranges, ``data.qpos`` for where the joints went.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from simrun import EntityError, Ground, Pose, UrdfRobot, World, WorldOptions, load_scene
from simrun.robots.arm_service import ArmService
from simrun.robots.mjcf_robot import MjcfRobot
from simrun.services.joint_service import JointService

FIXTURES = Path(__file__).resolve().parent.parent / "fixtures"
#: The one-line refusal: call, joint, value, unit, the range and what sets it.
REFUSAL = re.compile(
    r"^(\w+)(?:: point \d+)?: joint '([\w/]+)' target (\S+) (rad|m) is outside \[(\S+), (\S+)\] \4 \((.+)\); give"
)


def mjcf_arm() -> tuple[World, JointService]:
    world = World(base_dir=FIXTURES / "mjcf" / "arm")  # no ground: the arm's base is fixed, it may swing down
    world.insert(MjcfRobot(name="arm", file="arm.xml"))
    return world, JointService(world, "arm")


def urdf_arm() -> tuple[World, JointService]:
    world = World(base_dir=FIXTURES / "urdf")
    world.insert(Ground(name="ground"))
    urdf = "tiny_arm_description/urdf/tiny_arm.urdf"
    world.insert(UrdfRobot(name="arm", urdf=urdf, actuators=True, pose=Pose((0, 0, 0.3))))
    return world, JointService(world, "arm")


def qpos(world: World, joint: str) -> float:
    return float(world.joint(joint).qpos[0])


def joint_range(world: World, joint: str) -> tuple[float, float]:
    model = world.model
    j = model.joint(joint).id
    assert model.jnt_limited[j]
    low, high = model.jnt_range[j]
    return float(low), float(high)


def refused(call: object, *args: object) -> re.Match[str]:
    with pytest.raises(EntityError) as caught:
        call(*args)  # type: ignore[operator]
    message = str(caught.value)
    assert "\n" not in message
    found = REFUSAL.match(message)
    assert found, message
    return found


@pytest.mark.parametrize("robot", ["mjcf", "urdf"])
def test_imported_robots_refuse_targets_past_their_joint_ranges_and_reach_those_inside(robot: str) -> None:
    world, service = mjcf_arm() if robot == "mjcf" else urdf_arm()
    joint = "shoulder"
    low, high = joint_range(world, f"arm/{joint}")
    for bad in (high + 0.01, low - 0.01, 1e6, -1e300):
        found = refused(service.set_positions, [joint], [bad])
        assert found.group(1, 2, 4) == ("set_positions", joint, "rad")
        assert float(found.group(3)) == pytest.approx(bad)
        assert float(found.group(5)) >= low - 1e-9 and float(found.group(6)) <= high + 1e-9
    refused(service.move_to, [joint], [high + 0.5], 1.0)
    refused(service.trajectory, [joint, "elbow"], [0.5, 1.0], [0.1, 0.1, high + 0.5, 0.0])
    assert service.state().targets[service.state().names.index(joint)] != high + 0.5  # nothing was applied
    inside = 0.6 * high
    service.set_positions([joint], [inside])
    world.run(3.0)
    assert qpos(world, f"arm/{joint}") == pytest.approx(inside, abs=0.01)
    assert world.warnings() == {}


def test_an_mjcf_servo_whose_ctrlrange_is_narrower_than_its_joint_refuses_what_it_cannot_reach() -> None:
    """arm.xml's yaw: joint range +-170 degrees (2.967 rad), position servo ctrlrange +-2.96."""
    world, service = mjcf_arm()
    _, high = joint_range(world, "arm/yaw")
    control = float(world.model.actuator_ctrlrange[_actuator_of(world, "arm/yaw")][1])
    assert control < high  # the fixture's premise
    found = refused(service.set_positions, ["yaw"], [0.5 * (control + high)])  # in the joint's range, past the servo
    assert float(found.group(6)) == pytest.approx(control) and "ctrlrange" in found.group(7)
    service.set_positions(["yaw"], [control])
    world.run(3.0)
    assert qpos(world, "arm/yaw") == pytest.approx(control, abs=0.01)


def _actuator_of(world: World, joint: str) -> int:
    model = world.model
    j = model.joint(joint).id
    return next(a for a in range(model.nu) if int(model.actuator_trnid[a, 0]) == j)


def test_a_built_in_arm_refuses_targets_past_its_limits() -> None:
    """The Lynx L6 on a Pioneer (fixtures/scenes/arm_on_base.toml) through its ArmService."""
    world = load_scene(FIXTURES / "scenes" / "arm_on_base.toml")
    arm = world.service("ArmService", "base/arm")
    assert isinstance(arm, ArmService)
    _, high = joint_range(world, "base/arm/elbow")
    start = list(arm.joint_states().positions)
    index = arm.joints.index("base/arm/elbow")
    bad = list(start)
    bad[index] = high + 0.2
    found = refused(arm.set_joint_targets, bad)
    assert found.group(2) == "elbow" and float(found.group(6)) == pytest.approx(high)
    refused(arm.move_to, bad, 1.0)
    good = list(start)
    good[index] = 0.7 * high
    arm.move_to(good, 1.0)
    world.run(3.0)
    assert qpos(world, "base/arm/elbow") == pytest.approx(0.7 * high, abs=0.02)


def test_every_actuator_kind_has_its_range_and_a_velocity_stops_at_the_joint_limit(tmp_path: Path) -> None:
    """The model of every actuator kind (tests/test_joint_service.py): ranges from MuJoCo's own fields."""
    from test_joint_service import KINDS_XML

    (tmp_path / "kinds.xml").write_text(KINDS_XML)
    world = World(WorldOptions(gravity=(0.0, 0.0, 0.0)), base_dir=tmp_path)
    world.insert(MjcfRobot(name="k", file="kinds.xml"))
    service = JointService(world, "k")
    model = world.model
    # intvel: joint range +-100 degrees, actrange [-2, 2] (gear 1): the joint's range is the narrower
    found = refused(service.set_positions, ["intvel"], [1.8])
    assert float(found.group(6)) == pytest.approx(float(model.jnt_range[model.joint("k/intvel").id][1]))
    # the slide: +-0.2 m
    found = refused(service.set_positions, ["slide"], [0.25])
    assert found.group(4) == "m" and (found.group(5), found.group(6)) == ("-0.2", "0.2")
    # unlimited joints: the documented bound
    from simrun.services.joint_drives import MAX_SPEED, MAX_TARGET

    assert "1e+06" in refused(service.set_positions, ["motor"], [2 * MAX_TARGET]).group(7)
    with pytest.raises(EntityError, match=r"joint 'vel' velocity 1e\+300 rad/s is outside"):
        service.set_velocities(["vel"], [1e300])
    assert MAX_SPEED < 1e300
    # a velocity on the slide runs its target to the end of the range and stops there
    service.set_velocities(["slide"], [0.5])
    world.run(2.0)
    state = service.state()
    assert state.targets[state.names.index("slide")] == 0.2
    assert qpos(world, "k/slide") == pytest.approx(0.2, abs=0.005)
    assert world.warnings() == {}


def test_a_velocity_servo_refuses_speeds_past_its_ctrlrange(tmp_path: Path) -> None:
    (tmp_path / "v.xml").write_text(
        '<mujoco><worldbody><body><joint name="j" axis="0 1 0"/><geom size=".1"/></body></worldbody>'
        '<actuator><velocity joint="j" kv="5" gear="2" ctrlrange="-1 1"/></actuator></mujoco>'
    )
    world = World(WorldOptions(gravity=(0.0, 0.0, 0.0)), base_dir=tmp_path)
    world.insert(MjcfRobot(name="v", file="v.xml"))
    service = JointService(world, "v")
    with pytest.raises(EntityError, match=r"joint 'j' velocity 0.6 rad/s is outside \[-0.5, 0.5\] rad/s"):
        service.set_velocities(["j"], [0.6])
    service.set_velocities(["j"], [0.4])
    world.run(1.0)
    start = qpos(world, "v/j")
    world.run(1.0)
    assert qpos(world, "v/j") - start == pytest.approx(0.4, abs=0.02)


@pytest.mark.parametrize("robot", ["mjcf", "urdf"])
def test_a_target_a_hair_past_the_range_is_clamped_to_it_and_one_past_the_slack_refused(robot: str) -> None:
    """A joint at its limit reads a hair outside it (MuJoCo's limits are soft); sent back, it is the range's end."""
    world, service = mjcf_arm() if robot == "mjcf" else urdf_arm()
    found = refused(service.set_positions, ["shoulder"], [1e3])  # the range the drive allows, as it says it
    low, high = float(found.group(5)), float(found.group(6))
    joint_low, joint_high = joint_range(world, "arm/shoulder")
    assert joint_low <= low < high <= joint_high
    slack = 1e-3 * min(high - low, 1.0)  # docs/limits.md
    for given, taken in ((low - 4e-21, low), (high + 0.5 * slack, high), (0.25 * high, 0.25 * high)):
        service.set_positions(["shoulder"], [given])
        assert service.state().targets[service.state().names.index("shoulder")] == pytest.approx(taken, abs=1e-9)
    for bad in (low - 2 * slack, high + 2 * slack):
        refused(service.set_positions, ["shoulder"], [bad])
        refused(service.trajectory, ["shoulder"], [0.5], [bad])
        refused(service.trajectory, ["shoulder"], [0.5, 1.0], [low - 0.5 * slack, bad])  # the hair is not the end
    service.trajectory(["shoulder"], [0.5, 1.0], [high + 0.5 * slack, low - 0.5 * slack])
    world.run(1.5)
    assert service.state().targets[service.state().names.index("shoulder")] == low  # the last point, clamped
    assert qpos(world, "arm/shoulder") == pytest.approx(low, abs=0.05)


def test_a_built_in_arm_takes_back_the_joint_positions_it_reads() -> None:
    """What a client does (tests/test_serve_scenes.py): read joint_states, change one joint, send them all back."""
    world = load_scene(FIXTURES / "scenes" / "arm_on_base.toml")
    arm = world.service("ArmService", "base/arm")
    assert isinstance(arm, ArmService)
    world.run(0.5)
    read = list(arm.joint_states().positions)
    fingers = [i for i, name in enumerate(arm.joints) if "finger" in name]
    assert fingers
    for i in fingers:  # closed fingers sit at (or a hair past) the low end of their slide
        low, _ = joint_range(world, arm.joints[i])
        read[i] = low - 1e-12
    read[arm.joints.index("base/arm/yaw") if "base/arm/yaw" in arm.joints else 0] += 0.4
    arm.move_to(read, 1.0)
    world.run(1.5)
    for i in fingers:
        low, _ = joint_range(world, arm.joints[i])
        assert qpos(world, arm.joints[i]) == pytest.approx(low, abs=1e-3)
