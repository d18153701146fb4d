"""simrun serve --lockstep: an external controller steps the world; its recording re-simulates bit for bit.

Ground truth from outside the server: the same commands applied at the same steps to a world loaded in this
process give the same body pose to the last bit, and ``simrun resim`` (the CLI) re-simulates the recording.
"""

from __future__ import annotations

import subprocess

import numpy as np
from serve_helpers import SCENES, SIMRUN, serve

from simrun.client import Client
from simrun.record.simlog import Simlog
from simrun.run.session import prepare
from simrun.scene.scene_file import load_scene

BOEBOT = SCENES / "boebot.toml"
#: (steps before, service call, arguments): the external controller's script.
SCRIPT = [
    (10, "drive_distance", [-0.3, 0.6]),
    (1500, "rotate_degrees", [45.0, 0.5]),
    (1200, "cmd_vel", [0.05, 0.2]),
    (200, "cmd_vel", [0.05, 0.2]),
    (300, "all_stop", []),
    (250, None, None),
]


def test_lockstep_session_matches_an_in_process_run_and_resims_bit_identically(tmp_path):
    record = tmp_path / "session.simlog"
    with serve(BOEBOT, "--lockstep", "--record", str(record)) as server:
        sim = Client(server.url)
        assert sim.state()["mode"] == "lockstep"
        for steps, call, args in SCRIPT:
            before = sim.state()["time"]
            sim.step(steps=steps)
            assert sim.state()["time"] > before  # the world moves only when stepped
            if call is not None:
                sim.service("DriveService", "boebot").call(call, *args)
        served = sim.state()
        assert served["recording"]["active"]
    assert f"wrote {record}" in server.output[0]

    world = load_scene(BOEBOT)  # the same script, in this process
    prepare(world)
    drive = world.service("DriveService", "boebot")
    for steps, call, args in SCRIPT:
        world.step(steps)
        if call is not None:
            getattr(drive, call)(*args)
    ours = [*world.body("boebot").xpos, *world.body("boebot").xquat]
    assert np.array(served["poses"]["boebot"]).tobytes() == np.array(ours).tobytes()
    assert served["time"] == world.time

    log = Simlog(record)
    try:
        commands = log.commands()
    finally:
        log.close()
    assert [c.call for c in commands] == [c for _, c, _ in SCRIPT if c]
    done = subprocess.run([SIMRUN, "resim", str(record)], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    assert "bit-identical" in done.stdout
    frames = int(done.stdout.split(": ")[1].split()[0])
    assert frames >= served["time"] / 0.02 - 2
