"""A world that MuJoCo resets (an unstable simulation: mjWARN_BADQACC) is recorded with reset records, its clock
never runs backwards, and ``simrun resim`` / ``simrun replay`` accept the recording (issue 42 item 3).

The instability is the model's own: a hinge whose actuator pushes with its velocity (``biasprm = 0 0 0.003``,
positive feedback) grows until MuJoCo's acceleration check resets the data, about every 0.9 s. Ground truth is
MuJoCo itself: a plain ``mj_step`` loop over the scene's compiled model resets at the same steps as the world.
"""

from __future__ import annotations

import itertools
import subprocess
from pathlib import Path

import mujoco
import pytest
from click.testing import CliRunner
from scene_text import boebot_scene
from serve_helpers import SIMRUN, serve

from simrun.cli.main import main
from simrun.record.simlog import CHECKPOINT, COMMAND, FRAME, RESET, Simlog
from simrun.scene.scene_file import load_scene

UNSTABLE_MJCF = """<mujoco model="unstable">
  <worldbody>
    <body name="link" pos="0 0 0.5">
      <joint name="hinge" type="hinge" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.02" mass="0.01" contype="0" conaffinity="0"/>
    </body>
  </worldbody>
  <actuator>
    <general name="push" joint="hinge" gainprm="1" biastype="affine" biasprm="0 0 0.003"/>
  </actuator>
</mujoco>
"""
SCENE = boebot_scene(
    (1.0, 1.0),
    tail="""
[[entities]]
type = "MjcfRobot"
name = "wobbly"
file = "unstable.xml"
""",
)
COMMANDS = """[[commands]]
t = 0.5
entity = "boebot"
call = "cmd_vel"
args = [0.1, 0.2]

[[commands]]
t = 1.5
entity = "boebot"
call = "cmd_vel"
args = [0.05, -0.2]

[[commands]]
t = 2.5
entity = "boebot"
call = "cmd_vel"
args = [0.0, 0.0]
"""


@pytest.fixture
def scene(tmp_path: Path) -> Path:
    (tmp_path / "unstable.xml").write_text(UNSTABLE_MJCF)
    (tmp_path / "unstable.commands.toml").write_text(COMMANDS)
    path = tmp_path / "unstable.toml"
    path.write_text(SCENE)
    return path


def _mujoco_reset_steps(scene: Path, steps: int) -> list[int]:
    """The steps at which MuJoCo's own loop over the scene's model resets the data (its clock goes back)."""
    model = load_scene(scene).model
    data = mujoco.MjData(model)
    found = []
    for k in range(steps):
        before = data.time
        mujoco.mj_step(model, data)
        if data.time < before:
            found.append(k)
    return found


def _check_clock(path: Path) -> tuple[list[float], list[float], int]:
    """(frame times, reset times, commands) of a recording, asserting its clock never runs backwards."""
    log = Simlog(path)
    try:
        events = list(log.events())
    finally:
        log.close()
    clock = [e.time for e in events if e.kind in (FRAME, CHECKPOINT, RESET, COMMAND)]
    assert all(b >= a - 1e-9 for a, b in itertools.pairwise(clock)), "the recorded clock runs backwards"
    frames = [e.time for e in events if e.kind in (FRAME, CHECKPOINT)]
    resets = [e.time for e in events if e.kind == RESET]
    assert all(e.info is not None and e.info["count"] >= 1 for e in events if e.kind == RESET)
    return frames, resets, sum(e.kind == COMMAND for e in events)


def _replays(path: Path, tmp_path: Path) -> None:
    for flag, name in (("--glb", "run.glb"), ("--mcap", "run.mcap")):
        done = CliRunner().invoke(main, ["replay", str(path), flag, str(tmp_path / name)])
        assert done.exit_code == 0, done.output
        assert (tmp_path / name).stat().st_size > 0


def test_play_record_of_a_world_mujoco_resets(scene: Path, tmp_path: Path) -> None:
    record = tmp_path / "run.simlog"
    commands = str(tmp_path / "unstable.commands.toml")
    args = ["play", str(scene), "--duration", "3", "--commands", commands, "--record", str(record)]
    done = CliRunner().invoke(main, args)
    assert done.exit_code == 0, done.output
    frames, resets, _ = _check_clock(record)
    truth = _mujoco_reset_steps(scene, 1500)
    assert len(truth) >= 3  # MuJoCo itself resets this model about every 0.9 s
    assert resets == pytest.approx([k * 0.002 for k in truth], abs=1e-9)  # each reset at the step MuJoCo reset at
    assert len(frames) == 150 and frames[-1] == pytest.approx(2.98)  # 50 Hz frames to the end: the clock went on
    resim = CliRunner().invoke(main, ["resim", str(record)])
    assert resim.exit_code == 0, resim.output
    assert resim.stdout.strip().endswith("bit-identical") and "149 frame(s)" in resim.stdout
    _replays(record, tmp_path)


def test_serve_record_of_a_world_mujoco_resets(scene: Path, tmp_path: Path) -> None:
    record = tmp_path / "served.simlog"
    with serve(scene, "--lockstep", "--record", str(record)) as server:
        for k in range(12):  # 12 x 0.25 s: three resets, commands on both sides of each
            server.post("/api/step", {"steps": 125})
            answer = server.post("/api/services/DriveService/boebot/cmd_vel", {"args": [0.02 * (k % 4), 0.1]})
            assert answer["time"] == pytest.approx(0.25 * (k + 1))  # the clock the commands get goes on
        server.post("/api/step", {"steps": 50})
        assert server.get("/api/state")["time"] == pytest.approx(3.1)
    frames, resets, commands = _check_clock(record)
    assert commands == 12 and len(resets) >= 3 and frames[-1] == pytest.approx(3.08)  # the 50 Hz grid
    done = subprocess.run([SIMRUN, "resim", str(record)], capture_output=True, text=True, check=False, timeout=300)
    assert done.returncode == 0, done.stderr
    assert "bit-identical" in done.stdout
    _replays(record, tmp_path)
