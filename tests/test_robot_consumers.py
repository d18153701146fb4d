"""Issue 37: every robot kind appears identically to every consumer: the robot contract, ``simrun play``'s summary,
the MCAP channels of its recording (read with the ``mcap`` reader) and the dashboard's catalogue and teleoperation
list. Ground truth: MuJoCo's compiled model (which bodies carry free joints, which joints have actuators)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import mujoco
import pytest
from mcap.reader import make_reader

from simrun.robots.contract import describe
from simrun.scene.scene_file import load_scene
from simrun.serve.catalogue import build_catalogue

FIXTURES = Path(__file__).resolve().parent.parent / "fixtures"
SIMRUN = str(Path(sys.executable).parent / "simrun")
DRIVE = '\n[[services]]\ntype = "DriveService"\nentity = "bot"\n'
#: kind -> (entity table, drives, the body that moves with it or None for a fixed robot)
KINDS = {
    "catalogue": ('type = "BoeBot"', True, "bot"),
    "DifferentialDrive": ('type = "DifferentialDrive"\nwheel_radius = 0.03', True, "bot"),
    "arm": ('type = "LynxL6"', False, None),
    "MjcfRobot-wheeled": (
        f'type = "MjcfRobot"\nfile = "{FIXTURES / "mjcf" / "cylbot" / "cylbot.xml"}"\nwheels = ["left", "right"]',
        True,
        "bot/chassis",
    ),
    "MjcfRobot-arm": (f'type = "MjcfRobot"\nfile = "{FIXTURES / "mjcf" / "arm" / "arm.xml"}"', False, None),
    "UrdfRobot": (
        f'type = "UrdfRobot"\nurdf = "{FIXTURES / "urdf" / "meshbot" / "meshbot.urdf"}"\nfree = true\n'
        'wheels = ["left_axle", "right_axle"]',
        True,
        "bot",
    ),
}


def _scene(tmp_path: Path, kind: str) -> Path:
    table, drives, _ = KINDS[kind]
    text = f'[[entities]]\ntype = "Ground"\nname = "ground"\n\n[[entities]]\nname = "bot"\n{table}\n'
    path = tmp_path / "scene.toml"
    path.write_text(text + (DRIVE if drives else ""))
    return path


def _run(*args: str) -> str:
    done = subprocess.run([SIMRUN, *args], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    return done.stdout


@pytest.mark.parametrize("kind", list(KINDS))
def test_every_consumer_sees_the_same_robot(tmp_path, kind):
    _, drives, moving = KINDS[kind]
    scene = _scene(tmp_path, kind)
    world = load_scene(scene)
    model = world.model
    robot = describe(world, "bot")
    # the contract, against the compiled model
    if moving is None:
        assert not robot.mobile and robot.root == "bot"
    else:
        first = model.body_jntadr[model.body(moving).id]
        assert model.jnt_type[first] == mujoco.mjtJoint.mjJNT_FREE
        assert robot.mobile and robot.root == moving and robot.root_kind == "free"
    assert (robot.wheels is not None) == drives
    actuated = {model.actuator_trnid[a, 0] for a in range(model.nu)}
    assert set(robot.joints) == {model.joint(j).name for j in actuated}
    # the dashboard's catalogue and teleoperation list
    catalogue = build_catalogue(world)
    entry = next(e for e in catalogue["entities"] if e["name"] == "bot")
    assert entry["robot"] is True and entry["root"] == robot.root
    assert not next(e for e in catalogue["entities"] if e["name"] == "ground")["robot"]
    assert catalogue["teleop"] == (["bot"] if drives else [])
    # simrun play's summary and the recording's MCAP channels
    commands = tmp_path / "go.commands.toml"
    call = 'service = "DriveService"\nentity = "bot"\ncall = "set_drive_power"\nargs = [0.6, 0.6]'
    commands.write_text(f"[[commands]]\nt = 0.0\n{call}\n" if drives else "")
    log = tmp_path / "run.simlog"
    args = ["play", str(scene), "--duration", "1.0", "--record", str(log), "--json"]
    summary = json.loads(_run(*args, *(["--commands", str(commands)] if drives else [])))
    assert set(summary["distances_m"]) == ({"bot"} if moving else set())
    if drives:
        assert summary["distances_m"]["bot"] > 0.05
    out = tmp_path / "run.mcap"
    _run("replay", str(log), "--mcap", str(out))
    with out.open("rb") as stream:
        topics = {c.topic for c in make_reader(stream).get_summary().channels.values()}
    assert "/bot/pose" in topics and "/ground/pose" not in topics
    assert ("/bot/odometry" in topics) == drives


def test_joint_service_serves_a_built_in_arm():
    """JointService commands a LynxL6's position servos by segment name; the joints get there (MuJoCo's qpos)."""
    from simrun.robots.arm import LynxL6
    from simrun.services.joint_service import JointService
    from simrun.world.world import World

    world = World()
    world.insert(LynxL6(name="a"))
    joints = JointService(world, "a")
    model = world.model
    servos = [model.joint(model.actuator_trnid[k, 0]).name.removeprefix("a/") for k in range(model.nu)]
    assert list(joints.joints()) == servos and set(joints.kinds().values()) == {"position"}
    joints.set_positions(["shoulder", "elbow"], [0.3, -0.4])
    world.run(2.0)
    assert world.data.joint("a/shoulder").qpos[0] == pytest.approx(0.3, abs=0.005)  # measured 0.3001
    assert world.data.joint("a/elbow").qpos[0] == pytest.approx(-0.4, abs=0.005)
