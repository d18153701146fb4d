"""simrun serve: the world never waits for a client (scene GLB from a cache, reads during a long step, images).

A real server on 127.0.0.1; the world's pace is read from its simulated clock against this process's wall
clock. The GLB is checked against the server's own catalogue (every body a node), the images against each
other (the JPEG of a frame looks like its PNG) and against the camera's size in the scene.
"""

from __future__ import annotations

import base64
import io
import json
import struct
import threading
import time
import urllib.request

import numpy as np
from serve_helpers import SCENES, serve
from test_serve_limits import _real_time_factor

BOEBOT, SENSORS = SCENES / "boebot.toml", SCENES / "boebot_sensors.toml"


def _glb_nodes(data: bytes) -> set[str]:
    """The node names of a binary glTF (its JSON chunk)."""
    magic, version, length = struct.unpack_from("<4sII", data)
    assert magic == b"glTF" and version == 2 and length == len(data)
    size, kind = struct.unpack_from("<I4s", data, 12)
    assert kind == b"JSON"
    return {node.get("name", "") for node in json.loads(data[20 : 20 + size])["nodes"]}


def test_four_clients_looping_the_scene_glb_keep_the_real_time_factor():
    with serve(BOEBOT) as server:
        bodies = set(server.get("/api/world")["bodies"][1:])
        stop = threading.Event()
        answers: list[bytes] = []

        def loop_glb() -> None:
            while not stop.is_set():
                with urllib.request.urlopen(server.url + "api/scene.glb", timeout=30) as response:
                    answers.append(response.read())

        clients = [threading.Thread(target=loop_glb, daemon=True) for _ in range(4)]
        for client in clients:
            client.start()
        try:
            rtf, latency = _real_time_factor(server)
        finally:
            stop.set()
            for client in clients:
                client.join(30)
        assert rtf >= 0.8, rtf
        assert latency < 3.0, latency
        assert len(answers) >= 8
        assert len(set(answers)) == 1  # one build per compiled model
        assert bodies <= _glb_nodes(answers[0])


def test_reads_are_answered_during_a_long_step_and_changes_wait_for_its_end():
    with serve(BOEBOT, "--lockstep") as server:
        results: dict[str, object] = {}

        def long_step() -> None:
            results["step"] = server.post("/api/step", {"steps": 100_000})

        def pause() -> None:
            results["pause"] = server.post("/api/pause")
            results["pause_at"] = time.monotonic()

        stepping = threading.Thread(target=long_step)
        stepping.start()
        time.sleep(0.3)
        changing = threading.Thread(target=pause)
        changing.start()
        times = []
        for _ in range(3):  # answered at once, from between two chunks of the step: the time moves on
            started = time.monotonic()
            times.append(server.get("/api/state")["time"])
            assert time.monotonic() - started < 3.0
            time.sleep(0.1)
        sensor = server.get("/api/sensors")  # a route without the world thread
        assert isinstance(sensor, list)
        stepping.join(60)
        changing.join(60)
        step = results["step"]
        assert isinstance(step, dict) and step["stepped"] > 0
        # non-decreasing, the first while the step ran (on an idle machine its 200 s take about 1.5 s)
        assert 0 < times[0] <= times[1] <= times[2] <= step["time"] and times[0] < step["time"]
        assert step["cancelled"] in (None, "deadline")
        # the pause ran after the step had ended, at the time it ended
        pause = results["pause"]
        assert isinstance(pause, dict) and pause["paused"] is True and pause["time"] == step["time"]


def test_camera_images_as_png_and_jpeg_on_the_route_and_the_stream():
    from PIL import Image
    from websockets.sync.client import connect

    with serve(SENSORS) as server:
        deadline = time.monotonic() + 60
        while server.get("/api/sensors/view_cam")["samples"] < 1:
            assert time.monotonic() < deadline
            time.sleep(0.2)
        server.post("/api/pause")
        status_png, png = server.request("GET", "/api/sensors/view_cam/image")
        status_jpeg, jpeg = server.request("GET", "/api/sensors/view_cam/image?format=jpeg")
        assert status_png == 200 and status_jpeg == 200
        png_image, jpeg_image = Image.open(io.BytesIO(png)), Image.open(io.BytesIO(jpeg))
        assert (png_image.format, png_image.size) == ("PNG", (160, 120))
        assert (jpeg_image.format, jpeg_image.size) == ("JPEG", (160, 120))
        difference = np.abs(np.asarray(png_image.convert("RGB"), int) - np.asarray(jpeg_image.convert("RGB"), int))
        assert difference.mean() < 8, difference.mean()  # the same frame, JPEG's loss only
        server.post("/api/resume")
        stream = server.url.replace("http://", "ws://") + "api/stream?sensors=&poses=0&images=view_cam&format=png"
        with connect(stream, open_timeout=10, max_size=None) as ws:
            assert json.loads(ws.recv(timeout=10))["type"] == "hello"
            while (message := json.loads(ws.recv(timeout=60)))["type"] != "image":
                pass
        assert message["format"] == "png" and message["name"] == "view_cam"
        streamed = Image.open(io.BytesIO(base64.b64decode(message["data"])))
        assert (streamed.format, streamed.size) == ("PNG", (160, 120))
        with connect(stream.replace("format=png", "format=bmp"), open_timeout=10) as ws:
            refused = json.loads(ws.recv(timeout=10))
        assert (refused["type"], refused["status"], refused["field"]) == ("error", 422, "format")
