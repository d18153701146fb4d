"""Commands files within what the robot can do (simrun/run/commands.py, issue 42): refused before the run starts.

A commands file with more than MAX_COMMAND_VALUES values is refused on its bytes, before the TOML parse (a
1M-point trajectory of 12 MB took 122 s to run, then 20 s to parse before its refusal); a JointService
command the service would refuse mid-run (a target outside the joint's range, a trajectory span below the
timestep) is refused before the first step, with the command's file and line. Ground truth: the exit code,
the one error line, and that no run happened (no summary).
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

from simrun.run.commands import MAX_COMMAND_VALUES, load_commands

ROOT = Path(__file__).resolve().parent.parent
SCENE = ROOT / "fixtures" / "scenes" / "mjcf_arm_on_base.toml"  # a JointService on base/arm (MJCF arm)
SIMRUN = str(Path(sys.executable).parent / "simrun")
JOINT = '[[commands]]\nt = {t}\nservice = "JointService"\nentity = "base/arm"\ncall = "{call}"\nargs = {args}\n'


def play(commands: Path, duration: float = 60.0) -> tuple[subprocess.CompletedProcess[str], float]:
    env = dict(os.environ, MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
    started = time.monotonic()
    done = subprocess.run(
        [SIMRUN, "play", str(SCENE), "--commands", str(commands), "--duration", str(duration)],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    return done, time.monotonic() - started


def one_error(done: subprocess.CompletedProcess[str]) -> str:
    assert done.returncode == 1, done.stderr
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), done.stderr
    assert "Traceback" not in done.stderr and "drove" not in done.stdout  # refused before the run
    return lines[0]


def test_a_million_point_trajectory_is_refused_on_its_bytes(tmp_path: Path) -> None:
    n = 1_000_000
    times = ",".join(f"{(k + 1) / 500:g}" for k in range(n))
    path = tmp_path / "big.toml"
    path.write_text(JOINT.format(t=0.0, call="trajectory", args=f'[["yaw"], [{times}], [{",".join(["0.1"] * n)}]]'))
    done, elapsed = play(path)
    line = one_error(done)
    assert f"{path}: more than {MAX_COMMAND_VALUES} values in its arrays" in line
    assert elapsed < 60  # before: 122 s of running, or 20 s of parsing before the refusal


def test_commas_in_strings_and_comments_are_not_values(tmp_path: Path) -> None:
    path = tmp_path / "c.toml"
    commas = "," * (MAX_COMMAND_VALUES + 1)
    path.write_text(
        f"# {commas}\n" + '[[commands]]\nt = 1.0\nentity = "base"\ncall = "drive_distance"\nargs = [1.0, 0.5]\n'
    )
    (command,) = load_commands(path)
    assert command.call == "drive_distance" and command.args == (1.0, 0.5)


def test_a_target_past_the_joint_range_late_in_the_run_is_refused_before_it_starts(tmp_path: Path) -> None:
    path = tmp_path / "far.toml"
    path.write_text("\n\n" + JOINT.format(t=50.0, call="set_positions", args='[["elbow"], [1e6]]'))
    done, _ = play(path)
    line = one_error(done)
    assert line.startswith(
        f"error: {path}:3: commands[0]: set_positions: joint 'elbow' target 1000000 rad is outside ["
    )


def test_a_trajectory_span_below_the_timestep_is_refused_before_it_starts(tmp_path: Path) -> None:
    path = tmp_path / "fast.toml"
    path.write_text(JOINT.format(t=20.0, call="trajectory", args='[["yaw"], [1.0, 1.0000001], [0.1, 0.2]]'))
    done, _ = play(path)
    line = one_error(done)
    assert f"{path}:1: commands[0]: trajectory: times[1] = 1 s is 1e-07 s after times[0] = 1 s" in line


def test_commands_within_range_still_run(tmp_path: Path) -> None:
    path = tmp_path / "ok.toml"
    path.write_text(JOINT.format(t=0.1, call="move_to", args='[["elbow"], [0.5], 0.5]'))
    done, _ = play(path, duration=1.0)
    assert done.returncode == 0, done.stderr


ARM_SCENE = ROOT / "fixtures" / "scenes" / "arm_on_base.toml"  # an ArmService on base/arm (built-in LynxL6)
ARM = '[[commands]]\nt = {t}\nservice = "ArmService"\nentity = "base/arm"\ncall = "{call}"\nargs = {args}\n'


def test_an_arm_service_target_past_a_joint_range_is_refused_before_it_starts(tmp_path: Path) -> None:
    env = dict(os.environ, MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
    bad = tmp_path / "arm.toml"
    bad.write_text(ARM.format(t=30.0, call="move_to", args="[[0.0, 1e6, 0.0, 0.0, 0.0, 0.0], 1.0]"))
    refused = subprocess.run(
        [SIMRUN, "play", str(ARM_SCENE), "--commands", str(bad), "--duration", "60"],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    line = one_error(refused)
    assert f"{bad}:1: commands[0]: move_to: " in line and "target 1000000 rad is outside [" in line
    good = tmp_path / "ok.toml"
    good.write_text(ARM.format(t=0.1, call="set_joint_targets", args="[[0.0, 0.2, 0.0, 0.0, 0.0, 0.0]]"))
    ran = subprocess.run(
        [SIMRUN, "play", str(ARM_SCENE), "--commands", str(good), "--duration", "0.5"],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    assert ran.returncode == 0, ran.stderr
