"""JointService: targets, velocities, trajectories and state by joint name, over position, velocity and force
actuators, on an MJCF arm, a URDF arm and a model written here; the simulator's joint positions are the truth."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from simrun import EntityError, Ground, Pose, UrdfRobot, World, load_scene
from simrun.robots.mjcf_robot import MjcfRobot
from simrun.run.commands import load_commands
from simrun.services.joint_service import JointService

FIXTURES = Path(__file__).resolve().parent.parent / "fixtures"

#: One hinge per actuator kind, each on its own body: a motor, a velocity servo, a position servo with a
#: spring offset (general affine bias) and an integrated-velocity servo; damping and a spring to compensate.
#: Angles in the file are degrees (MJCF's default); the activation range is in radians.
KINDS_XML = """<mujoco>
  <worldbody>
    <body name="m" pos="0 0 1"><joint name="motor" axis="0 1 0" damping="0.5" stiffness="2"/>
      <geom type="capsule" fromto="0 0 0 .3 0 0" size=".03"/></body>
    <body name="v" pos="1 0 1"><joint name="vel" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 .3 0 0" size=".03"/></body>
    <body name="p" pos="2 0 1"><joint name="pos" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 .3 0 0" size=".03"/></body>
    <body name="i" pos="3 0 1"><joint name="intvel" axis="0 1 0" range="-100 100"/>
      <geom type="capsule" fromto="0 0 0 .3 0 0" size=".03"/></body>
    <body name="s" pos="4 0 1"><joint name="slide" type="slide" axis="1 0 0" range="-.2 .2"/><geom size=".05"/></body>
  </worldbody>
  <actuator>
    <motor joint="motor" gear="2" ctrlrange="-5 5"/>
    <velocity joint="vel" kv="5"/>
    <general joint="pos" gainprm="20" biastype="affine" biasprm="0.5 -20 -1"/>
    <intvelocity joint="intvel" kp="30" kv="2" actrange="-2 2"/>
    <motor joint="slide" ctrlrange="-50 50"/>
  </actuator>
</mujoco>"""


def _kinds_world(tmp_path: Path, gravity: float = -9.81) -> tuple[World, JointService]:
    (tmp_path / "kinds.xml").write_text(KINDS_XML)
    from simrun import WorldOptions

    world = World(WorldOptions(gravity=(0.0, 0.0, gravity)), base_dir=tmp_path)
    world.insert(Ground(name="ground"))
    world.insert(MjcfRobot(name="k", file="kinds.xml"))
    return world, JointService(world, "k")


def _position(world: World, joint: str) -> float:
    return float(world.joint(joint).qpos[0])


def test_each_actuator_kind_is_recognised_and_reaches_its_target(tmp_path: Path) -> None:
    world, service = _kinds_world(tmp_path, gravity=0.0)
    assert service.kinds() == {
        "motor": "force",
        "vel": "velocity",
        "pos": "position",
        "intvel": "intvelocity",
        "slide": "force",
    }
    targets = {"motor": 0.6, "vel": -0.4, "pos": 0.3, "intvel": 0.5, "slide": 0.1}
    service.set_positions(list(targets), list(targets.values()))
    world.run(4.0)
    for joint, target in targets.items():
        assert _position(world, f"k/{joint}") == pytest.approx(target, abs=0.005), joint
    assert world.warnings() == {}


def test_force_joints_hold_against_gravity_and_a_spring(tmp_path: Path) -> None:
    """The PID's feed-forward and integral: the motor (spring, damping) and the slide hold their targets."""
    world, service = _kinds_world(tmp_path)
    service.set_positions(["motor", "slide"], [0.6, 0.1])
    world.run(4.0)
    assert _position(world, "k/motor") == pytest.approx(0.6, abs=0.002)
    assert _position(world, "k/slide") == pytest.approx(0.1, abs=0.002)


def test_velocity_targets_run_the_joints_at_that_speed(tmp_path: Path) -> None:
    world, service = _kinds_world(tmp_path, gravity=0.0)
    service.set_velocities(["motor", "vel", "pos"], [0.3, -0.2, 0.25])
    world.run(1.0)
    start = {j: _position(world, f"k/{j}") for j in ("motor", "vel", "pos")}
    world.run(1.0)
    assert _position(world, "k/motor") - start["motor"] == pytest.approx(0.3, abs=0.01)
    assert _position(world, "k/vel") - start["vel"] == pytest.approx(-0.2, abs=0.01)
    assert _position(world, "k/pos") - start["pos"] == pytest.approx(0.25, abs=0.02)
    service.hold()
    held = _position(world, "k/motor")
    world.run(1.0)
    assert _position(world, "k/motor") == pytest.approx(held, abs=0.01)


def test_a_trajectory_passes_its_waypoints_on_time(tmp_path: Path) -> None:
    world, service = _kinds_world(tmp_path, gravity=0.0)
    service.trajectory(["pos", "motor"], [1.0, 2.0, 3.0], [0.4, 0.2, -0.3, -0.2, 0.0, 0.0])
    assert service.busy
    seen = {}
    for t in (1.0, 2.0, 3.0):
        world.run(t - world.time)
        seen[t] = (_position(world, "k/pos"), _position(world, "k/motor"))
    assert seen[1.0] == pytest.approx((0.4, 0.2), abs=0.05)  # a servo lags a moving target a little
    assert seen[2.0] == pytest.approx((-0.3, -0.2), abs=0.08)
    world.run(1.0)
    assert not service.busy
    assert (_position(world, "k/pos"), _position(world, "k/motor")) == pytest.approx((0.0, 0.0), abs=0.005)
    state = service.state()
    assert state.names == ("motor", "vel", "pos", "intvel", "slide")
    assert state.targets[2] == 0.0 and math.isnan(state.targets[1])


def test_the_same_service_drives_a_urdf_robot() -> None:
    world = World(base_dir=FIXTURES / "urdf")
    world.insert(Ground(name="ground"))
    world.insert(
        UrdfRobot(name="arm", urdf="tiny_arm_description/urdf/tiny_arm.urdf", actuators=True, pose=Pose((0, 0, 0.3)))
    )
    service = JointService(world, "arm")
    assert service.kinds() == {"shoulder": "force", "elbow": "force", "slide": "force"}
    service.set_positions(["shoulder", "elbow", "slide"], [-0.9, 0.6, 0.02])
    world.run(3.0)
    state = service.state()
    assert state.positions == pytest.approx((-0.9, 0.6, 0.02), abs=0.005)
    assert world.warnings() == {}


@pytest.mark.parametrize(
    ("call", "args", "message"),
    [
        ("set_positions", (["nope"], [0.1]), "has no actuated joint 'nope' \\(actuated joints: yaw, shoulder"),
        ("set_positions", (["yaw"], [0.1, 0.2]), "one value per joint"),
        ("set_positions", (["yaw"], [math.nan]), "not a finite number"),
        ("set_positions", ("yaw", [0.1]), "a list of joint names"),
        ("set_velocities", (["yaw", "yaw"], [0.1, 0.2]), "named twice"),
        ("trajectory", (["yaw"], [1.0, 0.5], [0.1, 0.2]), "times must increase"),
        ("trajectory", (["yaw"], [1.0], [0.1, 0.2]), "1 x 1 finite values, got 2"),
        ("trajectory", (["yaw"], [-1.0], [0.1]), "positive finite seconds"),
    ],
)
def test_bad_commands_are_refused_with_one_line(call: str, args: tuple[object, ...], message: str) -> None:
    world = World(base_dir=FIXTURES / "mjcf" / "arm")
    world.insert(MjcfRobot(name="arm", file="arm.xml"))
    service = JointService(world, "arm")
    with pytest.raises(EntityError, match=message):
        getattr(service, call)(*args)


def test_bad_parameters_are_refused() -> None:
    world = World(base_dir=FIXTURES / "mjcf" / "arm")
    world.insert(MjcfRobot(name="arm", file="arm.xml"))
    for bad in ({"rate": 0.0}, {"bandwidth": math.inf}):
        with pytest.raises(EntityError, match="must be a positive number"):
            JointService(world, "arm", **bad)  # type: ignore[arg-type]  # hold is a str


def test_commands_file_calls_and_the_scene_binding() -> None:
    commands = load_commands(FIXTURES / "scenes" / "mjcf_arm_on_base.commands.toml")
    calls = [(c.service, c.call) for c in commands]
    assert ("JointService", "move_to") in calls and ("JointService", "trajectory") in calls
    world = load_scene(FIXTURES / "scenes" / "mjcf_arm_on_base.toml")
    service = world.service("JointService", "base/arm")
    assert isinstance(service, JointService) and service.period == pytest.approx(1 / 500)


def test_snapshot_restore_continues_bit_for_bit(tmp_path: Path) -> None:
    """A run restored mid-trajectory from the service's snapshot and MuJoCo's state ends where the run did."""
    import mujoco

    world, service = _kinds_world(tmp_path)
    service.trajectory(["motor", "pos"], [1.0, 2.0], [0.5, 0.2, -0.1, 0.4])
    world.run(0.7)
    model, data = world.model, world.data
    size = mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_INTEGRATION)
    saved = np.zeros(size)
    mujoco.mj_getState(model, data, saved, mujoco.mjtState.mjSTATE_INTEGRATION)
    snap = service.snapshot()
    world.run(1.5)
    end = data.qpos.copy()
    mujoco.mj_setState(model, data, saved, mujoco.mjtState.mjSTATE_INTEGRATION)
    service.restore(snap)
    world.run(1.5)
    np.testing.assert_array_equal(data.qpos, end)


def test_a_rebuilt_world_finds_the_joints_again(tmp_path: Path) -> None:
    world, service = _kinds_world(tmp_path, gravity=0.0)
    service.set_positions(["pos"], [0.3])
    world.run(0.5)
    world.insert(Ground(name="other", pose=Pose((0.0, 0.0, -1.0))))  # a new model: ids move
    world.run(2.0)
    assert _position(world, "k/pos") == pytest.approx(0.3, abs=0.005)


SCENES = FIXTURES / "scenes"


@pytest.mark.parametrize(
    ("scene", "commands"),
    [
        ("arm_on_base.toml", None),  # built-in LynxL6 through its ArmService
        ("mjcf_arm_on_base.toml", "mjcf_arm_on_base.commands.toml"),  # MJCF arm, JointService commands
        ("mjcf_walkers.toml", "mjcf_walkers.commands.toml"),
    ],
)
def test_a_recording_with_held_joints_resimulates_bit_identically(tmp_path: Path, scene: str, commands: str | None):
    """A JointService restored from a checkpoint keeps what it holds: resim from the first checkpoint and from a
    later one is bit-identical (before: the first tick after restore bound the model again and held the joints
    anew at their current positions, 1 ulp off in ctrl at t = 0.02 s)."""
    import os
    import subprocess
    import sys

    simrun = str(Path(sys.executable).parent / "simrun")
    env = dict(os.environ, MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
    log = tmp_path / "run.simlog"
    play = [simrun, "play", str(SCENES / scene), "--duration", "2.5", "--record", str(log)]
    if commands:
        play += ["--commands", str(SCENES / commands)]
    done = subprocess.run(play, capture_output=True, text=True, env=env, timeout=300)
    assert done.returncode == 0, done.stderr
    for start in ([], ["--from", "1.5"]):
        again = subprocess.run(
            [simrun, "resim", str(log), *start], capture_output=True, text=True, env=env, timeout=300
        )
        assert again.returncode == 0 and "bit-identical" in again.stdout, (start, again.stdout, again.stderr)
