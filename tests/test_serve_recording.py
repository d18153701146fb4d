"""A served session's ``.simlog`` cannot be lost: written in chunks as it runs (version 1.2), readable after a
SIGKILL up to its last chunk, 2,000 commands in one session, a full disk that ends only the recording, and
never a user's file touched. Ground truth: ``simrun resim`` (a separate process) re-steps the recorded
commands in MuJoCo and compares every recorded state bit for bit."""

from __future__ import annotations

import contextlib
import resource
import signal
import subprocess
from collections.abc import Iterator

import pytest
from serve_helpers import SCENES, SIMRUN, Server, serve

from simrun.record.simlog import Simlog

BOEBOT = SCENES / "boebot.toml"
#: A Boe-Bot with a 100 Hz IMU, a 10 Hz laser and a 320x240 webcam at 15 Hz.
SENSOR_SCENE = """
[world]
timestep = 0.002

[[entities]]
type = "Ground"
name = "ground"

[[entities]]
type = "BoeBot"
name = "boebot"
pose = { position = [1.0, 1.0, 0.001] }

[[entities]]
type = "Box"
name = "box"
dimensions = [0.2, 0.2, 0.2]
pose = { position = [1.6, 1.0, 0.1] }

[[services]]
type = "DriveService"
entity = "boebot"

[[entities]]
type = "Camera"
name = "view"
eye = [1.4, 0.58, 1.09]
target = [1.4, 1.09, 0.0]
main = true

[[sensors]]
type = "LaserRangeFinder"
name = "laser"
entity = "boebot"
rays = 91
rate = 10.0

[[sensors]]
type = "IMU"
name = "imu"
entity = "boebot"
rate = 100.0

[[sensors]]
type = "Webcam"
name = "view_cam"
camera = "view"
width = 320
height = 240
rate = 15.0
"""


def _resim(record) -> subprocess.CompletedProcess[str]:
    done = subprocess.run([SIMRUN, "resim", str(record)], capture_output=True, text=True, check=False, timeout=300)
    assert done.returncode == 0, (done.stdout, done.stderr)
    assert "bit-identical" in done.stdout, done.stdout
    return done


def _session(server: Server, rounds: int) -> None:
    for k in range(rounds):
        server.post("/api/step", {"steps": 250})
        server.post("/api/services/DriveService/boebot/cmd_vel", {"args": [0.05 * (k % 4), 0.1]})


def test_a_sigkill_leaves_a_recording_read_up_to_its_last_chunk(tmp_path):
    record = tmp_path / "run.simlog"
    with pytest.raises(AssertionError) as stopped, serve(BOEBOT, "--lockstep", "--record", str(record)) as server:
        _session(server, 12)  # 6 s simulated: a chunk at every 1 s checkpoint
        server.process.kill()
        server.process.wait(30)
    assert stopped.value.args[0][0] == -signal.SIGKILL
    log = Simlog(record)
    try:
        assert log.truncated is not None and "not finished" in log.truncated
        frames = list(log.records())
        commands = log.commands()
    finally:
        log.close()
    assert frames[-1].time >= 5.0 - 1e-9 and len(frames) >= 250  # everything up to the last checkpoint
    assert 10 <= len(commands) <= 12 and all(c.t <= frames[-1].time + 1e-9 for c in commands[:-1])
    done = _resim(record)
    assert done.stderr.count("note: ") == 1 and "not finished" in done.stderr
    glb = tmp_path / "run.glb"
    replayed = subprocess.run([SIMRUN, "replay", str(record), "--glb", str(glb)], capture_output=True, text=True,
                              check=False, timeout=300)  # fmt: skip
    assert replayed.returncode == 0, replayed.stderr
    assert glb.stat().st_size > 0 and replayed.stderr.count("note: ") == 1


def test_two_thousand_commands_leave_a_readable_recording_with_a_small_header(tmp_path):
    record = tmp_path / "run.simlog"
    spool = tmp_path / ".run.simlog.spool"  # a user's file named like the old spool
    spool.write_bytes(b"mine")
    with serve(BOEBOT, "--lockstep", "--record", str(record)) as server:
        for k in range(2000):
            if k % 100 == 0:
                server.post("/api/step", {"steps": 25})
            server.post("/api/services/DriveService/boebot/cmd_vel", {"args": [0.001 * (k % 50), 0.0]})
        server.post("/api/step", {"steps": 25})
        stopped = server.post("/api/recording/stop")
        assert stopped["written"] == [str(record)]
        log = Simlog(record)  # finished while the server runs: whole, with its end record
        try:
            assert log.truncated is None and len(log.commands()) == 2000
            assert log._start < 4096  # the header does not grow with the commands
        finally:
            log.close()
    assert spool.read_bytes() == b"mine"
    assert sorted(p.name for p in tmp_path.iterdir()) == [".run.simlog.spool", "run.simlog"]
    _resim(record)


@contextlib.contextmanager
def _file_size_limit(limit: int) -> Iterator[None]:
    """Files written by processes started in the block stop at ``limit`` bytes (EFBIG, as a full disk)."""
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    previous = signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # an ignored signal stays ignored across exec
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
        signal.signal(signal.SIGXFSZ, previous)


def test_a_full_disk_ends_the_recording_with_one_error_and_keeps_what_was_written(tmp_path):
    record = tmp_path / "run.simlog"
    limit = 64 * 1024
    limited = _file_size_limit(limit)
    with (
        pytest.raises(AssertionError) as stopped,
        limited,
        serve(BOEBOT, "--lockstep", "--record", str(record)) as server,
    ):
        _session(server, 40)  # 20 s simulated: far more than 64 KiB of frames
        state = server.get("/api/state")
        assert state["recording"]["error"] and not state["recording"]["active"]
        assert state["time"] == pytest.approx(20.0)  # the world went on
    returncode, out, err = stopped.value.args[0]
    assert returncode == 1 and f"wrote {record}" in out
    assert err.count("error: ") == 1 and "File too large" in err and "Traceback" not in err
    assert record.stat().st_size <= limit
    log = Simlog(record)
    try:
        assert log.truncated is not None
        frames = list(log.records())
    finally:
        log.close()
    assert frames and frames[-1].time > 1.0
    _resim(record)


def test_sensors_are_recorded_at_their_own_rate_and_images_once_per_rendered_frame(tmp_path):
    text = SENSOR_SCENE
    scene = tmp_path / "robot.toml"
    scene.write_text(text)
    record = tmp_path / "run.simlog"
    with serve(scene, "--lockstep", "--record", str(record), "--record-sensors", "imu,view_cam,laser") as server:
        for _ in range(5):
            server.post("/api/step", {"steps": 500})  # 5 s simulated
        assert server.get("/api/state")["time"] == pytest.approx(5.0)
    log = Simlog(record)
    try:
        counts = log.counts()
        images = list(log.images())
    finally:
        log.close()
    duration = 5.0
    assert abs(counts["frames"] - duration * 50) <= 1  # the 50 Hz frame grid
    assert abs(counts["images.view_cam"] - duration * 15) <= 1  # once per rendered frame, not per 20 ms frame
    assert abs(counts["sensor_samples.imu"] - duration * 100) <= 1  # every 100 Hz sample, not one per frame
    assert abs(counts["sensor_samples.laser"] - duration * 10) <= 1
    times = [t for t, name, _, _ in images]
    assert times == sorted(times) and len(set(times)) == len(times)
    from io import BytesIO

    from PIL import Image

    first = Image.open(BytesIO(images[0][3]))
    assert first.format == "PNG" and first.size == (320, 240)
    _resim(record)


class _Crash:
    """A controller that fails at t >= 0.5 s (a bug in the simulation thread)."""

    period, next_time = 0.01, 0.0

    def tick(self, model, data) -> None:
        if data.time >= 0.5:
            raise RuntimeError("a bug at 0.5 s")

    def reset(self, model, data) -> None: ...

    def snapshot(self) -> dict:
        return {}

    def restore(self, state) -> None: ...


def test_a_crash_of_the_simulation_thread_still_finishes_the_recording(tmp_path):
    import time

    from simrun.serve.loop import ServeOptions, SimLoop
    from simrun.serve.recording import LiveRecording

    record = tmp_path / "run.simlog"
    options = ServeOptions(scene=BOEBOT, rate=10.0, record=record)
    loop = SimLoop(options, lambda world, loop: LiveRecording(world, loop, record, BOEBOT))
    loop.start()
    loop.call(lambda world: world.controllers.insert(0, _Crash())).result(30)
    deadline = time.monotonic() + 60
    while loop.running and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not loop.running and loop.error is not None and "a bug at 0.5 s" in loop.error
    log = Simlog(record)
    try:
        assert log.truncated is None  # finished: its end record written
        frames = list(log.records())
    finally:
        log.close()
    assert frames[-1].time == pytest.approx(0.5, abs=0.021)
