"""SIGINT/SIGTERM at any moment of a served lockstep session: the world thread finishes its step, the server
finishes the recording and exits 0, and the recording re-simulates bit for bit (``simrun resim``, a separate
process: ground truth from MuJoCo re-stepping the recorded commands, not from the server).

``SIMRUN_SIGNAL_SESSIONS`` sets how many sessions get a signal at a random point (issue 39 asks for 50:
``SIMRUN_SIGNAL_SESSIONS=50 pytest tests/test_serve_signals.py``, about 4 minutes); ``make test`` runs 4.
"""

from __future__ import annotations

import os
import random
import signal
import subprocess
import threading
import time
from typing import Any

import pytest
from serve_helpers import SCENES, SIMRUN, serve
from test_serve_recording import SENSOR_SCENE

from simrun.record.simlog import Simlog

BOEBOT = SCENES / "boebot.toml"
SESSIONS = int(os.environ.get("SIMRUN_SIGNAL_SESSIONS", "4"))


def _resim(record: Any) -> str:
    done = subprocess.run([SIMRUN, "resim", str(record)], capture_output=True, text=True, check=False, timeout=300)
    assert done.returncode == 0, (done.stdout, done.stderr)
    assert "bit-identical" in done.stdout, done.stdout
    return done.stdout


@pytest.mark.parametrize("session", range(SESSIONS))
def test_a_signal_at_a_random_point_of_a_lockstep_session_keeps_a_complete_recording(tmp_path, session):
    rng = random.Random(39_000 + session)
    stop = signal.SIGTERM if session % 2 == 0 else signal.SIGINT
    record = tmp_path / "run.simlog"
    answers: list[Any] = []
    with serve(BOEBOT, "--lockstep", "--record", str(record), stop=stop) as server:
        server.post("/api/step", {"steps": rng.randint(1, 300)})
        server.post("/api/services/DriveService/boebot/cmd_vel", {"args": [0.1, 0.3]})
        # a long step (100,000 steps: tens of seconds) that the signal lands in, or a short one
        steps = 100_000 if rng.random() < 0.7 else rng.randint(1, 2000)
        answered: list[float] = []

        def step() -> None:
            answers.append(server.request("POST", "/api/step", {"steps": steps}))
            answered.append(time.monotonic())

        worker = threading.Thread(target=step)
        worker.start()
        # a long step (boebot: >= 4 s of wall time) is running when the signal comes 0.5-1.5 s later
        time.sleep(rng.uniform(0.5, 1.5) if steps == 100_000 else rng.uniform(0.0, 1.5))
        signalled = time.monotonic()
    stopped_after = time.monotonic() - signalled
    worker.join(30)
    assert not worker.is_alive()
    assert f"wrote {record}" in server.output[0]
    assert not [p for p in tmp_path.iterdir() if p != record]  # no spool or temporary file left
    status, answer = answers[0]
    assert stopped_after < 30  # the step stopped at its next 50 steps (before: it ran on, answered 500)
    if steps == 100_000 and answered[0] > signalled:  # answered after the signal: cancelled by the shutdown
        assert status == 200 and answer["cancelled"] == "shutdown", (status, answer)
    elif steps == 100_000:  # an idle machine can run all 200 s before the signal (about 1 s): not cancelled
        assert status == 200 and answer["cancelled"] is None and answer["stepped"] == steps, (status, answer)
    if status == 200 and isinstance(answer, dict):  # the step answered with the state it stopped at
        assert answer["stepped"] <= answer["requested"] == steps
        assert answer["cancelled"] in (None, "shutdown")
        assert answer["cancelled"] is None or answer["stepped"] < steps
    log = Simlog(record)
    try:
        assert log.truncated is None
        frames = list(log.records())
        assert [c.call for c in log.commands()] == ["cmd_vel"]
    finally:
        log.close()
    if status == 200 and isinstance(answer, dict):
        assert frames[-1].time <= answer["time"] + 1e-9
    _resim(record)


def test_a_step_past_its_deadline_answers_with_the_state_it_reached():
    from simrun.serve.loop import STEP_CHUNK, ServeOptions, SimLoop

    loop = SimLoop(ServeOptions(scene=BOEBOT, lockstep=True))
    loop.start()
    try:
        answer = loop.call(loop.step_request(100_000, deadline=0.3)).result(60)
        world_time = loop.call(lambda world: float(world.data.time)).result(60)
    finally:
        loop.stop()
    assert answer["cancelled"] == "deadline" and 0 < answer["stepped"] < 100_000
    assert answer["stepped"] % STEP_CHUNK == 0
    assert answer["time"] == world_time  # the world is exactly where the answer says
    assert answer["steps"] == answer["stepped"]


def test_sigterm_during_a_long_step_with_a_webcam_exits_0_with_the_recording(tmp_path):
    """The issue's case: a step of 100,000 steps with a camera rendering (longer than the 30 s the server
    used to wait for its world thread before exiting under it: exit 139, no recording)."""
    scene = tmp_path / "robot.toml"
    scene.write_text(SENSOR_SCENE)
    record = tmp_path / "run.simlog"
    answers: list[Any] = []
    with serve(
        scene, "--lockstep", "--record", str(record), "--record-sensors", "view_cam,imu", stop=signal.SIGTERM
    ) as server:
        worker = threading.Thread(
            target=lambda: answers.append(server.request("POST", "/api/step", {"steps": 100_000}))
        )
        worker.start()
        time.sleep(1.5)
        signalled = time.monotonic()
    assert time.monotonic() - signalled < 30
    worker.join(30)
    status, answer = answers[0]
    assert status == 200 and answer["cancelled"] == "shutdown" and 0 < answer["stepped"] < 100_000
    log = Simlog(record)
    try:
        assert log.truncated is None
        counts = log.counts()
    finally:
        log.close()
    assert abs(counts["images.view_cam"] - answer["time"] * 15) <= 2
    _resim(record)
