"""simrun resim of recordings from a served world that was edited before or while it was recorded.

Ground truth: MuJoCo's own state, re-simulated from the scene file: a recording started after edits begins
with them (before its first checkpoint), and resim applies every edit recorded before the checkpoint it
starts from, so the re-simulated frames equal the recorded ones bit for bit (``simrun resim`` says so).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from serve_helpers import SCENES, SIMRUN, serve

from simrun.client import Client
from simrun.record.simlog import Simlog
from simrun.world.edit_apply import EditRecord

CRATE = {"type": "Box", "name": "crate", "dimensions": [0.2, 0.3, 0.2], "mass": 2.0, "free": True,
         "pose": {"position": [1.0, 1.6, 0.1]}}  # fmt: skip


def resim(log: Path, *args: str) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
    return subprocess.run([SIMRUN, "resim", str(log), *args], capture_output=True, text=True, timeout=300, env=env)


def test_recordings_started_after_edits_and_checkpoints_after_edits_resimulate(tmp_path: Path) -> None:
    record = tmp_path / "run.simlog"
    with serve(SCENES / "boebot.toml", "--lockstep", "--edit", "--record", str(record)) as server:
        sim = Client(server.url)
        sim.service("DriveService", "boebot").drive_distance(1.0, 0.5)
        sim.step(seconds=0.5)
        sim.insert(CRATE)  # while the first recording runs
        sim.step(seconds=1.7)  # past the checkpoints at 1 s and 2 s
        sim.stop_recording()
        sim.teleport("box", [1.6, 0.4, 0.1])  # between recordings
        sim.apply_force("crate", force=[0.0, 20.0, 0.0], duration=0.5)
        sim.step(seconds=0.2)
        sim.start_recording()  # run-2.simlog: begins with the three edits
        sim.step(seconds=1.5)
    second = record.with_name("run-2.simlog")
    assert sys.executable and second.exists()
    kinds = [r.command.kind for r in Simlog(second).events() if isinstance(r.command, EditRecord)]
    assert kinds == ["insert", "teleport", "apply_force"]
    for log, start in ((record, []), (record, ["--from", "1.5"]), (second, []), (second, ["--from", "3.5"])):
        done = resim(log, *start)
        assert done.returncode == 0 and "bit-identical" in done.stdout, (log.name, start, done.stdout, done.stderr)
