"""The ``NAME/odom`` frame of an MCAP recorded from the middle of a served session (issue 39).

A drive's odometry (``/NAME/odometry``, ``foxglove.PoseInFrame`` in ``NAME/odom``) is its estimate since its
odometry was last zeroed, which in a served world is when the session started (or the world was reset),
not when the recording started; ``/tf_static`` places ``NAME/odom`` in ``world``. Whatever the origin is,
the two must agree in the same file: ``/tf_static`` applied to each odometry message lands on the robot's
ground truth (``/NAME/pose``) at the same time, up to the estimate's drift. Checked with the ``mcap`` reader
and its protobuf decoder on the MCAP written as the second recording ran, and on the export of its
``.simlog`` (the other path), after the robot drove and turned for 2 s before that recording started.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from serve_helpers import serve
from test_serve_recording import SENSOR_SCENE

from simrun.record.mcap_export import export_mcap

pytest.importorskip("mcap")
pytest.importorskip("mcap_protobuf")


def _read(path: Path) -> dict[str, list[tuple[int, object]]]:
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    out: dict[str, list[tuple[int, object]]] = {}
    with path.open("rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        topics = ["/tf_static", "/boebot/odometry", "/boebot/pose"]
        for _, channel, message, decoded in reader.iter_decoded_messages(topics=topics, log_time_order=True):
            out.setdefault(channel.topic, []).append((message.log_time, decoded))
    return out


def _yaw(q: object) -> float:
    x, y, z, w = q.x, q.y, q.z, q.w  # type: ignore[attr-defined]
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def _check(path: Path) -> None:
    messages = _read(path)
    statics = messages["/tf_static"]
    frames = {(t.child_frame_id, t.translation.x, t.translation.y, t.rotation.z, t.rotation.w)
              for _, m in statics for t in m.transforms}  # type: ignore[attr-defined]  # fmt: skip
    assert len(frames) == 1, frames  # one origin, the same in every /tf_static of the file
    child, ox, oy, qz, qw = frames.pop()
    assert child == "boebot/odom"
    oyaw = 2 * math.atan2(qz, qw)
    truth = dict(messages["/boebot/pose"])
    odometry = messages["/boebot/odometry"]
    assert len(odometry) >= 2
    first = messages["/boebot/pose"][0][1].pose.position  # type: ignore[attr-defined]
    assert math.hypot(first.x - ox, first.y - oy) > 0.15  # the recording starts away from the odometry's origin
    for t, message in odometry:
        pose = message.pose  # type: ignore[attr-defined]
        x, y, theta = pose.position.x, pose.position.y, _yaw(pose.orientation)
        wx = ox + math.cos(oyaw) * x - math.sin(oyaw) * y
        wy = oy + math.sin(oyaw) * x + math.cos(oyaw) * y
        real = truth[t].pose  # type: ignore[attr-defined]
        assert math.hypot(wx - real.position.x, wy - real.position.y) < 0.02, (t, wx, wy, real.position)
        turn = (oyaw + theta - _yaw(real.orientation) + math.pi) % (2 * math.pi) - math.pi
        assert abs(turn) < math.radians(3), (t, turn)


def test_the_odom_frame_of_a_recording_started_mid_session_agrees_with_its_odometry(tmp_path):
    scene = tmp_path / "robot.toml"
    scene.write_text(SENSOR_SCENE)
    record = tmp_path / "run.simlog"
    with serve(scene, "--lockstep", "--record", str(record), "--record-as", "mcap") as server:
        server.post("/api/recording/stop")
        for _ in range(8):  # 2 s simulated, forward and turning (a command expires: again every 0.25 s)
            server.post("/api/services/DriveService/boebot/cmd_vel", {"args": [0.15, 0.6]})
            server.post("/api/step", {"steps": 125})
        assert server.post("/api/recording/start")["path"] == str(tmp_path / "run-2.simlog")
        server.post("/api/step", {"steps": 1000})
    live = tmp_path / "run-2.mcap"
    exported = tmp_path / "exported.mcap"
    export_mcap(tmp_path / "run-2.simlog", exported)
    _check(live)
    _check(exported)
