"""Hostile ``.simlog`` files and full disks given to ``simrun resim`` and ``simrun replay --mcap/--html/--glb/--usd``:
exit 1 with one ``error:`` line naming the file and what is wrong, never exit 3 or a traceback, no output left
behind (issue 42 item 3); ``resim`` streams the recording and stops at the first frame that differs, naming
its time and what differs.

Recordings are made here by simrun itself from the fixture scenes (version 1.1 by ``simrun play --record``,
version 1.2 by the served world's live recorder) and then edited byte by byte.
"""

from __future__ import annotations

import json
import math
import os
import resource
import shutil
import signal
import struct
import subprocess
import sys
import tracemalloc
import zlib
from collections.abc import Callable
from pathlib import Path

import pytest
from bounded import run_bounded
from click.testing import CliRunner

from simrun.cli.main import main
from simrun.record.simlog import Recorder, Simlog, resimulate
from simrun.run.commands import Command
from simrun.run.session import prepare
from simrun.scene.scene_file import load_scene

SCENES = Path(__file__).resolve().parent.parent / "fixtures" / "scenes"
Records = list[list]  # [kind, body] pairs


def _split(data: bytes) -> tuple[bytes, Records, bool]:
    """(header bytes, records, chunked) of a recording; a chunked one's records are taken out of its chunks."""
    n = struct.unpack("<I", data[12:16])[0]
    head, at, records = data[: 16 + n], 16 + n, []
    chunked = struct.unpack("<H", data[10:12])[0] >= 2
    while at < len(data):
        kind, length = struct.unpack("<BI", data[at : at + 5])
        if not chunked:
            records.append([kind, data[at + 5 : at + 5 + length]])
        elif kind == 4:
            body, k = data[at + 9 : at + 5 + length], 0
            while k < len(body):
                inner, size = struct.unpack("<BI", body[k : k + 5])
                records.append([inner, body[k + 5 : k + 5 + size]])
                k += 5 + size
        at += 5 + length
    return head, records, chunked


def _join(head: bytes, records: Records, chunked: bool) -> bytes:
    payload = b"".join(struct.pack("<BI", kind, len(body)) + body for kind, body in records)
    if not chunked:
        return head + payload
    return head + struct.pack("<BII", 4, len(payload) + 4, zlib.crc32(payload)) + payload + struct.pack("<BI", 6, 0)


def _edit(change: Callable[[Records, int], None]) -> Callable[[bytes], bytes]:
    def edit(data: bytes) -> bytes:
        head, records, chunked = _split(data)
        state_size = json.loads(head[16:])["state_size"]
        change(records, state_size)
        return _join(head, records, chunked)

    return edit


def _frames(records: Records) -> list[int]:
    return [k for k, (kind, _) in enumerate(records) if kind in (1, 2)]


def _set_time(index: int, value: float) -> Callable[[Records, int], None]:
    def change(records: Records, size: int) -> None:
        k = _frames(records)[index]
        records[k][1] = struct.pack("<d", value) + records[k][1][8:]

    return change


def _nan_state(records: Records, size: int) -> None:
    k = _frames(records)[3]
    records[k][1] = records[k][1][:16] + struct.pack("<d", math.nan) + records[k][1][24:]


def _swap(records: Records, size: int) -> None:
    a, b = _frames(records)[3:5]
    records[a], records[b] = records[b], records[a]


def _snapshot_length(records: Records, size: int) -> None:
    body = records[_frames(records)[0]][1]
    records[_frames(records)[0]][1] = body[: 8 + 8 * size] + struct.pack("<I", 0xFFFFFFF0) + body[8 + 8 * size + 4 :]


def _insert(kind: int, body: bytes) -> Callable[[Records, int], None]:
    return lambda records, size: records.insert(_frames(records)[3], [kind, body])


def _header_length(data: bytes) -> bytes:
    return data[:12] + struct.pack("<I", 0xFFFFFFFF) + data[16:]


def _header_not_object(data: bytes) -> bytes:
    raw = b"[1, 2]"
    n = struct.unpack("<I", data[12:16])[0]
    return data[:12] + struct.pack("<I", len(raw)) + raw + data[16 + n :]


#: (name, edit, text the one error line holds), for both versions of the format.
CASES = [
    ("truncated_header", lambda data: data[:20], "runs past the end of the file"),
    ("header_not_an_object", _header_not_object, "the header is not a JSON object"),
    ("huge_header_length", _header_length, "header length 4294967295 runs past the end"),
    ("huge_snapshot_length", _edit(_snapshot_length), "checkpoint snapshot length 4294967280 does not fit"),
    ("nan_frame_time", _edit(_set_time(3, math.nan)), "record time nan is not a finite time"),
    ("nan_in_the_state", _edit(_nan_state), "holds NaN or infinity"),
    ("frames_out_of_order", _edit(_swap), "does not follow"),
    ("unknown_record_kind", _edit(_insert(99, b"x" * 10)), "corrupt record (kind 99"),
    ("sensor_record_not_an_object", _edit(_insert(3, struct.pack("<d", 0.1) + b"[1, 2]")), "is not a JSON object"),
    ("reset_record_too_short", _edit(_insert(8, b"x")), "reset record too short"),
]
COMMANDS = {
    "resim": lambda log, out: ["resim", str(log)],
    "mcap": lambda log, out: ["replay", str(log), "--mcap", str(out / "o.mcap")],
    "html": lambda log, out: ["replay", str(log), "--html", str(out / "o.html")],
    "glb": lambda log, out: ["replay", str(log), "--glb", str(out / "o.glb")],
    "usd": lambda log, out: ["replay", str(log), "--usd", str(out / "o.usda")],
}


def _play(folder: Path, scene: str, seconds: str, *extra: str) -> Path:
    shutil.copy(SCENES / scene, folder / scene)
    log = folder / f"{Path(scene).stem}.simlog"
    done = CliRunner().invoke(main, ["play", str(folder / scene), "--duration", seconds, "--record", str(log), *extra])
    assert done.exit_code == 0, done.output
    return log


@pytest.fixture(scope="module")
def recordings(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A version-1.1 recording (``play --record``) and a version-1.2 one (the live recorder, commands inside)."""
    folder = tmp_path_factory.mktemp("recordings")
    old = _play(folder, "boebot.toml", "2", "--commands", str(SCENES / "square.commands.toml"))
    world = load_scene(folder / "boebot.toml")
    prepare(world)
    world.step(100)
    live = Recorder(world, folder / "live.simlog", folder / "boebot.toml", [], live=True)
    for k in range(8):
        world.step(125)
        command = Command(t=float(world.data.time), service="DriveService", entity="boebot", call="cmd_vel",
                          args=(0.1, 0.1 * k))  # fmt: skip
        command.apply(world)
        live.command(command)
    live.close()
    return {"1.1": old, "1.2": folder / "live.simlog"}


def _one_error(code: int, err: str, path: Path) -> str:
    lines = [line for line in err.splitlines() if line.strip() and not line.startswith("note: ")]
    assert code == 1 and "Traceback" not in err, (code, err)
    assert len(lines) == 1 and lines[0].startswith("error: ") and str(path) in lines[0], err
    return lines[0]


@pytest.mark.parametrize("command", list(COMMANDS))
@pytest.mark.parametrize("version", ["1.1", "1.2"])
@pytest.mark.parametrize(("name", "edit", "needle"), CASES, ids=[c[0] for c in CASES])
def test_a_hostile_recording_is_one_error_line(recordings, tmp_path, command, version, name, edit, needle):  # type: ignore[no-untyped-def]
    path = tmp_path / f"{name}.simlog"
    path.write_bytes(edit(recordings[version].read_bytes()))
    shutil.copy(recordings[version].parent / "boebot.toml", tmp_path / "boebot.toml")
    out = tmp_path / "out"
    out.mkdir()
    done = CliRunner().invoke(main, COMMANDS[command](path, out))
    assert needle in _one_error(done.exit_code, done.stderr, path)
    assert list(out.iterdir()) == []  # nothing written, not even a temporary file


@pytest.mark.parametrize("command", ["mcap", "html", "glb", "usd"])
def test_a_body_flung_beyond_float32_is_refused_by_replay(recordings, tmp_path, command):  # type: ignore[no-untyped-def]
    def far(records: Records, size: int) -> None:  # qpos[0], the Boe-Bot's x, 1e300 m: finite, but not in float32
        k = _frames(records)[3]
        records[k][1] = records[k][1][:16] + struct.pack("<d", 1e300) + records[k][1][24:]

    path = tmp_path / "far.simlog"
    path.write_bytes(_edit(far)(recordings["1.1"].read_bytes()))
    shutil.copy(recordings["1.1"].parent / "boebot.toml", tmp_path / "boebot.toml")
    out = tmp_path / "out"
    out.mkdir()
    done = CliRunner().invoke(main, COMMANDS[command](path, out))
    assert "beyond 1e+30 m; the recorded state is corrupt" in _one_error(done.exit_code, done.stderr, path)
    assert list(out.iterdir()) == []


def test_a_command_recorded_before_the_frame_it_follows_is_refused(recordings, tmp_path):  # type: ignore[no-untyped-def]
    def back(records: Records, size: int) -> None:
        k = next(k for k, (kind, _) in enumerate(records) if kind == 5)  # the first command, at 0.45 s
        entry = json.loads(records[k][1][8:])
        entry[0] = 0.3
        records[k][1] = struct.pack("<d", 0.3) + json.dumps(entry).encode()

    path = tmp_path / "back.simlog"
    path.write_bytes(_edit(back)(recordings["1.2"].read_bytes()))
    shutil.copy(recordings["1.2"].parent / "boebot.toml", tmp_path / "boebot.toml")
    for command in ("resim", "mcap"):
        done = CliRunner().invoke(main, COMMANDS[command](path, tmp_path))
        assert "(the clock runs backwards)" in _one_error(done.exit_code, done.stderr, path)

    def before(records: Records, size: int) -> None:  # the third command earlier than the second
        k = [k for k, (kind, _) in enumerate(records) if kind == 5][2]
        entry = json.loads(records[k][1][8:])
        entry[0] = 0.5
        records[k][1] = struct.pack("<d", 0.5) + json.dumps(entry).encode()

    path.write_bytes(_edit(before)(recordings["1.2"].read_bytes()))
    done = CliRunner().invoke(main, COMMANDS["resim"](path, tmp_path))
    assert "command 2: at t = 0.5 s, before command 1 at" in _one_error(done.exit_code, done.stderr, path)


@pytest.mark.parametrize(
    "reading",
    [5, {}, {"time": "now", "ranges": [1.0]}, {"time": 1e300}, {"time": -5.0}],
    ids=["number", "empty", "text_time", "huge_time", "negative_time"],
)
def test_a_sensor_reading_of_the_wrong_shape_is_one_error_line_in_mcap(tmp_path, reading):  # type: ignore[no-untyped-def]
    log = _play(tmp_path, "pioneer_room.toml", "0.3", "--record-sensors", "laser")
    body = struct.pack("<d", 0.1) + json.dumps({"laser": reading}).encode()
    log.write_bytes(_edit(lambda records, size: records.insert(_frames(records)[3], [3, body]))(log.read_bytes()))
    done = CliRunner().invoke(main, ["replay", str(log), "--mcap", str(tmp_path / "o.mcap")])
    assert "sensor 'laser'" in _one_error(done.exit_code, done.stderr, log)
    assert not (tmp_path / "o.mcap").exists()


@pytest.mark.parametrize("command", ["resim", "mcap"])
@pytest.mark.parametrize("name", ["huge_header_length", "huge_snapshot_length"])
def test_huge_counts_are_refused_quickly_and_small(recordings, tmp_path, command, name):  # type: ignore[no-untyped-def]
    edit = next(case[1] for case in CASES if case[0] == name)
    path = tmp_path / f"{name}.simlog"
    path.write_bytes(edit(recordings["1.2"].read_bytes()))
    shutil.copy(recordings["1.2"].parent / "boebot.toml", tmp_path / "boebot.toml")
    done = run_bounded(["simrun", *COMMANDS[command](path, tmp_path)], seconds=60, memory_mb=1500)
    _one_error(done.code, done.err, path)


def _limited(limit: int) -> Callable[[], None]:
    def apply() -> None:  # pragma: no cover - runs in the child
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, resource.RLIM_INFINITY))

    return apply


def test_replay_mcap_on_a_full_disk_is_one_error_line_and_leaves_nothing(recordings, tmp_path):  # type: ignore[no-untyped-def]
    out = tmp_path / "out"
    out.mkdir()
    code = "import sys; from simrun.cli.main import main; sys.argv[0] = 'simrun'; sys.exit(main())"
    done = subprocess.run(
        [sys.executable, "-c", code, "replay", str(recordings["1.1"]), "--mcap", str(out / "o.mcap")],
        capture_output=True, text=True, timeout=120, preexec_fn=_limited(20_000), check=False,
        env={**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")},
    )  # fmt: skip
    message = _one_error(done.returncode, done.stderr, out / "o.mcap")
    assert "cannot write" in message
    assert list(out.iterdir()) == []


def test_resim_stops_at_the_first_frame_that_differs_and_names_what_differs(recordings, tmp_path):  # type: ignore[no-untyped-def]
    def flip(records: Records, size: int) -> None:
        for index in (50, 75):  # the frames at 1.0 s and 1.5 s: one bit of qpos[1] (the free joint's y)
            k = _frames(records)[index]
            body = bytearray(records[k][1])
            body[8 + 8 * 2] ^= 0x01
            records[k][1] = bytes(body)

    path = tmp_path / "flipped.simlog"
    path.write_bytes(_edit(flip)(recordings["1.1"].read_bytes()))
    shutil.copy(recordings["1.1"].parent / "boebot.toml", tmp_path / "boebot.toml")
    done = CliRunner().invoke(main, ["resim", str(path)])
    message = _one_error(done.exit_code, done.stderr, path)
    assert "differs from the recording at t = 1.000 s (49 frame(s) from t = 0 s were identical)" in message
    assert "qpos[1] (joint 'boebot/" in message and "recorded " in message and "re-simulated " in message


def test_resim_streams_the_recording(tmp_path):  # type: ignore[no-untyped-def]
    peaks = []
    for seconds in ("3", "12"):
        folder = tmp_path / seconds
        folder.mkdir()
        log = Simlog(_play(folder, "boebot.toml", seconds, "--commands", str(SCENES / "square.commands.toml")))
        world = load_scene(log.scene_path())
        prepare(world)
        tracemalloc.start()
        done = resimulate(world, log)
        peaks.append(tracemalloc.get_traced_memory()[1])
        tracemalloc.stop()
        log.close()
        assert done.mismatch is None and done.compared == int(seconds) * 50 - 1
    # 450 more frames of 880 bytes (+ a Record each) held in a list would add over 400 kB
    assert peaks[1] - peaks[0] < 150_000 and peaks[1] < 1_000_000, peaks
