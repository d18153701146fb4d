"""Who carries the weight: ground contact forces of every built-in robot, bare and with every built-in arm.

Ground truth is MuJoCo's own contact forces (``mj_contactForce``) against statics computed here from the
compiled model's masses (``body_mass``), centres of mass (``xipos``) and the robots' support positions (the
drive axle, each caster): the ground must carry the whole weight, arm included (its gravity compensation
acts as joint torques, not as a lift), and the load must move between the axle and the casters as the
lever arms say when the arm stretches forward.
"""

import math

import mujoco
import numpy as np
import pytest

from simrun import Ground, Pose, World
from simrun.robots.arm import KukaLBR3, LynxL6
from simrun.robots.arm_service import ArmService
from simrun.robots.catalogue import READY_ROBOTS
from simrun.services.drive_service import DriveService

ARMS = [KukaLBR3, LynxL6]


def _contacts(model, data, robot):
    """(geom name, normal force N, contact point world xyz) of every ground contact of ``robot``'s tree."""
    ground = {g for g in range(model.ngeom) if model.geom(g).name.startswith("ground/")}
    force = np.zeros(6)
    result = []
    for i in range(data.ncon):
        contact = data.contact[i]
        other = contact.geom2 if contact.geom1 in ground else contact.geom1 if contact.geom2 in ground else None
        if other is None or not model.geom(other).name.startswith(f"{robot}/"):
            continue
        mujoco.mj_contactForce(model, data, i, force)
        result.append((model.geom(other).name, float(force[0]), contact.pos.copy()))
    return result


def _statics(model, data, robot):
    """Total weight (N) and the centre of mass ahead of the axle (m), from masses and poses.

    The lever arm is horizontal (gravity's): the robot's X axis projected on the ground, so a robot that
    sinks a little into its soft contacts under a tall arm still gets the true arm."""
    root = model.body(robot).id
    bodies = [b for b in range(model.nbody) if _under(model, b, root)]
    masses = model.body_mass[bodies]
    centre = masses @ data.xipos[bodies] / masses.sum()
    heading = data.xmat[root].reshape(3, 3)[:, 0] * [1.0, 1.0, 0.0]
    along = float((centre - data.xpos[root]) @ (heading / np.linalg.norm(heading)))
    return float(masses.sum() * -model.opt.gravity[2]), along


def _under(model, body, root):
    while body > 0:
        if body == root:
            return True
        body = model.body_parentid[body]
    return False


def _mounted(robot_cls, arm_cls):
    world = World()
    world.insert(Ground(name="ground"))
    robot = world.insert(robot_cls(name="base", pose=Pose((0.0, 0.0, 0.001))))
    _, _, height = robot.chassis_dimensions
    top = robot.chassis_clearance + height
    low, high = _span(robot)  # the arm stands on the chassis over the middle of its supports
    world.insert(arm_cls(name="arm", parent="base", pose=Pose(((low + high) / 2, 0.0, top))))
    return world, robot, ArmService(world, "base/arm")


def _supports(robot):
    """Support positions along X from the axle, m: the wheels at 0, each caster at its centre."""
    return {"base/left_tyre": 0.0, "base/right_tyre": 0.0} | {f"base/{s}": x for s, x, _ in robot.casters()}


def _span(robot):
    """The supports' extent along X from the axle, m: (rearmost, foremost) of the axle and the casters."""
    xs = [0.0, *(x for _, x, _ in robot.casters())]
    return min(xs), max(xs)


def _stretch(world, robot, service):
    """The largest forward shoulder pitch (whole degrees up to 90) at which statics keeps every support
    loaded: the centre of mass stays inside the support span with 15 % of the span to spare on each side
    (a Kuka reaching out over a Boe-Bot would tip it over its wheels)."""
    model = world.model
    data = mujoco.MjData(model)
    data.qpos[:] = world.data.qpos
    shoulder = model.joint(service.joints[1]).qposadr[0]
    low, high = _span(robot)
    spare = 0.15 * (high - low)
    best = 0
    for degrees in range(1, 91):
        data.qpos[shoulder] = math.radians(degrees)
        mujoco.mj_kinematics(model, data)
        _, along = _statics(model, data, "base")
        if not low + spare <= along <= high - spare:
            break
        best = degrees
    return best


@pytest.mark.parametrize("arm_cls", ARMS, ids=lambda c: c.__name__)
@pytest.mark.parametrize("robot_cls", READY_ROBOTS, ids=lambda c: c.__name__)
def test_the_ground_carries_the_whole_robot_and_arm_and_the_load_shifts_as_statics_predicts(robot_cls, arm_cls):
    world, robot, service = _mounted(robot_cls, arm_cls)
    model = world.model
    supports = _supports(robot)
    degrees = _stretch(world, robot, service)
    assert degrees >= 2, "every arm can lean forward over every base"
    moments = {}
    for pose, angle in (("rest", 0.0), ("stretched", math.radians(degrees))):
        targets = [0.0] * len(service.joints)
        targets[1] = angle
        service.move_to(targets, 1.5)  # slowly: a jerk of a heavy arm would rock a light base over
        world.run(3.0)
        data = world.data
        weight, along = _statics(model, data, "base")
        contacts = _contacts(model, data, "base")
        total = sum(f for _, f, _ in contacts)
        assert total == pytest.approx(weight, rel=0.005), f"{pose}: ground carries {total:.3f} N of {weight:.3f} N"
        arm_weight, _ = _statics(model, data, "base/arm")
        assert abs(total - weight) < 0.005 * arm_weight, f"{pose}: the arm's own weight, within 0.5 % of it"
        assert {name for name, _, _ in contacts} <= set(supports), f"{pose}: only wheels and casters touch"
        # moment balance about the axle with the published support positions: sum N_i x_i = W x_com
        loads = {name: 0.0 for name in supports}
        for name, f, _ in contacts:
            loads[name] += f
        moment = sum(loads[name] * x for name, x in supports.items())
        span = max(abs(x) for x in supports.values())
        assert moment == pytest.approx(weight * along, abs=0.01 * weight * span), pose
        if len(supports) == 3:  # statically determinate: the caster's share follows from the lever arms alone
            (caster,) = [n for n in supports if "caster" in n]
            expected = weight * along / supports[caster]
            assert loads[caster] == pytest.approx(expected, abs=0.01 * weight), pose
        moments[pose] = (moment, weight * along)
    shift, predicted = moments["stretched"][0] - moments["rest"][0], moments["stretched"][1] - moments["rest"][1]
    assert abs(predicted) > 0.001 * weight  # stretching moves the centre of mass forward
    assert shift == pytest.approx(predicted, rel=0.05, abs=0.002 * weight * span)


def _pitch_degrees(quat):
    w, x, y, z = quat
    return math.degrees(math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x)))))


@pytest.mark.parametrize("robot_cls", READY_ROBOTS, ids=lambda c: c.__name__)
def test_robots_stay_level_on_their_supports_at_full_speed_braking_and_turning(robot_cls):
    world = World()
    world.insert(Ground(name="ground"))
    world.insert(robot_cls(name="r", pose=Pose((0.0, 0.0, 0.001))))
    drive = DriveService(world, "r")
    model, data = world.model, world.data
    chassis = model.geom("r/chassis").id
    world.run(0.3)
    worst, scrapes = 0.0, 0

    def watch(seconds, done=lambda: False):
        nonlocal worst, scrapes
        for _ in range(round(seconds / model.opt.timestep)):
            if done():
                return
            world.step()
            worst = max(worst, abs(_pitch_degrees(data.qpos[3:7])))
            scrapes += any(chassis in (data.contact[i].geom1, data.contact[i].geom2) for i in range(data.ncon))

    drive.drive_distance(2.0, power=1.0)  # the service's full speed ...
    watch(2.5)
    drive.all_stop()  # ... and braking from it
    watch(1.0)
    for command, amount in ((drive.drive_distance, 0.5), (drive.drive_distance, -0.3), (drive.rotate_degrees, 180.0)):
        command(amount, power=1.0)  # the service's full speed, its own braking at the end
        watch(10.0, lambda: not drive.busy)
        watch(0.2)
    drive.set_drive_power(1.0, -1.0)  # spin at full power
    watch(1.0)
    drive.all_stop()
    watch(1.0)
    assert worst < 1.0, f"pitched {worst:.2f} degrees"
    assert scrapes == 0, f"the chassis touched the floor in {scrapes} steps"


def test_two_arms_on_one_base_and_a_free_standing_arm_weigh_what_they_weigh():
    # each arm carries its own compensated links down to the free joint above it, so two arms on one robot are
    # both carried once; an arm that is itself free (no robot) stands on its base with its whole weight
    world = World()
    world.insert(Ground(name="ground"))
    world.insert(READY_ROBOTS[1](name="base", pose=Pose((0.0, 0.0, 0.001))))  # Pioneer 3-DX
    for name, x in (("front", 0.05), ("back", -0.1)):
        world.insert(LynxL6(name=name, parent="base", pose=Pose((x, 0.0, 0.237))))
    world.insert(LynxL6(name="alone", free=True, pose=Pose((2.0, 0.0, 0.001))))
    world.run(2.0)
    model, data = world.model, world.data
    for robot in ("base", "alone"):
        weight, _ = _statics(model, data, robot)
        total = sum(f for _, f, _ in _contacts(model, data, robot))
        assert total == pytest.approx(weight, rel=0.005), robot
    welded = World()
    welded.insert(LynxL6(name="fixed"))
    welded.run(0.1)
    assert not welded.data.xfrc_applied.any()  # welded to the world: nothing to carry, nothing applied
