"""simrun serve --foxglove-port: the live world in the Foxglove WebSocket protocol, read by a protocol client here.

The client is written from the protocol's specification (github.com/foxglove/ws-protocol: JSON control
messages, binary message data = opcode 1, subscription id u32, log time u64, payload), and decodes the
payload with the protobuf schema the server advertises. Ground truth: the server's own state at that time.
"""

from __future__ import annotations

import base64
import json
import struct

import pytest
from serve_helpers import SCENES, serve

pytest.importorskip("google.protobuf", reason="pip install protobuf (mcap-protobuf-support brings it)")


def _message_class(channel: dict) -> type:
    from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

    assert channel["encoding"] == "protobuf" and channel["schemaEncoding"] == "protobuf"
    files = descriptor_pb2.FileDescriptorSet.FromString(base64.b64decode(channel["schema"]))
    pool = descriptor_pool.DescriptorPool()
    for file in files.file:
        pool.Add(file)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(channel["schemaName"]))


def test_foxglove_clients_get_body_transforms_and_laser_scans_of_the_live_world():
    from websockets.sync.client import connect

    with serve(SCENES / "pioneer_room.toml", "--lockstep", "--foxglove-port", "0") as server:
        line = server.process.stdout.readline()
        assert line.startswith("foxglove ws://127.0.0.1:")
        with connect(line.split()[1], subprotocols=["foxglove.sdk.v1", "foxglove.websocket.v1"], open_timeout=10) as ws:
            channels: dict[str, dict] = {}
            while "/tf" not in channels or "/sensors/laser" not in channels:
                control = json.loads(ws.recv(timeout=10))
                if control["op"] == "advertise":
                    channels.update({c["topic"]: c for c in control["channels"]})
            assert channels["/tf"]["schemaName"] == "foxglove.FrameTransforms"
            assert channels["/sensors/laser"]["schemaName"] == "foxglove.LaserScan"
            subscriptions = [
                {"id": 1, "channelId": channels["/tf"]["id"]},
                {"id": 2, "channelId": channels["/sensors/laser"]["id"]},
            ]
            ws.send(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))
            server.post("/api/services/DriveService/p3dx/cmd_vel", {"args": [0.3, 0.5]})
            state = server.post("/api/step", {"seconds": 1.0})
            transforms, scan = _message_class(channels["/tf"]), _message_class(channels["/sensors/laser"])
            tf_at_state = scans = None
            while tf_at_state is None or scans is None:
                frame = ws.recv(timeout=10)
                if isinstance(frame, str):
                    continue
                opcode, subscription, log_time = struct.unpack_from("<BIQ", frame)
                assert opcode == 1
                if subscription == 1 and log_time == round(state["time"] * 1e9):
                    tf_at_state = transforms.FromString(frame[13:])
                elif subscription == 2:
                    scans = scan.FromString(frame[13:])
    p3dx = next(t for t in tf_at_state.transforms if t.child_frame_id == "p3dx")
    x, y, z, qw, qx, qy, qz = state["poses"]["p3dx"]
    assert (p3dx.parent_frame_id, p3dx.translation.x, p3dx.translation.y, p3dx.translation.z) == ("world", x, y, z)
    assert (p3dx.rotation.w, p3dx.rotation.x, p3dx.rotation.y, p3dx.rotation.z) == (qw, qx, qy, qz)
    assert abs(x - 0.5) > 0.05  # it drove
    assert {t.child_frame_id for t in tf_at_state.transforms} == set(state["poses"])
    assert scans.frame_id == "p3dx" and len(scans.ranges) == 360 and 0 < min(scans.ranges) < 8.0
