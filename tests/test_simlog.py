"""Recording, kinematic replay and bit-exact re-simulation from checkpoints."""

import struct
from pathlib import Path

import pytest
from click.testing import CliRunner

from simrun.cli.main import main
from simrun.record.simlog import Simlog, SimlogError

SCENES = Path(__file__).resolve().parent.parent / "fixtures" / "scenes"
SCENE = str(SCENES / "boebot.toml")
COMMANDS = str(SCENES / "square.commands.toml")


def record(path: Path, duration: str = "8") -> None:
    result = CliRunner().invoke(
        main, ["play", SCENE, "--duration", duration, "--commands", COMMANDS, "--record", str(path)]
    )
    assert result.exit_code == 0, result.output


def test_two_runs_give_identical_logs(tmp_path):
    record(tmp_path / "a.simlog")
    record(tmp_path / "b.simlog")
    assert (tmp_path / "a.simlog").read_bytes() == (tmp_path / "b.simlog").read_bytes()
    log = Simlog(tmp_path / "a.simlog")
    records = list(log.records())
    assert len(records) == 400 and [r.kind for r in records].count(2) == 8  # 50 Hz frames, 1 Hz checkpoints
    assert log.header["mujoco"] and log.header["state_size"] == records[0].state.size
    assert [c.call for c in log.commands()][:2] == ["rotate_degrees", "drive_distance"]
    log.close()


@pytest.mark.parametrize("start", ["0", "3.5", "6"])
def test_resim_from_a_checkpoint_is_bit_identical(tmp_path, start):
    path = tmp_path / "run.simlog"
    record(path)
    result = CliRunner().invoke(main, ["resim", str(path), "--from", start])
    assert result.exit_code == 0, result.output
    assert result.stdout.strip().endswith("bit-identical")


def test_resim_detects_a_changed_recording(tmp_path):
    path = tmp_path / "run.simlog"
    record(path)
    log = Simlog(path)
    offset = log._start
    data = bytearray(path.read_bytes())
    for record_ in log.records():
        _, length = struct.unpack("<BI", data[offset : offset + 5])
        if record_.time > 5.0:
            data[offset + 5 + 8 + 8] ^= 0x01  # one bit of qpos
            break
        offset += 5 + length
    log.close()
    path.write_bytes(bytes(data))
    result = CliRunner().invoke(main, ["resim", str(path), "--from", "3"])
    assert result.exit_code == 1
    assert "differs from the recording at t = 5.0" in result.stderr


def test_reader_rejects_corrupt_and_newer_files(tmp_path):
    path = tmp_path / "run.simlog"
    record(path, "2")
    data = path.read_bytes()
    (tmp_path / "magic.simlog").write_bytes(b"NOTALOG!" + data[8:])
    with pytest.raises(SimlogError, match="bad magic"):
        Simlog(tmp_path / "magic.simlog")
    (tmp_path / "newer.simlog").write_bytes(data[:8] + struct.pack("<H", 2) + data[10:])
    with pytest.raises(SimlogError, match=r"version 2\.1 is newer than this reader"):
        Simlog(tmp_path / "newer.simlog")
    (tmp_path / "cut.simlog").write_bytes(data[:-7])
    log = Simlog(tmp_path / "cut.simlog")
    size = 8 + 8 * log.header["state_size"]  # a frame: time and the state, float64
    with pytest.raises(SimlogError, match=rf"byte \d+: record of {size} bytes runs past the end of the file"):
        list(log.records())
    result = CliRunner().invoke(main, ["resim", str(tmp_path / "newer.simlog")])
    assert result.exit_code == 1 and result.stderr.startswith("error: ")


def test_replay_refuses_a_changed_scene(tmp_path):
    scene = tmp_path / "boebot.toml"
    scene.write_text(Path(SCENE).read_text())
    result = CliRunner().invoke(main, ["play", str(scene), "--duration", "1", "--record", str(tmp_path / "r.simlog")])
    assert result.exit_code == 0
    scene.write_text(scene.read_text().replace("mass = 5.0", "mass = 6.0"))
    result = CliRunner().invoke(main, ["resim", str(tmp_path / "r.simlog")])
    assert result.exit_code == 1 and "changed since" in result.stderr


def test_sensor_readings_are_recorded(tmp_path):
    path = tmp_path / "room.simlog"
    result = CliRunner().invoke(
        main,
        [
            "play",
            str(SCENES / "pioneer_room.toml"),
            "--duration",
            "1",
            "--record",
            str(path),
            "--record-sensors",
            "laser",
        ],
    )
    assert result.exit_code == 0, result.output
    log = Simlog(path)
    readings = list(log.sensor_readings())
    assert len(readings) == 50 and len(list(log.records())) == 50
    time, values = readings[10]
    assert time == pytest.approx(0.2) and len(values["laser"]["ranges"]) == 360
    assert min(values["laser"]["ranges"]) == pytest.approx(1.45, abs=0.01)
    bad = CliRunner().invoke(
        main,
        [
            "play",
            str(SCENES / "pioneer_room.toml"),
            "--record",
            str(tmp_path / "x.simlog"),
            "--record-sensors",
            "radar",
        ],
    )
    assert bad.exit_code == 1 and "no sensor named radar" in bad.stderr


def test_python_controller_module_drives_and_resimulates(tmp_path):
    module = tmp_path / "circle.py"
    module.write_text(
        "def step(world):\n"
        "    world.service('DriveService', 'boebot').cmd_vel(0.1, 0.5 if world.data.time < 3 else -0.5)\n"
    )
    path = tmp_path / "ctrl.simlog"
    result = CliRunner().invoke(
        main, ["play", SCENE, "--duration", "5", "--commands", str(module), "--record", str(path), "--json"]
    )
    assert result.exit_code == 0, result.output
    import json

    assert json.loads(result.stdout)["distances_m"]["boebot"] > 0.3
    result = CliRunner().invoke(main, ["resim", str(path), "--from", "2.5", "--controller", str(module)])
    assert result.exit_code == 0 and "bit-identical" in result.stdout
    broken = tmp_path / "broken.py"
    broken.write_text("x = 1/0\n")
    result = CliRunner().invoke(main, ["play", SCENE, "--commands", str(broken)])
    assert result.exit_code == 1 and "ZeroDivisionError" in result.stderr
