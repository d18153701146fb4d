"""The live Foxglove server follows edits: an inserted robot's channels are advertised, a removed one's withdrawn.

The client speaks ``foxglove.websocket.v1`` from its specification (github.com/foxglove/ws-protocol: the
server's ``advertise`` / ``unadvertise`` JSON, the client's ``subscribe``, binary message data = opcode ``0x01``,
subscription id u32, log time u64 ns, payload), as tests/test_foxglove_client.py does, and decodes protobuf
payloads with the advertised FileDescriptorSet. Ground truth: the server's own pose answers (MuJoCo's
``xpos`` of the body) and the scene after the edit.
"""

from __future__ import annotations

import json
import struct
import time
from typing import Any

import pytest
from scene_text import boebot_scene
from serve_helpers import serve
from test_foxglove_client import _decoder

from simrun.client import Client

pytest.importorskip("google.protobuf", reason="pip install protobuf (mcap-protobuf-support brings it)")

SCENE = boebot_scene(
    entities="""
[[entities]]
type = "Box"
name = "crate"
free = true
mass = 2.0
dimensions = [0.2, 0.2, 0.2]
pose = { position = [1.0, 0.0, 0.1] }
"""
)
BEFORE = {"/clock", "/tf", "/tf_static", "/scene", "/boebot/pose", "/boebot/joint_states", "/boebot/odometry"}
BOT2 = {"/bot2/pose", "/bot2/joint_states", "/bot2/odometry", "/sensors/imu2"}


class Listener:
    """A protocol client's view: channels advertised now (by topic), message frames by subscription id."""

    def __init__(self, ws: Any) -> None:
        self.ws = ws
        self.channels: dict[str, dict] = {}
        self.unadvertised: list[int] = []
        self.frames: list[bytes] = []

    def pump(self, seconds: float) -> None:
        """Read what comes for ``seconds`` (or until quiet for 1 s)."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            try:
                frame = self.ws.recv(timeout=1.0)
            except TimeoutError:
                return
            if isinstance(frame, bytes):
                self.frames.append(frame)
                continue
            control = json.loads(frame)
            if control["op"] == "advertise":
                self.channels.update({c["topic"]: c for c in control["channels"]})
            elif control["op"] == "unadvertise":
                self.unadvertised += control["channelIds"]
                gone = set(control["channelIds"])
                self.channels = {t: c for t, c in self.channels.items() if c["id"] not in gone}

    def until(self, wanted: set[str], absent: set[str] = frozenset(), seconds: float = 15.0) -> None:
        end = time.monotonic() + seconds
        while (not wanted <= set(self.channels) or absent & set(self.channels)) and time.monotonic() < end:
            self.pump(1.0)
        assert wanted <= set(self.channels), wanted - set(self.channels)
        assert not absent & set(self.channels), absent & set(self.channels)


def _messages(listener: Listener, subscription: int, decode: Any) -> list[tuple[int, Any]]:
    out = []
    for frame in listener.frames:
        opcode, sub, log_time = struct.unpack_from("<BIQ", frame)
        if opcode == 0x01 and sub == subscription:
            out.append((log_time, decode(frame[13:])))
    return out


def test_foxglove_channels_follow_an_insert_a_new_service_and_sensor_and_a_remove(tmp_path):
    from websockets.sync.client import connect

    path = tmp_path / "scene" / "fox.toml"
    path.parent.mkdir()
    path.write_text(SCENE)
    with serve(path, "--lockstep", "--edit", "--foxglove-port", "0") as server:
        line = server.process.stdout.readline()
        assert line.startswith("foxglove ws://127.0.0.1:")
        sim = Client(server.url)
        with connect(line.split()[1], subprotocols=["foxglove.websocket.v1"], open_timeout=10, max_queue=None) as ws:
            assert json.loads(ws.recv(timeout=10))["op"] == "serverInfo"
            fox = Listener(ws)
            fox.until(BEFORE)
            assert set(fox.channels) == BEFORE
            tf_id = fox.channels["/tf"]["id"]

            sim.insert({"type": "BoeBot", "name": "bot2", "pose": {"position": [0.0, 1.0, 0.001]}})
            sim.add_service({"type": "DriveService", "entity": "bot2"})
            sim.add_sensor({"type": "IMU", "name": "imu2", "entity": "bot2", "rate": 50.0})
            sim.remove("crate")
            sim.step(seconds=0.1)  # the loop publishes: the channels follow the world first
            fox.until(BEFORE | BOT2)
            assert set(fox.channels) == BEFORE | BOT2
            assert fox.channels["/tf"]["id"] == tf_id  # a channel that stays is the same channel
            topics = ["/bot2/pose", "/tf", "/sensors/imu2", "/scene"]
            subs = [{"id": k, "channelId": fox.channels[t]["id"]} for k, t in enumerate(topics, start=1)]
            decoders = {k: _decoder(fox.channels[t]) for k, t in enumerate(topics, start=1)}
            ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
            time.sleep(1.0)  # subscriptions are not acknowledged by the protocol
            sim.call("DriveService", "bot2", "cmd_vel", 0.1, 0.0)
            state = sim.step(seconds=1.0)
            fox.pump(4.0)

            at = round(state["time"] * 1e9)
            pose = [m for t, m in _messages(fox, 1, decoders[1]) if t == at]
            assert pose, "no /bot2/pose at the last step"
            x, y, z = state["poses"]["bot2"][:3]
            assert (pose[0].pose.position.x, pose[0].pose.position.y, pose[0].pose.position.z) == (x, y, z)
            assert x > 0.02  # bot2 drove through its added drive service
            tf = next(m for t, m in _messages(fox, 2, decoders[2]) if t == at)
            frames = {f.child_frame_id for f in tf.transforms}
            assert "bot2" in frames and "crate" not in frames
            assert _messages(fox, 3, decoders[3]), "no IMU reading on /sensors/imu2"
            scenes = [m for _, m in _messages(fox, 4, decoders[4])]
            assert scenes and "bot2" in {e.id for e in scenes[-1].entities}
            assert "crate" not in {e.id for e in scenes[-1].entities}

            withdrawn = {fox.channels[t]["id"] for t in BOT2}
            sim.remove("bot2")  # its drive and IMU go with it
            sim.step(seconds=0.1)
            fox.until(BEFORE, absent=BOT2)
            assert set(fox.channels) == BEFORE
            assert withdrawn <= set(fox.unadvertised)
