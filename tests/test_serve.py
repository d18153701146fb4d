"""simrun serve: a real server on 127.0.0.1 drives the Boe-Bot; the simulator's body pose is the ground truth."""

from __future__ import annotations

import json
import math
import signal
import socket
import time

import numpy as np
import pytest
from serve_helpers import SCENES, serve, wait_idle

from simrun.client import Client, ClientError

BOEBOT = SCENES / "boebot.toml"
START = np.array([1.0, 1.0])  # boebot.toml puts the robot at (1, 1), heading +X (the box is ahead: drive back)


def _travel(pose: list[float]) -> np.ndarray:
    return np.array(pose[:2]) - START


def test_http_drives_the_boebot_one_metre_and_the_simulator_agrees():
    with serve(BOEBOT, "--rate", "1000") as server:
        world = server.get("/api/world")
        assert [s["type"] for s in world["services"]] == ["DriveService"]
        assert "drive_distance" in world["services"][0]["commands"]
        answer = server.post("/api/services/DriveService/boebot/drive_distance", {"args": [-1.0, 0.6]})
        assert answer["applied"] and answer["time"] >= 0
        odometry = wait_idle(server, "DriveService", "boebot")["odometry"]
        time.sleep(0.3)  # let it settle (0.3 wall s is many simulated seconds here)
        state = server.get("/api/state")
        travelled = _travel(state["poses"]["boebot"])
        assert np.linalg.norm(travelled) == pytest.approx(1.0, abs=0.02)
        assert travelled[0] < -0.98 and abs(travelled[1]) < 0.005  # backwards, straight
        assert math.hypot(odometry["x"] - travelled[0], odometry["y"] - travelled[1]) < 0.02
        assert state["time"] > 5.0 and state["mode"] == "realtime"


def test_python_client_drives_the_boebot_one_metre():
    with serve(BOEBOT, "--rate", "1000") as server:
        sim = Client(server.url)
        drive = sim.service("DriveService", "boebot")
        assert drive.drive_distance(metres=-1.0, power=0.6)["applied"]
        deadline = time.monotonic() + 60
        while drive.state()["busy"]:
            assert time.monotonic() < deadline
            time.sleep(0.05)
        time.sleep(0.3)
        travelled = _travel(sim.pose("boebot"))
        assert np.linalg.norm(travelled) == pytest.approx(1.0, abs=0.02)
        with pytest.raises(ClientError) as refused:
            drive.drive_distance(metres=1.0, speed=3)
        assert refused.value.status == 422 and refused.value.field == "args.speed"


def test_pause_step_rate_reset_and_the_stream():
    with serve(BOEBOT, "--paused") as server:
        sim = Client(server.url)
        first = sim.state()
        assert first["paused"] and first["time"] == 0.0
        after = sim.step(steps=50)
        assert after["time"] == pytest.approx(0.1) and after["steps"] == 50
        assert sim.step(seconds=0.2)["time"] == pytest.approx(0.3)
        assert sim.set_rate(2.0)["rate"] == 2.0
        messages = sim.stream()
        hello = next(messages)
        assert hello["type"] == "hello" and hello["api_version"] == "1.0"
        sim.resume()
        poses = [m for m in (next(messages) for _ in range(5)) if m["type"] == "poses"]
        assert poses and "boebot" in poses[-1]["poses"]
        messages.close()
        time.sleep(0.5)
        running = sim.state()
        assert running["time"] > 0.3 and not running["paused"]
        with pytest.raises(ClientError) as refused:
            sim.step(steps=1)  # real time: stepping needs a pause
        assert refused.value.status == 409
        reset = sim.reset()
        assert reset["time"] < 0.05
        assert reset["poses"]["boebot"][:2] == pytest.approx(list(START), abs=1e-3)
        document = server.get("/openapi.json")
        assert document["openapi"].startswith("3.") and document["info"]["version"] == "1.0"
        assert "/api/services/DriveService/boebot/drive_distance" in document["paths"]


def test_sigterm_stops_cleanly_and_writes_the_recording_and_its_mcap(tmp_path):
    from mcap.reader import make_reader

    from simrun.record.simlog import Simlog

    record = tmp_path / "run.simlog"
    args = ["--rate", "100", "--record", str(record), "--record-as", "mcap"]
    with serve(BOEBOT, *args, stop=signal.SIGTERM) as server:
        server.post("/api/services/DriveService/boebot/cmd_vel", {"args": [0.1, 0.0]})
        time.sleep(0.5)
    assert record.is_file() and not list(tmp_path.glob(".*"))  # no spool or temporary file left
    assert f"wrote {record}" in server.output[0] and f"wrote {record.with_suffix('.mcap')}" in server.output[0]
    log = Simlog(record)
    try:
        frames = sum(1 for _ in log.records())
        assert [c.call for c in log.commands()] == ["cmd_vel"]
    finally:
        log.close()
    with record.with_suffix(".mcap").open("rb") as stream:
        summary = make_reader(stream).get_summary()
    counts = {c.topic: summary.statistics.channel_message_counts[c.id] for c in summary.channels.values()}
    assert counts["/tf"] == frames > 10


def test_other_hosts_need_a_token():
    from simrun.errors import UsageError
    from simrun.serve.server import check_access

    with pytest.raises(UsageError, match="--token"):
        check_access("0.0.0.0", None)
    with pytest.raises(UsageError, match="at least 16"):
        check_access("127.0.0.1", "short")
    check_access("127.0.0.1", None)
    check_access("0.0.0.0", "x" * 16)


def test_a_token_is_required_when_given():
    token = "t" * 24
    with serve(BOEBOT, "--token", token) as server:
        status, body = server.request("GET", "/api/state")
        assert status == 401 and body["field"] == "authorization"
        status, body = server.request("GET", "/api/state", headers={"Authorization": f"Bearer {token}"})
        assert status == 200 and "poses" in body
        assert Client(server.url, token=token).state()["mode"] == "realtime"


def _raw(url: str, request: bytes) -> bytes:
    host, port = url.split("//")[1].rstrip("/").split(":")
    with socket.create_connection((host, int(port)), timeout=10) as sock:
        sock.sendall(request)
        chunks = []
        while chunk := sock.recv(65536):
            chunks.append(chunk)
    return b"".join(chunks)


def test_a_foreign_host_header_is_refused():
    with serve(BOEBOT) as server:
        answer = _raw(server.url, b"GET /api/state HTTP/1.1\r\nHost: evil.example:80\r\nConnection: close\r\n\r\n")
        head, _, body = answer.partition(b"\r\n\r\n")
        assert head.startswith(b"HTTP/1.1 403") and json.loads(body)["field"] == "host"


@pytest.mark.parametrize(
    ("args", "code", "message"),
    [
        (["--host", "0.0.0.0"], 2, "error: --host 0.0.0.0 makes the world reachable from other machines: give --token"),
        (["--token", "short"], 2, "error: --token must be at least 16 characters"),
        (["--rate", "nan"], 2, "is not in [0.01, 1000]"),
    ],
    ids=["open-host-without-token", "short-token", "nan-rate"],
)
def test_unsafe_or_bad_options_are_refused_before_listening(args, code, message):
    import subprocess

    from serve_helpers import SIMRUN

    done = subprocess.run(
        [SIMRUN, "serve", str(BOEBOT), "--port", "0", *args], capture_output=True, text=True, timeout=60
    )
    assert done.returncode == code and message in done.stderr and "serving" not in done.stdout
    assert "Traceback" not in done.stderr


def test_a_refused_scene_fails_with_one_line_before_listening(tmp_path):
    import subprocess

    from serve_helpers import SIMRUN

    scene = tmp_path / "bad.toml"
    scene.write_text('[[entities]]\ntype = "Box"\nname = "b"\ndimensions = [0.1, -1, 0.1]\n')
    done = subprocess.run([SIMRUN, "serve", str(scene), "--port", "0"], capture_output=True, text=True, timeout=60)
    assert done.returncode == 1 and done.stderr.startswith(f"error: {scene}:") and done.stderr.count("\n") == 1
    assert "serving" not in done.stdout
