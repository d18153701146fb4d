"""simrun replay --mcap: MCAP with Foxglove's schemas, read back by the mcap reader and its protobuf decoder.

Ground truth: the recording itself, replayed here (body poses per frame, checkpoint odometry, sensor records).
"""

from __future__ import annotations

import math
import subprocess
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory

from simrun.record.simlog import CHECKPOINT, Simlog, replay_states
from simrun.scene.scene_file import load_scene

CHECKOUT = Path(__file__).resolve().parent.parent
SCENES = CHECKOUT / "fixtures" / "scenes"
SIMRUN = str(Path(__import__("sys").executable).parent / "simrun")


def _run(*args: str) -> str:
    done = subprocess.run([SIMRUN, *args], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    return done.stdout


def _read(path: Path) -> tuple[dict[str, tuple[str, str, int]], list[tuple[str, int, object]]]:
    """({topic: (schema name, message encoding, count)}, [(topic, log time ns, decoded message)])."""
    with path.open("rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        channels = {
            c.topic: (
                summary.schemas[c.schema_id].name,
                c.message_encoding,
                summary.statistics.channel_message_counts[c.id],
            )
            for c in summary.channels.values()
        }
        messages = [
            (channel.topic, message.log_time, decoded)
            for _, channel, message, decoded in reader.iter_decoded_messages(
                topics=[t for t in channels if channels[t][1] != "json"]
            )
        ]
    return channels, messages


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    """The demo run (make demo): the Boe-Bot around the box for 40 s, recorded, and its MCAP."""
    folder = tmp_path_factory.mktemp("demo")
    log = folder / "demo.simlog"
    _run("play", str(SCENES / "boebot.toml"), "--duration", "40", "--commands", str(SCENES / "square.commands.toml"),
         "--record", str(log))  # fmt: skip
    out = folder / "demo.mcap"
    printed = _run("replay", str(log), "--mcap", str(out))
    assert f"wrote {out}" in printed
    return log, out


def test_demo_mcap_has_every_channel_schema_and_count(demo):
    log, out = demo
    channels, _ = _read(out)
    recording = Simlog(log)
    try:
        frames = sum(1 for _ in recording.records())
        checkpoints = sum(1 for r in recording.records() if r.kind == CHECKPOINT)
    finally:
        recording.close()
    assert channels == {
        "/tf": ("foxglove.FrameTransforms", "protobuf", frames),
        "/boebot/pose": ("foxglove.PoseInFrame", "protobuf", frames),
        "/boebot/odometry": ("foxglove.PoseInFrame", "protobuf", checkpoints),
        # the live Foxglove stream's channels too (simrun.record.foxglove_channels): clock, wheel joints, scene
        "/clock": ("simrun.Clock", "json", frames),
        "/boebot/joint_states": ("foxglove.JointStates", "protobuf", frames),
        "/scene": ("foxglove.SceneUpdate", "protobuf", 40),  # the first frame and every simulated second after
        "/tf_static": ("foxglove.FrameTransforms", "protobuf", 40),  # boebot/odom, with the scene
    }
    assert frames == 2000 and checkpoints == 40  # 40 s: a frame every 0.02 s and a checkpoint every 1 s from t = 0


def test_demo_mcap_poses_equal_the_recording(demo):
    log, out = demo
    _, messages = _read(out)
    recording = Simlog(log)
    world = load_scene(recording.scene_path())
    model, data = world.model, world.data
    names = [model.body(b).name for b in range(1, model.nbody)]
    expected = []
    try:
        for t in replay_states(world, recording):
            expected.append((t, np.array(data.xpos[1:]), np.array(data.xquat[1:])))
        odometry = [(r.time, r.controllers[0]["odom"]) for r in recording.records() if r.kind == CHECKPOINT]
    finally:
        recording.close()
    transforms = [(t, m) for topic, t, m in messages if topic == "/tf"]
    assert len(transforms) == len(expected)
    for (log_time, message), (t, xpos, xquat) in zip(transforms, expected, strict=True):
        assert log_time == round(t * 1e9)
        by_name = {tr.child_frame_id: tr for tr in message.transforms}
        for k, name in enumerate(names):
            tr = by_name[name]
            assert tr.parent_frame_id == "world"
            assert [tr.translation.x, tr.translation.y, tr.translation.z] == list(xpos[k])
            assert [tr.rotation.w, tr.rotation.x, tr.rotation.y, tr.rotation.z] == list(xquat[k])
    robot = names.index("boebot")
    poses = [m for topic, _, m in messages if topic == "/boebot/pose"]
    assert [p.pose.position.x for p in poses] == [float(x[robot][0]) for _, x, _ in expected]
    odom = [m for topic, _, m in messages if topic == "/boebot/odometry"]
    assert [(o.pose.position.x, o.pose.position.y) for o in odom] == [(v[1], v[2]) for _, v in odometry]
    heading = [2 * math.atan2(o.pose.orientation.z, o.pose.orientation.w) for o in odom]
    assert heading == pytest.approx([v[3] for _, v in odometry], abs=1e-12)


def test_sensor_readings_become_laser_scans_images_and_json(tmp_path):
    scene = tmp_path / "sensors.toml"
    text = (SCENES / "boebot_sensors.toml").read_text()
    scene.write_text(text + '\n[[sensors]]\ntype = "GPS"\nname = "gps"\nentity = "boebot"\nrate = 5.0\n')
    log = tmp_path / "s.simlog"
    _run("play", str(scene), "--duration", "1.5", "--record", str(log), "--record-sensors", "laser,view_cam,gps")
    out = tmp_path / "s.mcap"
    _run("replay", str(log), "--mcap", str(out))
    channels, messages = _read(out)
    recording = Simlog(log)
    try:
        readings = list(recording.sensor_readings())
    finally:
        recording.close()

    def samples(name: str) -> list[dict]:
        seen: dict[float, dict] = {}
        for _, values in readings:
            seen.setdefault(values[name]["time"], values[name])
        return list(seen.values())

    assert channels["/sensors/laser"] == ("foxglove.LaserScan", "protobuf", len(samples("laser")))
    assert channels["/sensors/view_cam"] == ("foxglove.RawImage", "protobuf", len(samples("view_cam")))
    assert channels["/sensors/gps"][1:] == ("json", len(samples("gps")))
    assert len(samples("laser")) == 15 and len(samples("view_cam")) == 3  # 10 Hz and 2 Hz in [0, 1.5) s
    scans = [m for topic, _, m in messages if topic == "/sensors/laser"]
    assert [list(s.ranges) for s in scans] == [r["ranges"] for r in samples("laser")]
    assert scans[0].frame_id == "boebot" and scans[0].pose.position.z == 0.06
    assert scans[0].start_angle == pytest.approx(-math.pi / 2) and scans[0].end_angle == pytest.approx(math.pi / 2)
    images = [m for topic, _, m in messages if topic == "/sensors/view_cam"]
    assert (images[-1].width, images[-1].height, images[-1].encoding, images[-1].step) == (160, 120, "rgb8", 480)
    assert images[-1].data == np.asarray(samples("view_cam")[-1]["rgb"], dtype=np.uint8).tobytes()


def test_mcap_is_byte_identical_from_run_to_run_and_refuses_bad_names(demo, tmp_path):
    log, out = demo
    again = tmp_path / "again.mcap"
    _run("replay", str(log), "--mcap", str(again))
    assert again.read_bytes() == out.read_bytes()
    done = subprocess.run(
        [SIMRUN, "replay", str(log), "--mcap", str(tmp_path / "x.bag")], capture_output=True, text=True
    )
    assert done.returncode == 1 and "must end in .mcap" in done.stderr and not (tmp_path / "x.bag").exists()
