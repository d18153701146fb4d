"""Articulated arms and the arm service, including an arm on a driving mobile base."""

import math

import mujoco
import numpy as np
import pytest

from simrun import Box, EntityError, Ground, Pose, World, WorldOptions
from simrun.robots.arm import ArmJoint, ArticulatedArm, KukaLBR3, LynxL6, Segment, SixDof
from simrun.robots.arm_service import ArmService
from simrun.robots.catalogue import Pioneer3DX
from simrun.services.drive_service import DriveService


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
    with pytest.raises(EntityError, match=r"joint 'limited' target 1 rad is outside \[-0.2, 0.2\] rad"):
        service.set_joint_targets([0.0, 1.0])  # beyond the limit: refused (issue 42)
    service.set_joint_targets([0.0, 0.2])  # at the limit
    world.run(3.0)
    passive, limited = service.joint_states().positions
    assert passive == pytest.approx(0.3, abs=0.02)  # the spring pulls it to its rest angle
    assert limited == pytest.approx(0.2, abs=0.01)  # at the joint limit
    with pytest.raises(EntityError, match="has 2 joints, got 3"):
        service.set_joint_targets([0, 0, 0])


def test_arm_on_a_mobile_base_and_the_base_still_drives():
    world = World()
    world.insert(Ground(name="ground"))
    world.insert(Pioneer3DX(name="base", pose=Pose((0, 0, 0.001))))
    world.insert(LynxL6(name="arm", parent="base", pose=Pose((0.1, 0, 0.237))))  # on the 0.237 m top
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


# -- issue 13: arms that behave like the real ones ---------------------------------------------------------------

ARMS = [KukaLBR3, LynxL6]


def joint_steps(arm_cls):
    """(index, step) for every commanded joint of a ready arm: 0.4 rad for hinges, 0.01 m for slides."""
    arm = arm_cls(name="a")
    steps = []
    for k, name in enumerate(arm.joint_names("a")):
        segment = next(s for s in arm.segments if f"a/{s.name}" == name)
        steps.append((k, 0.01 if segment.joint.kind == "slide" else 0.4))
    return steps


@pytest.mark.parametrize(
    ("arm_cls", "index", "step"),
    [(cls, k, step) for cls in ARMS for k, step in joint_steps(cls)],
    ids=[f"{cls.TYPE}-{k}" for cls in ARMS for k, _ in joint_steps(cls)],
)
def test_each_joint_steps_to_its_target_with_at_most_five_percent_overshoot(arm_cls, index, step):
    world = World()
    world.insert(Ground(name="ground"))
    world.insert(arm_cls(name="a"))
    service = ArmService(world, "a")
    name = service.joints[index]
    settle = service.servo_design()[name]["settling_time"]
    targets = [0.0] * len(service.joints)
    targets[index] = step
    service.set_joint_targets(targets)
    path = []
    for _ in range(round(max(1.5 * settle, 1.0) / 0.002)):
        world.step()
        path.append(float(world.data.joint(name).qpos[0]))  # the simulator's joint position
    path = np.array(path)
    assert path.max() <= step * 1.05  # overshoot <= 5 %
    assert path[-1] == pytest.approx(step, rel=0.02)  # settled within 1.5x the stated settling time
    assert world.warnings() == {}


def test_servo_design_is_critically_damped_and_states_a_settling_time():
    world = World()
    world.insert(KukaLBR3(name="k"))
    design = ArmService(world, "k").servo_design()
    assert set(design) == {f"k/link{i}" for i in range(1, 8)}
    for values in design.values():
        assert values["damping_ratio"] == pytest.approx(1.0)
        assert values["kv"] == pytest.approx(2 * np.sqrt(values["kp"] * values["inertia"]) - values["kp"] / 50)
        assert 0 < values["settling_time"] < 2.0
    # the base joint sees the whole stretched-out arm: more inertia than the wrist
    assert design["k/link1"]["inertia"] > 10 * design["k/link7"]["inertia"]


@pytest.mark.parametrize("arm_cls", ARMS)
def test_top_level_arm_links_never_touch_their_base_or_parent(arm_cls):
    world = World()
    world.insert(Ground(name="ground"))
    world.insert(arm_cls(name="a"))
    service = ArmService(world, "a")
    targets = [0.0] * len(service.joints)
    targets[0] = 1.0  # the old bug: a top-level arm's first link rubbed on its base and stopped short
    service.set_joint_targets(targets)
    world.run(3.0)
    assert world.data.joint(service.joints[0]).qpos[0] == pytest.approx(1.0, abs=0.005)
    model, data = world.model, world.data
    arm_bodies = {b for b in range(model.nbody) if model.body(b).name.startswith("a")}
    for i in range(data.ncon):
        c = data.contact[i]
        pair = {model.geom_bodyid[c.geom1], model.geom_bodyid[c.geom2]}
        assert not pair <= arm_bodies, [model.geom(c.geom1).name, model.geom(c.geom2).name]


def capsule_inertia_about_end(mass, length, radius):
    """Moment of inertia of a uniform capsule about a transverse axis through one end of its cylinder."""
    cylinder, spheres = np.pi * radius**2 * length, 4 / 3 * np.pi * radius**3
    mc, ms = mass * cylinder / (cylinder + spheres), mass * spheres / (cylinder + spheres)
    centre = mc * (length**2 / 12 + radius**2 / 4) + ms * (2 * radius**2 / 5 + length**2 / 4 + 3 * length * radius / 8)
    return centre + mass * (length / 2) ** 2


def test_a_passive_joint_swings_at_the_pendulum_period():
    mass, length, radius = 0.5, 0.3, 0.02
    arm = ArticulatedArm(
        name="pendulum",
        pose=Pose((0, 0, 1.0), (0.0, 1.0, 0.0, 0.0)),  # upside down: the link hangs from the base
        segments=(
            Segment("link", length, radius, mass, ArmJoint(axis=(0, 1, 0), drive="none", damping=0.0, armature=0.0)),
        ),
    )
    world = World()
    world.insert(arm)
    model = world.model
    assert model.body_gravcomp[model.body("pendulum/link").id] == 0.0  # off for a free joint
    world.data.joint("pendulum/link").qpos[0] = 0.1
    mujoco.mj_forward(model, world.data)
    angles, times = [], []
    for _ in range(2000):
        world.step()
        angles.append(float(world.data.joint("pendulum/link").qpos[0]))
        times.append(float(world.data.time))
    angles = np.array(angles)
    crossings = [
        times[k] - angles[k] * (times[k + 1] - times[k]) / (angles[k + 1] - angles[k])
        for k in range(len(angles) - 1)
        if angles[k] > 0 >= angles[k + 1]
    ]
    period = float(np.mean(np.diff(crossings)))
    expected = 2 * np.pi * np.sqrt(capsule_inertia_about_end(mass, length, radius) / (mass * 9.81 * length / 2))
    assert period == pytest.approx(expected, rel=0.01)
    assert angles.max() == pytest.approx(0.1, abs=0.005)  # it swings (no gravity compensation holds it)


def test_lynx_gripper_closes_both_fingers_and_holds_a_box_under_gravity():
    world = World(WorldOptions(gravity=(0.0, 0.0, 0.0)))
    world.insert(LynxL6(name="lynx"))
    wrist_top = 0.03 + 0.02 + 0.12 + 0.12 + 0.05 + 0.02
    world.insert(
        Box(name="box", dimensions=(0.016, 0.016, 0.016), mass=0.02, free=True, pose=Pose((0, 0, wrist_top + 0.025)))
    )
    arm = ArmService(world, "lynx")
    assert arm.joints[-1] == "lynx/finger_left" and len(arm.joints) == 6
    data = world.data
    for finger in ("finger_left", "finger_right"):
        data.joint(f"lynx/{finger}").qpos[0] = 0.012  # open
    mujoco.mj_forward(world.model, data)
    arm.set_joint_targets([0, 0, 0, 0, 0, 0.012])
    world.run(0.2)
    arm.set_joint_targets([0, 0, 0, 0, 0, 0.004])  # close on the 16 mm box
    world.run(1.0)
    left, right = (float(data.joint(f"lynx/{f}").qpos[0]) for f in ("finger_left", "finger_right"))
    assert left == pytest.approx(right, abs=2e-4)  # both fingers, mirrored
    assert 0.006 < left < 0.008  # stopped by the box: its inner face at the opening, the box half-width 0.008

    def in_hand():  # the box in the wrist frame (simulator poses)
        wrist = world.body("lynx/wrist_rotate")
        return wrist.xmat.reshape(3, 3).T @ (world.body("box").xpos - wrist.xpos)

    held = in_hand()
    world.model.opt.gravity[:] = (0.0, 0.0, -9.81)
    world.run(1.0)
    assert np.linalg.norm(in_hand() - held) < 0.001  # gravity on: it stays where the fingers hold it
    arm.move_to([0.8, 0.3, 0.3, 0, 0.5, 0.004], duration=1.0)  # swing it around
    world.run(1.5)
    moved = in_hand()
    # the move starts from the gripper's target, not from where the box stopped the fingers: the grip holds
    # through the swing (it once opened to the box's width and let it slide 7 mm down onto the wrist)
    assert np.linalg.norm(moved - held) < 0.001
    box = world.body("box").xpos.copy()
    arm.set_joint_targets([0.8, 0.3, 0.3, 0, 0.5, 0.015])  # open: it falls
    world.run(0.5)
    assert world.body("box").xpos[2] < box[2] - 0.05


def test_lynx_gripper_opens_wide_enough_to_approach_a_3_cm_object():
    # Lynxmotion's Little Grip opens to 1.25 in (31.75 mm, docs/robots.md): a 3 cm box fits between the open
    # fingers without touching them. Ground truth: the finger capsules' poses and sizes in the simulator and
    # its contact list.
    world = World(WorldOptions(gravity=(0.0, 0.0, 0.0)))
    world.insert(LynxL6(name="lynx"))
    wrist_top = 0.03 + 0.02 + 0.12 + 0.12 + 0.05 + 0.02
    world.insert(
        Box(name="box", dimensions=(0.02, 0.03, 0.02), mass=0.02, free=True, pose=Pose((0, 0, wrist_top + 0.025)))
    )
    arm = ArmService(world, "lynx")
    model, data = world.model, world.data
    opened = model.jnt_range[model.joint("lynx/finger_left").id][1]
    for finger in ("finger_left", "finger_right"):
        data.joint(f"lynx/{finger}").qpos[0] = opened
    mujoco.mj_forward(model, data)
    arm.set_joint_targets([0, 0, 0, 0, 0, opened])
    start = world.body("box").xpos.copy()
    fingers = {model.geom(f"lynx/{f}/geom").id for f in ("finger_left", "finger_right")}
    boxes = {g for g in range(model.ngeom) if model.geom_bodyid[g] == model.body("box").id}
    touches = 0
    for _ in range(250):
        world.step()
        pairs = [{data.contact[i].geom1, data.contact[i].geom2} for i in range(data.ncon)]
        touches += sum(bool(pair & fingers) and bool(pair & boxes) for pair in pairs)
    fingers = sorted(fingers)
    left, right = (data.geom_xpos[g] for g in fingers)
    gap = abs(left[1] - right[1]) - model.geom_size[fingers[0]][0] - model.geom_size[fingers[1]][0]
    assert gap == pytest.approx(0.03175, abs=2e-4)  # 1.25 in between the inner faces
    assert touches == 0 and np.linalg.norm(world.body("box").xpos - start) < 1e-4  # never pushed


def test_six_dof_joint_axes_are_locked_free_or_limited_with_drives_and_springs():
    joint = SixDof(
        x=ArmJoint(limits=(-0.05, 0.05), kp=400.0, max_force=100.0),  # driven slide, limited
        z=ArmJoint(drive="none", spring=200.0, spring_ref=0.02, damping=5.0),  # free slide with a spring
        rz=ArmJoint(drive="position", kp=20.0, limits=(-1.0, 1.0)),  # driven hinge
        ry=ArmJoint(drive="none", damping=0.5, limits=(-0.3, 0.3)),  # passive, limited
    )
    arm = ArticulatedArm(
        name="six",
        segments=(Segment("link", 0.2, 0.03, 1.0, joint),),
    )
    world = World(WorldOptions(gravity=(0.0, 0.0, 0.0)))
    world.insert(arm)
    service = ArmService(world, "six")
    assert service.joints == ["six/link/x", "six/link/z", "six/link/ry", "six/link/rz"]
    model = world.model
    assert model.njnt == 4 and model.nu == 2  # y and rx locked; two servos
    with pytest.raises(EntityError, match=r"joint 'link/x' target 0.2 m is outside \[-0.05, 0.05\] m"):
        service.set_joint_targets([0.2, 0.0, 0.0, 0.5])  # x beyond its limit: refused (issue 42)
    service.set_joint_targets([0.05, 0.0, 0.0, 0.5])  # x at its limit
    world.run(3.0)
    x, z, ry, rz = service.joint_states().positions
    assert x == pytest.approx(0.05, abs=0.002)  # at its limit
    assert z == pytest.approx(0.02, abs=0.001)  # the spring's rest position
    assert rz == pytest.approx(0.5, abs=0.01)
    assert abs(ry) < 0.01  # passive, nothing drives it (no gravity)
    body = world.body("six/link")
    np.testing.assert_allclose(body.xpos, [0.05, 0.0, 0.05 + 0.02], atol=0.003)  # ground truth: the body moved


def test_custom_arm_with_six_dof_and_gripper_round_trips_through_a_scene(tmp_path):
    from simrun import SceneError, load_scene, save_scene, scene_text

    path = tmp_path / "arm.toml"
    path.write_text(
        """
[[entities]]
type = "ArticulatedArm"
name = "arm"

[[entities.segments]]
name = "turret"
length = 0.1
joint = { axis = [0.0, 0.0, 1.0], limits = [-1.0, 1.0], kp = 30.0 }

[[entities.segments]]
name = "slider"
length = 0.2
joint = { x = { limits = [-0.05, 0.05], kp = 200.0 }, rz = { drive = "none", spring = 5.0 } }

[[entities.segments]]
name = "finger_a"
length = 0.03
radius = 0.005
mass = 0.01
joint = { axis = [0.0, 1.0, 0.0], kind = "slide", limits = [0.0, 0.02], kp = 100.0 }

[[entities.segments]]
name = "finger_b"
length = 0.03
radius = 0.005
mass = 0.01
parent = "slider"
joint = { axis = [0.0, -1.0, 0.0], kind = "slide", limits = [0.0, 0.02], mimic = "finger_a" }
"""
    )
    world = load_scene(path)
    service = ArmService(world, "arm")
    assert service.joints == ["arm/turret", "arm/slider/x", "arm/slider/rz", "arm/finger_a"]
    assert world.model.body("arm/finger_b").parentid[0] == world.model.body("arm/slider").id
    saved = tmp_path / "saved.toml"
    save_scene(world, saved)
    assert scene_text(load_scene(saved)) == saved.read_text()
    path.write_text(path.read_text().replace("kp = 200.0", "kp = -1.0"))
    with pytest.raises(SceneError, match=r"segments.*kp must be a finite number >= 0"):
        load_scene(path)


def test_velocity_servo_holds_a_joint_speed():
    arm = ArticulatedArm(
        name="spin", segments=(Segment("turret", 0.1, joint=ArmJoint(drive="velocity", kv=20.0, damping=0.0)),)
    )
    world = World()
    world.insert(arm)
    service = ArmService(world, "spin")
    service.set_joint_targets([0.5])  # rad/s
    world.run(1.0)
    before = float(world.data.joint("spin/turret").qpos[0])
    world.run(1.0)
    assert float(world.data.joint("spin/turret").qpos[0]) - before == pytest.approx(0.5, rel=0.02)
    assert service.joint_states().velocities[0] == pytest.approx(0.5, rel=0.02)


def test_gravity_compensation_is_a_per_joint_option():
    def lever(**options):
        return ArticulatedArm(
            name="lever",
            segments=(
                Segment("upright", 0.1, joint=ArmJoint(locked=True)),
                Segment("arm", 0.3, 0.02, 1.0, ArmJoint(axis=(0, 1, 0), kp=20.0, **options)),
                Segment("hand", 0.05, 0.02, 0.2, ArmJoint(locked=True)),
            ),
        )

    sag = {}
    for name, options in {"on": {}, "off": {"gravity_compensation": False}}.items():
        world = World()
        world.insert(lever(**options))
        service = ArmService(world, "lever")
        service.set_joint_targets([0.6])  # leaning over: gravity pulls it further
        world.run(3.0)
        sag[name] = service.joint_states().positions[0] - 0.6
        model = world.model
        compensated = [model.body_gravcomp[model.body(f"lever/{s}").id] for s in ("upright", "arm", "hand")]
        assert compensated == ([1.0, 1.0, 1.0] if name == "on" else [1.0, 0.0, 0.0])  # a locked link follows
    assert abs(sag["on"]) < 1e-3 and sag["off"] > 0.05
    passive = World()
    passive.insert(
        ArticulatedArm(
            name="p",
            segments=(Segment("s", 0.1, joint=ArmJoint(drive="none", gravity_compensation=True)),),
        )
    )
    assert passive.model.body_gravcomp[passive.model.body("p/s").id] == 1.0  # asked for: on


def test_servo_damping_ratio_none_keeps_the_given_kv():
    world = World()
    world.insert(
        ArticulatedArm(
            name="a",
            segments=(
                Segment("j", 0.2, joint=ArmJoint(axis=(0, 1, 0), kp=40.0, kv=3.0, damping=1.0, damping_ratio=None)),
                Segment("k", 0.2, joint=ArmJoint(axis=(0, 1, 0), kp=40.0, damping_ratio=0.5, damping=0.0)),
            ),
        )
    )
    design = ArmService(world, "a").servo_design()
    assert design["a/j"]["kv"] == 3.0
    inertia = design["a/j"]["inertia"]
    assert design["a/j"]["damping_ratio"] == pytest.approx(4.0 / (2 * np.sqrt(40.0 * inertia)))
    assert design["a/k"]["kv"] == pytest.approx(np.sqrt(40.0 * design["a/k"]["inertia"]))
    assert world.model.actuator("a/j").biasprm[2] == pytest.approx(-3.0)
    # the bound: a 0.2 m, 0.5 kg capsule of radius 0.03 about its end, plus the one above it stretched out
    span = 0.2 + 2 * 0.03
    own = 0.5 * (2 * (3 * 0.03**2 + span**2) / 12 + 0.03**2 / 2)
    assert design["a/k"]["inertia"] == pytest.approx(0.01 + own + 0.5 * 0.1**2)
    assert design["a/j"]["inertia"] == pytest.approx(0.01 + 2 * own + 0.5 * 0.1**2 + 0.5 * 0.3**2)


@pytest.mark.parametrize(
    ("segments", "message"),
    [
        ((), "no segments"),
        ((Segment("a", 0.1), Segment("a", 0.1)), "segment names must be unique"),
        ((Segment("a/b", 0.1),), "segment names must be unique, without '/'"),
        ((Segment("a", 0.1, parent="b"), Segment("b", 0.1)), "'a' hangs from 'b', not defined before it"),
        ((Segment("a", -0.1),), "length must be a positive number"),
        ((Segment("a", 0.1, joint=ArmJoint(kind="ball")),), "kind must be hinge or slide"),
        ((Segment("a", 0.1, joint=ArmJoint(drive="torque")),), "drive one of position, velocity, none"),
        ((Segment("a", 0.1, joint=ArmJoint(limits=(0.5, -0.5))),), "low < high"),
        ((Segment("a", 0.1, joint=ArmJoint(kp=0.0)),), "a position servo needs kp > 0"),
        ((Segment("a", 0.1, joint=ArmJoint(damping=-1.0)),), "damping must be a finite number >= 0"),
        ((Segment("a", 0.1, joint=ArmJoint(damping_ratio=0.0)),), "damping_ratio must be positive"),
        ((Segment("a", 0.1, joint=ArmJoint(mimic="nobody")),), "mimics 'nobody', which must be a segment"),
    ],
)
def test_bad_arms_are_refused(segments, message):
    world = World()
    world.insert(ArticulatedArm(name="bad", segments=segments))
    with pytest.raises(EntityError, match=message):
        world.compile()


def test_arm_service_checks_its_commands_and_keeps_a_move_across_checkpoints():
    world = World()
    world.insert(LynxL6(name="lynx"))
    arm = ArmService(world, "lynx")
    with pytest.raises(EntityError, match="has 6 joints, got 2"):
        arm.move_to([0.0, 0.0], 1.0)
    with pytest.raises(EntityError, match="finite"):
        arm.set_joint_targets([0, 0, math.nan, 0, 0, 0])
    with pytest.raises(EntityError, match="duration must be a positive"):
        arm.move_to([0.0] * 6, 0.0)
    arm.move_to([0.3, 0.2, 0.1, 0.0, 0.0, 0.01], 1.0)
    world.run(0.4)
    state = arm.snapshot()
    assert state["move"][1] == 1.0 and arm.busy
    arm.restore({"move": None, "next_time": state["next_time"]})
    assert not arm.busy
    arm.restore(state)
    assert arm.busy
    assert world.run_until(lambda: not arm.busy, timeout=2.0)
    world.run(1.0)
    np.testing.assert_allclose(arm.joint_states().positions, [0.3, 0.2, 0.1, 0.0, 0.0, 0.01], atol=0.005)
    arm.move_to([0.0] * 6, 1.0)
    world.reset()
    assert not arm.busy and world.time == 0.0


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ("[[entities.segments]]\nname = 'a'\n", r"segments\[0\].length: every segment needs a length"),
        ("[[entities.segments]]\nlength = 0.1\n", r"\[0\].name: every segment needs a name"),
        ("[[entities.segments]]\nname = 'a'\nlength = 0.1\ncolour = 1\n", r"\[0\].colour: unknown key"),
        ("[[entities.segments]]\nname = 'a'\nlength = 'long'\n", r"\[0\].length: expected a number"),
        ("[[entities.segments]]\nname = 'a'\nlength = 0.1\noffset = [1, 2]\n", r"\[0\].offset: expected 3 numbers"),
        ("[[entities.segments]]\nname = 'a'\nlength = 0.1\nparent = 3\n", r"\[0\].parent: expected a segment name"),
        ("[[entities.segments]]\nname = 'a'\nlength = 0.1\njoint = 3\n", r"\[0\].joint: expected a table"),
        ("[[entities.segments]]\nname = 'a'\nlength = 0.1\njoint = { kind = 1 }\n", r"joint.kind: expected a string"),
        ("[[entities.segments]]\nname = 'a'\nlength = 0.1\njoint = { locked = 1 }\n", r"joint.locked: expected true"),
        ("[[entities.segments]]\nname = 'a'\nlength = 0.1\njoint = { x = {}, q = {} }\n", r"joint.q: unknown key"),
        ("[[entities.segments]]\nname = 'a'\nlength = 0.1\njoint = { x = 2 }\n", r"joint.x: expected a table"),
        ("[[entities.segments]]\nname = 'a'\nlength = 0.1\njoint = { axis = [1] }\n", r"joint.axis: expected 3"),
    ],
)
def test_scene_segment_errors_name_the_key(tmp_path, table, message):
    from simrun import SceneError, load_scene

    path = tmp_path / "arm.toml"
    path.write_text(f"[[entities]]\ntype = 'ArticulatedArm'\nname = 'arm'\n\n{table}")
    with pytest.raises(SceneError, match=message):
        load_scene(path)
    with pytest.raises(SceneError, match="expected an array of segment tables"):
        path.write_text("[[entities]]\ntype = 'ArticulatedArm'\nname = 'arm'\nsegments = 3\n")
        load_scene(path)


def test_settling_time_follows_the_damping_ratio():
    world = World()
    segments = tuple(
        Segment(f"s{k}", 0.1, joint=ArmJoint(axis=(0, 1, 0), kp=30.0, damping=0.0, damping_ratio=zeta))
        for k, zeta in enumerate((0.5, 1.0, 2.0))
    )
    world.insert(ArticulatedArm(name="a", segments=segments))
    design = ArmService(world, "a").servo_design()
    under, critical, over = (design[f"a/s{k}"] for k in range(3))
    assert under["settling_time"] == pytest.approx(4.0 / (0.5 * under["natural_frequency"]))
    assert critical["settling_time"] == pytest.approx(5.83 / critical["natural_frequency"])
    slow = over["natural_frequency"] * (2.0 - math.sqrt(3.0))
    assert over["settling_time"] == pytest.approx(4.0 / slow)


def test_arm_base_links_and_gripper_coupling_in_the_model():
    world = World()
    world.insert(LynxL6(name="lynx", color=(0.2, 0.3, 0.4, 1.0)))
    model = world.model
    base = model.geom("lynx/base")
    np.testing.assert_allclose(base.pos, [0.0, 0.0, 0.015])  # a 0.03 m cylinder standing on the origin
    np.testing.assert_allclose(model.geom("lynx/elbow/geom").rgba, [0.2, 0.3, 0.4, 1.0])
    coupling = model.equality("lynx/finger_right/mimic")
    np.testing.assert_allclose(coupling.solref, [0.005, 1.0])
    np.testing.assert_allclose(coupling.solimp, [0.99, 0.999, 0.001, 0.5, 2.0])
    assert coupling.data[1] == 1.0  # mirrored one to one
    bad = World()
    bad.insert(LynxL6(name="x", base_mass=0.0))
    with pytest.raises(EntityError, match="base_mass must be a positive number"):
        bad.compile()


def test_a_restored_move_continues_from_where_it_started():
    world = World()
    world.insert(KukaLBR3(name="k"))
    arm = ArmService(world, "k")
    arm.move_to([0.6, 0, 0, 0, 0, 0, 0], 2.0)
    world.run(0.5)
    state = arm.snapshot()
    arm.restore(state)
    world.run(0.5)  # a quarter of the way further: the cosine profile at half time
    target = world.data.ctrl[world.model.actuator("k/link1").id]
    assert target == pytest.approx(0.3, abs=0.02)


def test_scene_segment_offset_reaches_the_model(tmp_path):
    from simrun import load_scene

    path = tmp_path / "arm.toml"
    path.write_text(
        "[[entities]]\ntype = 'ArticulatedArm'\nname = 'arm'\n\n[[entities.segments]]\nname = 'a'\nlength = 0.1\n"
        "offset = [0.02, 0.0, 0.01]\n"
    )
    world = load_scene(path)
    np.testing.assert_allclose(world.model.body("arm/a").pos, [0.02, 0.0, 0.05 + 0.01])


def test_arm_model_details_and_scene_flags(tmp_path):
    from simrun import SceneError, load_scene

    world = World()
    world.insert(ArticulatedArm(name="a", base_mass=2.5, segments=(Segment("s", 0.1),)))
    service = ArmService(world, "a")
    assert world.model.body_mass[world.model.body("a").id] == pytest.approx(2.5)  # the base, as given
    world.run(0.1)
    assert service.joint_states().time == pytest.approx(world.time)
    for bad, message in (
        ({"base_height": 0.0}, "base_height must be a positive number"),
        ({"segments": (Segment("s", 0.1, radius=0.0),)}, "radius must be a positive number"),
    ):
        broken = World()
        broken.insert(ArticulatedArm(name="b", **({"segments": (Segment("s", 0.1),)} | bad)))
        with pytest.raises(EntityError, match=message):
            broken.compile()
    path = tmp_path / "arm.toml"
    path.write_text(
        "[[entities]]\ntype = 'ArticulatedArm'\nname = 'arm'\n\n[[entities.segments]]\nname = 'a'\nlength = 0.1\n"
        "joint = { gravity_compensation = false }\n"
    )
    loaded = load_scene(path)
    assert loaded.model.body_gravcomp[loaded.model.body("arm/a").id] == 0.0
    path.write_text("[[entities]]\ntype = 'ArticulatedArm'\nname = 'arm'\nsegments = [3]\n")
    with pytest.raises(SceneError, match=r"\[0\]: expected a table"):
        load_scene(path)


@pytest.mark.parametrize("arm_cls", [KukaLBR3, LynxL6], ids=["KukaLBR3", "LynxL6"])
@pytest.mark.parametrize("signs", ["same", "alternating"])
def test_every_joint_stepping_at_once_settles_within_twice_its_stated_time(arm_cls, signs):
    # docs/robots.md: single-joint steps settle within 1.5x servo_design's time; all joints at once within 2x
    # (measured: KUKA link4 1.81x, the rest <= 1.32x; Lynx <= 1.18x). Ground truth: the joints' qpos.
    world = World()
    world.insert(arm_cls(name="arm"))
    arm = ArmService(world, "arm")
    design = arm.servo_design()
    world.run(0.5)
    steps = []
    for k, name in enumerate(arm.joints):
        size = 0.01 if "finger" in name else 0.4
        steps.append(size if signs == "same" or k % 2 == 0 or "finger" in name else -size)
    arm.set_joint_targets(steps)
    history = []
    for _ in range(round(3.0 / world.options.timestep)):
        world.step()
        history.append([world.data.joint(name).qpos[0] for name in arm.joints])
    positions = np.asarray(history)
    for k, name in enumerate(arm.joints):
        outside = np.flatnonzero(np.abs(positions[:, k] - steps[k]) > 0.02 * abs(steps[k]))
        settled = (outside[-1] + 1 if len(outside) else 0) * world.options.timestep
        assert settled <= 2.0 * design[name]["settling_time"], name
