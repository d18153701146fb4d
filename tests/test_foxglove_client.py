"""simrun serve --foxglove-port as a Foxglove user meets it: a client offering only ``foxglove.websocket.v1``.

The client here is written from the protocol's specification (github.com/foxglove/ws-protocol, v1: the
server's ``serverInfo`` and ``advertise`` JSON, the client's ``subscribe``, binary message data = opcode
``0x01``, subscription id u32, log time u64 nanoseconds, payload), not from the server's code; it decodes
each protobuf payload with the FileDescriptorSet the server advertises and each JSON payload as JSON.
The MCAP of the same session (``--foxglove-mcap``) is read with the ``mcap`` reader and its protobuf decoder.
Ground truth: the server's state answers (poses, time), MuJoCo's own load of the scene (joints), gravity.
"""

from __future__ import annotations

import base64
import io
import json
import math
import struct
import time
from pathlib import Path

import mujoco
import pytest
from serve_helpers import SCENES, serve

from simrun.scene.scene_file import load_scene

pytest.importorskip("google.protobuf", reason="pip install protobuf (mcap-protobuf-support brings it)")

SCENE = SCENES / "foxglove_robot.toml"
#: Every channel the scene has, with its schema: one robot (boebot: pose, wheel joints, a drive), a laser,
#: an IMU and a webcam, the clock and the scene entities.
EXPECTED = {
    "/clock": "simrun.Clock",
    "/tf": "foxglove.FrameTransforms",
    "/tf_static": "foxglove.FrameTransforms",
    "/scene": "foxglove.SceneUpdate",
    "/boebot/pose": "foxglove.PoseInFrame",
    "/boebot/joint_states": "foxglove.JointStates",
    "/boebot/odometry": "foxglove.PoseInFrame",
    "/sensors/laser": "foxglove.LaserScan",
    "/sensors/imu": "simrun.Imu",
    "/sensors/view_cam": "foxglove.RawImage",
    "/sensors/view_cam/compressed": "foxglove.CompressedImage",
}


def _decoder(channel: dict) -> object:
    """A function payload -> message for an advertised channel (protobuf from its schema, or JSON)."""
    if channel["encoding"] == "json":
        return lambda payload: json.loads(payload)
    from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

    assert channel["encoding"] == "protobuf" and channel["schemaEncoding"] == "protobuf"
    files = descriptor_pb2.FileDescriptorSet.FromString(base64.b64decode(channel["schema"]))
    pool = descriptor_pool.DescriptorPool()
    for file in files.file:
        pool.Add(file)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(channel["schemaName"])).FromString


def _mcap(path: Path) -> tuple[dict[str, str], dict[str, int], dict[str, object]]:
    """({topic: schema name}, {topic: count}, {topic: first decoded message}) of an MCAP file."""
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    with path.open("rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        schemas = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
        counts = {c.topic: summary.statistics.channel_message_counts[c.id] for c in summary.channels.values()}
        first: dict[str, object] = {}
        for _, channel, _message, decoded in reader.iter_decoded_messages(
            topics=[c.topic for c in summary.channels.values() if c.message_encoding == "protobuf"]
        ):
            first.setdefault(channel.topic, decoded)
    return schemas, counts, first


def test_a_standard_foxglove_client_decodes_every_channel_and_the_session_mcap_agrees(tmp_path):
    from PIL import Image
    from websockets.sync.client import connect

    mcap = tmp_path / "session.mcap"
    record = tmp_path / "run.simlog"
    args = ["--lockstep", "--foxglove-port", "0", "--foxglove-mcap", str(mcap), "--record", str(record),
            "--record-as", "mcap", "--record-sensors", "laser,imu,view_cam"]  # fmt: skip
    received: dict[str, list[tuple[int, object]]] = {}
    states = []
    with serve(SCENE, *args) as server:
        line = server.process.stdout.readline()
        assert line.startswith("foxglove ws://127.0.0.1:")
        with connect(line.split()[1], subprotocols=["foxglove.websocket.v1"], open_timeout=10, max_queue=None) as ws:
            assert ws.subprotocol == "foxglove.websocket.v1"
            info = json.loads(ws.recv(timeout=10))
            assert info["op"] == "serverInfo"
            channels: dict[str, dict] = {}
            while set(channels) != set(EXPECTED):
                control = json.loads(ws.recv(timeout=10))
                if control["op"] == "advertise":
                    channels.update({c["topic"]: c for c in control["channels"]})
                assert set(channels) <= set(EXPECTED), set(channels) - set(EXPECTED)
            assert {t: c["schemaName"] for t, c in channels.items()} == EXPECTED
            topics = sorted(channels)
            subscriptions = [{"id": k, "channelId": channels[t]["id"]} for k, t in enumerate(topics, start=1)]
            ws.send(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))
            decoders = {k: (t, _decoder(channels[t])) for k, t in enumerate(topics, start=1)}
            time.sleep(1.0)  # the subscription is not acknowledged by the protocol: let the server take it
            server.post("/api/services/DriveService/boebot/cmd_vel", {"args": [0.1, 0.5]})
            for _ in range(6):
                states.append(server.post("/api/step", {"seconds": 0.5}))
            while True:  # until the stream is quiet: every message logged reached this client
                try:
                    frame = ws.recv(timeout=3)
                except TimeoutError:
                    break
                if isinstance(frame, str):
                    continue
                opcode, subscription, log_time = struct.unpack_from("<BIQ", frame)
                assert opcode == 0x01
                topic, decode = decoders[subscription]
                received.setdefault(topic, []).append((log_time, decode(frame[13:])))
    assert set(received) == set(EXPECTED), set(EXPECTED) - set(received)

    # one message of each, decoded, against the server's own answers and MuJoCo's load of the scene
    last = states[-1]
    at_last = {
        topic: [m for t, m in messages if t == round(last["time"] * 1e9)] for topic, messages in received.items()
    }
    tf = at_last["/tf"][0]
    x, y, z, qw, qx, qy, qz = last["poses"]["boebot"]
    bot = next(t for t in tf.transforms if t.child_frame_id == "boebot")
    assert (bot.translation.x, bot.translation.y, bot.translation.z) == (x, y, z)
    assert (bot.rotation.w, bot.rotation.x, bot.rotation.y, bot.rotation.z) == (qw, qx, qy, qz)
    assert {t.child_frame_id for t in tf.transforms} >= set(last["poses"])
    pose = at_last["/boebot/pose"][0]
    assert (pose.frame_id, pose.pose.position.x, pose.pose.position.y) == ("world", x, y)
    assert math.hypot(x - 1.0, y - 1.0) > 0.02  # it drove (measured 0.049 m)
    clock = at_last["/clock"][0]
    assert clock["sec"] * 10**9 + clock["nsec"] == round(last["time"] * 1e9)
    model = load_scene(SCENE).model  # MuJoCo's compile of the scene, here
    hinge = {model.joint(j).name for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE}
    joints = at_last["/boebot/joint_states"][0]
    assert {j.name for j in joints.joints} <= hinge and len(joints.joints) == 2
    assert all(math.isfinite(j.position) and math.isfinite(j.velocity) for j in joints.joints)
    odometry = received["/boebot/odometry"][-1][1]
    assert odometry.frame_id == "boebot/odom"
    assert odometry.pose.position.x == pytest.approx(x - 1.0, abs=0.01)  # odometry from the start pose (1, 1)
    assert odometry.pose.position.y == pytest.approx(y - 1.0, abs=0.01)
    scan = received["/sensors/laser"][-1][1]
    assert scan.frame_id == "boebot" and len(scan.ranges) == 91 and 0 < min(scan.ranges) <= 4.0
    imu = received["/sensors/imu"][0][1]
    assert imu["frame_id"] == "boebot" and len(imu["orientation"]) == 4
    assert math.hypot(*imu["accelerometer"]) == pytest.approx(9.81, abs=1.5)  # gravity, the robot barely moving
    raw = received["/sensors/view_cam"][-1][1]
    assert (raw.width, raw.height, raw.encoding, len(raw.data)) == (160, 120, "rgb8", 160 * 120 * 3)
    jpeg = received["/sensors/view_cam/compressed"][-1][1]
    assert jpeg.format == "jpeg" and Image.open(io.BytesIO(jpeg.data)).size == (160, 120)
    scene = received["/scene"][0][1]
    ids = {e.id for e in scene.entities}
    assert {"boebot", "box"} <= ids
    box = next(e for e in scene.entities if e.id == "box")
    assert [(c.size.x, c.size.y, c.size.z) for c in box.cubes] == [pytest.approx((0.2, 0.2, 0.2))]

    # the MCAP of the same session: the same channels, schemas and counts
    schemas, counts, first = _mcap(mcap)
    assert schemas == EXPECTED
    assert counts == {topic: len(messages) for topic, messages in received.items()}
    assert first["/tf"].transforms[0].child_frame_id == received["/tf"][0][1].transforms[0].child_frame_id
    # the recording's MCAP (from the .simlog) has the same channels and schemas, at the recording's frame rate
    recorded, recorded_counts, _ = _mcap(record.with_suffix(".mcap"))
    assert recorded == EXPECTED
    assert recorded_counts["/tf"] > counts["/tf"]  # a frame every 0.02 s; the live stream once per step request


def test_foxglove_mcap_refuses_another_suffix_and_the_recording_path(tmp_path):
    import subprocess

    from serve_helpers import SIMRUN

    bad = tmp_path / "x.bag"
    done = subprocess.run([SIMRUN, "serve", str(SCENE), "--port", "0", "--lockstep", "--foxglove-port", "0",
                           "--foxglove-mcap", str(bad)], capture_output=True, text=True, timeout=120)  # fmt: skip
    assert done.returncode == 1 and "must end in .mcap" in done.stderr and not bad.exists()
    record = tmp_path / "run.simlog"
    clash = record.with_suffix(".mcap")
    args = ["--record", str(record), "--record-as", "mcap", "--foxglove-mcap", str(clash)]
    done = subprocess.run([SIMRUN, "serve", str(SCENE), "--port", "0", "--lockstep", "--foxglove-port", "0", *args],
                          capture_output=True, text=True, timeout=120)  # fmt: skip
    assert done.returncode == 1 and str(clash) in done.stderr, done.stderr
