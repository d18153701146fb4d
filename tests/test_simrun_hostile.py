"""Hostile scenes, commands files and recordings (issue 21): each is refused with ONE `error:` line that names
the file (and, for TOML, the line), a documented exit code, no traceback, no hang, and no code run."""

import json
import os
import shutil
import struct
from pathlib import Path

import pytest
from click.testing import CliRunner

from simrun.cli.main import main
from simrun.record.simlog import Simlog

SCENES = Path(__file__).resolve().parent.parent / "fixtures" / "scenes"
BOX = '[[entities]]\ntype = "Box"\nname = "box"\n'
BOEBOT = '[[entities]]\ntype = "BoeBot"\nname = "bot"\n'
DRIVE = '[[services]]\ntype = "DriveService"\nentity = "bot"\n'
FIFO = hasattr(os, "mkfifo")


def run(args: list[str]) -> tuple[int, str, str]:
    result = CliRunner().invoke(main, args)
    return result.exit_code, result.stdout, result.stderr


def assert_one_error(code: int, out: str, err: str, name: str, line: int | None, expected: int = 1) -> str:
    assert "Traceback" not in out + err
    assert code == expected, (code, out, err)
    lines = [x for x in err.splitlines() if x.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    where = f"{name}:{line}:" if line is not None else name
    assert where in lines[0], (where, lines[0])
    return lines[0]


# -- scenes: (name, scene text or bytes, line named in the error, text the error must hold) ----------------------

SCENE_CASES = [
    ("non_utf8", BOX.encode() + b"color = [1, 0, 0, 1] # \xff\xfe\n", 4, "not UTF-8"),
    ("bad_toml", BOX + "mass = = 3\n", 4, "not valid TOML"),
    (
        "huge_scale",
        '[assets]\nhead = "head.mbin"\n[[entities]]\ntype = "MeshEntity"\nname = "m"\nasset = "head"\nscale = 1e200\n',
        7,
        "scale: must be at most",
    ),
    ("nan_mass", BOX + "mass = nan\n", 4, "mass: expected a finite number, got nan"),
    ("inf_position", BOX + "pose = { position = [0.0,\n inf, 0.0] }\n", 5, "pose.position[1]: expected a finite"),
    ("nan_gravity", "[world]\ngravity = [0.0, 0.0, -nan]\n", 2, "world.gravity[2]"),
    ("negative_mass", BOX + "free = true\nmass = -100.0\n", 5, "entities[0] 'box': mass must be a positive number"),
    (
        "camera_eye_is_target",
        '[[entities]]\ntype = "Camera"\nname = "view"\neye = [1.0, 2.0, 3.0]\ntarget = [1.0, 2.0, 3.0]\n',
        5,
        "eye and target are the same point",
    ),
    ("camera_eye_only", '[[entities]]\ntype = "Camera"\nname = "view"\neye = [1.0, 2.0, 3.0]\n', 4, "give both eye"),
    (
        "ragged_heightfield",
        '[[entities]]\ntype = "HeightField"\nname = "terrain"\nheights = [\n  [0.0, 1.0, 0.5],\n  [0.0, 1.0],\n]\n',
        6,
        "row 1 has 2 numbers, row 0 has 3",
    ),
    ("tiny_timestep", "[world]\ntimestep = 1e-12\n", 2, "world.timestep: must be in [1e-05, 0.1] seconds"),
    ("huge_timestep", "[world]\ntimestep = 5.0\n", 2, "world.timestep: must be in"),
    (
        "misspelt_service",
        BOEBOT + '[[services]]\ntype = "DriveServce"\nentity = "bot"\n',
        5,
        "unknown service type 'DriveServce'",
    ),
    (
        "service_on_a_box",
        BOX + '[[services]]\ntype = "DriveService"\nentity = "box"\n',
        4,
        "services[0] 'DriveService': 'box' is a Box, not a differential-drive robot",
    ),
    ("service_extra_key", BOEBOT + DRIVE + "speed = 3\n", 7, "services[0] 'DriveService': speed: unknown key"),
    ("unknown_entity_type", '[[entities]]\ntype = "Boxx"\nname = "b"\n', 2, "unknown entity type 'Boxx'"),
    ("missing_texture", BOX + 'texture = "nowhere.png"\n', 4, "'nowhere.png' cannot be read"),
    ("texture_is_a_folder", BOX + 'texture = "."\n', 4, "is a folder"),
    (
        "urdf_package_not_a_folder",
        '[[entities]]\ntype = "UrdfRobot"\nname = "arm"\n'
        'urdf = "../../fixtures/urdf/tiny_arm_description/urdf/tiny_arm.urdf"\n'
        'package_dirs = { tiny_arm_description = "nowhere" }\n',
        5,
        "'nowhere' is not a folder",
    ),
    (
        "sensor_nan_noise",
        BOEBOT + '[[sensors]]\ntype = "GPS"\nname = "gps"\nentity = "bot"\nnoise = nan\n',
        8,
        "sensors[0] 'gps': noise: expected a finite number",
    ),
    (
        "sensor_absurd_rate",
        BOEBOT + '[[sensors]]\ntype = "IMU"\nname = "imu"\nentity = "bot"\nrate = 1e300\n',
        8,
        "sensors[0] 'imu': rate: must be at most",
    ),
    (
        "sensor_unknown_entity",
        BOEBOT + '[[sensors]]\ntype = "IMU"\nname = "imu"\nentity = "robot"\n',
        7,
        "no entity named 'robot'",
    ),
    (
        "sensor_cannot_read_its_entity",
        BOX + '[[sensors]]\ntype = "Encoders"\nname = "enc"\nentity = "box"\n',
        4,
        "sensors[0] 'enc': cannot read 'box'",
    ),
    ("duplicate_name", BOX + BOX, 4, "already exists"),
    (
        "too_many_entities",
        "".join(f'[[entities]]\ntype = "Sky"\nname = "s{k}"\n' for k in range(10_001)),
        30_001,
        "10001 entities, over the limit of 10000",
    ),
]


@pytest.mark.parametrize(("name", "text", "line", "needle"), SCENE_CASES, ids=[c[0] for c in SCENE_CASES])
def test_hostile_scene_is_one_error_line_with_file_and_line(tmp_path, name, text, line, needle):
    shutil.copy(SCENES / "head.mbin", tmp_path / "head.mbin")
    folder = tmp_path / "a" / "b"
    folder.mkdir(parents=True)
    shutil.copy(SCENES / "head.mbin", folder / "head.mbin")
    path = folder / f"{name}.toml"
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    if name == "urdf_package_not_a_folder":  # the URDF path is relative to the scene's folder
        text = path.read_text().replace("../../fixtures", str(SCENES.parent))
        path.write_text(text)
    message = assert_one_error(*run(["check", str(path)]), str(path), line)
    assert needle in message


@pytest.mark.skipif(not FIFO, reason="no FIFOs here")
@pytest.mark.parametrize("field", ["texture", "image", "asset", "scene"])
def test_fifo_is_never_opened_for_reading(tmp_path, field):
    os.mkfifo(tmp_path / "pipe.png")
    os.mkfifo(tmp_path / "pipe.mbin")
    if field == "scene":
        os.mkfifo(tmp_path / "scene.toml")
        message = assert_one_error(*run(["check", str(tmp_path / "scene.toml")]), str(tmp_path / "scene.toml"), None)
        assert "FIFO" in message
        return
    kind = {"texture": "Box", "image": "HeightField", "asset": "MeshEntity"}[field]
    path = tmp_path / "s.toml"
    suffix = "mbin" if field == "asset" else "png"
    path.write_text(f'[[entities]]\ntype = "{kind}"\nname = "x"\n{field} = "pipe.{suffix}"\n')
    message = assert_one_error(*run(["check", str(path)]), str(path), 4)
    assert "FIFO" in message


# -- commands files ---------------------------------------------------------------------------------------------

COMMAND = '[[commands]]\nt = 0.5\nentity = "bot"\n'
COMMAND_CASES = [
    ("nan_argument", COMMAND + 'call = "drive_distance"\nargs = [nan, 0.5]\n', 5, "argument 1 is not a finite number"),
    ("inf_in_a_list", COMMAND + 'call = "drive_speed"\nargs = [0.1, inf]\n', 5, "argument 2 is not a finite"),
    ("too_many_arguments", COMMAND + 'call = "drive_distance"\nargs = [1.0, 0.5, 7.0]\n', 5, "cannot take 3"),
    ("too_few_arguments", COMMAND + 'call = "drive_speed"\nargs = [1.0]\n', 5, "cannot take 1"),
    ("unknown_call", COMMAND + 'call = "self_destruct"\n', 4, "has no command 'self_destruct'"),
    ("private_call", COMMAND + 'call = "__init__"\n', 4, "has no command '__init__'"),
    ("nan_time", '[[commands]]\nt = nan\nentity = "bot"\ncall = "all_stop"\n', 2, "t: expected a finite number"),
    ("negative_time", '[[commands]]\nt = -1.0\nentity = "bot"\ncall = "all_stop"\n', 2, "t: must be in [0, "),
    ("missing_call", COMMAND, 1, "missing 'call'"),
    ("unknown_service", COMMAND + 'service = "Teleporter"\ncall = "go"\n', 4, "unknown service type 'Teleporter'"),
    # a missing entity is named at its entity = line (issue 26; it said "no DriveService is bound" at line 1)
    ("missing_entity", '[[commands]]\nt = 0.5\nentity = "ghost"\ncall = "all_stop"\n', 3, "no entity 'ghost'"),
    (
        "unbound_entity",
        '[[commands]]\nt = 0.5\nservice = "ArmService"\nentity = "bot"\ncall = "move_to"\nargs = [[0.0], 1.0]\n',
        1,
        "no ArmService is bound",
    ),
    ("not_utf8", b"[[commands]]\nt = 0.5 # \xff\n", 2, "not UTF-8"),
]


@pytest.mark.parametrize(("name", "text", "line", "needle"), COMMAND_CASES, ids=[c[0] for c in COMMAND_CASES])
def test_hostile_commands_are_refused_before_the_run(tmp_path, name, text, line, needle):
    scene = tmp_path / "bot.toml"
    scene.write_text(BOEBOT + DRIVE)
    path = tmp_path / f"{name}.commands.toml"
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    message = assert_one_error(*run(["play", str(scene), "--duration", "1", "--commands", str(path)]), str(path), line)
    assert needle in message


def test_bad_play_options_are_usage_errors(tmp_path):
    for option in (["--duration", "nan"], ["--duration", "-1"], ["--fps", "0"], ["--fps", "inf"]):
        code, _, err = run(["play", str(SCENES / "boebot.toml"), *option])
        assert code == 2 and "Traceback" not in err and "Error: Invalid value" in err, (option, err)


# -- recordings -------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def recording(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("rec")
    shutil.copy(SCENES / "boebot.toml", folder / "boebot.toml")
    (folder / "ctl.py").write_text("def step(world):\n    world.service('DriveService', 'boebot').cmd_vel(0.1, 0.2)\n")
    code, _out, err = run(
        [
            "play",
            str(folder / "boebot.toml"),
            "--duration",
            "2.5",
            "--commands",
            str(folder / "ctl.py"),
            "--record",
            str(folder / "run.simlog"),
        ]
    )
    assert code == 0, err
    return folder / "run.simlog"


def split(data: bytes) -> tuple[dict, bytes]:
    length = struct.unpack("<I", data[12:16])[0]
    return json.loads(data[16 : 16 + length]), data[16 + length :]


def join(data: bytes, header: dict) -> bytes:
    raw = json.dumps(header).encode()
    return data[:12] + struct.pack("<I", len(raw)) + raw + split(data)[1]


def with_header(**changes):
    def edit(data: bytes, folder: Path) -> bytes:
        header = split(data)[0]
        for key, value in changes.items():
            if value is KeyError:
                del header[key]
            else:
                header[key] = value
        return join(data, header)

    return edit


def nan_checkpoint(data: bytes, folder: Path) -> bytes:
    _header, records = split(data)
    start = len(data) - len(records)
    out = bytearray(data)
    out[start + 5 + 8 : start + 5 + 16] = struct.pack("<d", float("nan"))  # the first record is a checkpoint
    return bytes(out)


def far_future_frame(data: bytes, folder: Path) -> bytes:
    header, records = split(data)
    start = len(data) - len(records)
    size = 8 + 8 * header["state_size"]
    _kind, length = struct.unpack("<BI", data[start : start + 5])
    second = start + 5 + length
    out = bytearray(data)
    out[second + 5 : second + 13] = struct.pack("<d", 1e9)  # a frame a billion seconds on: resim would never end
    assert struct.unpack("<B", data[second : second + 1])[0] == 1 and size > 0
    return bytes(out)


def evil_controller(data: bytes, folder: Path) -> bytes:
    (folder / "evil.py").write_text(f"open({str(folder / 'PWNED')!r}, 'w').close()\ndef step(world):\n    pass\n")
    header = split(data)[0]
    header["controller"] = str(folder / "evil.py")
    return join(data, header)


RECORDING_CASES = [
    ("missing_frame_period", with_header(frame_period=KeyError), "header: frame_period: missing"),
    ("negative_frame_period", with_header(frame_period=-1), "header: frame_period: must be in"),
    ("missing_scene", with_header(scene=KeyError), "header: scene: missing"),
    ("state_size_text", with_header(state_size="big"), "header: state_size: expected int"),
    ("tiny_timestep", with_header(timestep=1e-12), "header: timestep: must be in"),
    (
        "nan_command_argument",
        with_header(commands=[[0.5, "DriveService", "boebot", "cmd_vel", [float("nan"), 1]]]),
        "corrupt header (NaN in the data)",
    ),
    (
        "text_command_argument",
        with_header(commands=[[0.5, "DriveService", "boebot", "cmd_vel", ["fast", 1]]]),
        "linear must be a number, got 'fast'",
    ),
    (
        "wrong_command_arity",
        with_header(commands=[[0.5, "DriveService", "boebot", "cmd_vel", [1]]]),
        "header: commands[0].args: cmd_vel",
    ),
    ("scene_elsewhere", with_header(scene="no/such/scene.toml"), "recorded scene"),
    ("nan_checkpoint", nan_checkpoint, "holds NaN or infinity"),
    ("far_future_frame", far_future_frame, "does not follow"),
    ("controller_named_by_the_file", evil_controller, "give that file with --controller"),
    ("truncated", lambda data, folder: data[:-3], "runs past the end of the file"),
    ("bad_magic", lambda data, folder: b"\x89SIMLOX\n" + data[8:], "bad magic"),
]


@pytest.mark.parametrize(("name", "edit", "needle"), RECORDING_CASES, ids=[c[0] for c in RECORDING_CASES])
def test_hostile_recording_is_refused_and_runs_no_code(tmp_path, recording, name, edit, needle):
    folder = recording.parent
    path = folder / f"{name}.simlog"
    path.write_bytes(edit(recording.read_bytes(), folder))
    args = ["resim", str(path)]
    if name not in ("controller_named_by_the_file", "bad_magic", "missing_scene"):
        args += ["--controller", str(folder / "ctl.py")]
    message = assert_one_error(*run(args), str(path), None)
    assert needle in message
    assert not (folder / "PWNED").exists()
    assert "bit-identical" not in message


def test_controller_must_match_the_recorded_sha256(recording, tmp_path):
    other = tmp_path / "ctl.py"
    other.write_text((recording.parent / "ctl.py").read_text().replace("0.2", "0.3"))
    message = assert_one_error(*run(["resim", str(recording), "--controller", str(other)]), str(other), None)
    assert "differs from the recorded" in message
    code, out, err = run(["resim", str(recording), "--controller", str(recording.parent / "ctl.py")])
    assert code == 0 and out.strip().endswith("bit-identical"), err


def test_resim_works_from_any_folder(recording, tmp_path, monkeypatch):
    moved = tmp_path / "moved"
    shutil.copytree(recording.parent, moved)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    log = Simlog(moved / "run.simlog")
    assert log.header["scene"] == "boebot.toml" and log.header["controller"] == "ctl.py"
    log.close()
    code, out, err = run(
        ["resim", os.path.relpath(moved / "run.simlog"), "--from", "1.5", "--controller", str(moved / "ctl.py")]
    )
    assert code == 0 and out.strip().endswith("bit-identical"), err
    code, out, err = run(["resim", str(moved / "run.simlog"), "--controller", str(moved / "ctl.py")])
    assert code == 0 and "bit-identical" in out, err


def test_internal_error_is_one_line_exit_3_and_traceback_only_on_request(monkeypatch, tmp_path):
    import simrun.scene.scene_file

    def broken(path):
        raise RuntimeError("simulated bug")

    monkeypatch.setattr(simrun.scene.scene_file, "load_scene", broken)  # simrun check imports it when it runs
    monkeypatch.delenv("SIMRUN_DEBUG", raising=False)
    result = CliRunner().invoke(main, ["check", str(SCENES / "basic.toml")])
    assert result.exit_code == 3 and "Traceback" not in result.output
    assert result.stderr.strip().splitlines() == [
        "internal error: RuntimeError: simulated bug (please report; SIMRUN_DEBUG=1 shows more)"
    ]
    monkeypatch.setenv("SIMRUN_DEBUG", "1")
    result = CliRunner().invoke(main, ["check", str(SCENES / "basic.toml")])
    assert isinstance(result.exception, RuntimeError)


def test_urdf_robot_with_package_dirs_loads(tmp_path):
    """The attack campaign's `UrdfRobot` with `package_dirs` crashed the scene reader (a parameterised generic)."""
    urdf = SCENES.parent / "urdf" / "tiny_arm_description"
    path = tmp_path / "arm.toml"
    path.write_text(
        '[[entities]]\ntype = "UrdfRobot"\nname = "arm"\n'
        f'urdf = "{(urdf / "urdf" / "tiny_arm.urdf").as_posix()}"\n'
        f'package_dirs = {{ tiny_arm_description = "{urdf.as_posix()}" }}\n'
    )
    code, out, err = run(["check", str(path), "--seconds", "0.1"])
    assert code == 0 and "Traceback" not in out + err, err
    path.write_text(path.read_text().replace("package_dirs = {", "package_dirs = { other = 3, "))
    message = assert_one_error(*run(["check", str(path)]), str(path), 5)
    assert "package_dirs.other: expected str, got int 3" in message


def test_unknown_camera_is_one_error_line(tmp_path):
    code, out, err = run(["snapshot", str(SCENES / "basic.toml"), "-o", str(tmp_path / "x.png"), "--camera", "nosuch"])
    assert code == 1 and "Traceback" not in out + err
    assert err.strip() == "error: no camera named 'nosuch' (cameras: view; follow:ENTITY follows an entity)"


@pytest.mark.parametrize("call", ["tick", "reset", "snapshot", "restore"])
def test_a_controllers_lifecycle_method_is_not_a_command(tmp_path, call):
    """``call = "tick"`` with two numbers reached MuJoCo with a float as the model (AttributeError, exit 3)."""
    scene = tmp_path / "bot.toml"
    scene.write_text(BOEBOT + DRIVE)
    path = tmp_path / "c.commands.toml"
    path.write_text(f'[[commands]]\nt = 0.5\nentity = "bot"\ncall = "{call}"\nargs = [1.0, 2.0]\n')
    message = assert_one_error(*run(["play", str(scene), "--duration", "1", "--commands", str(path)]), str(path), 4)
    assert f"DriveService has no command {call!r}" in message
