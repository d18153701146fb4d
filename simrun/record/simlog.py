r"""``.simlog`` recordings: versioned, streamed to disk in records, replayable and re-simulatable bit-exactly.

Layout (little-endian): 8-byte magic ``\x89SIMLOG\n``, u16 major, u16 minor, u32 header length, the header
as UTF-8 JSON (MuJoCo version, platform, scene path and SHA-256, seed, timestep, state size, frame period,
the timed commands, the controller module's name and SHA-256), then records: u8 kind, u32 length, payload.
Kind 1, a frame: f64 time and the full integration state (``mj_getState(mjSTATE_INTEGRATION)``, f64
array). Kind 2, a checkpoint: a frame followed by the JSON snapshots of every world controller (drive and
arm services, sensors). Kind 3: f64 time and the recorded sensor readings as JSON. Records are written as
the run goes, so memory stays bounded; the reader streams them back. They go to a temporary file beside
the target, renamed over it when the run ends (also when it ends with an error: the records up to then);
a recording that cannot be written whole (a full disk) leaves no ``.simlog`` and no temporary file.

Version 1.2 (``Recorder(live=True)``, the recordings of ``simrun serve``) is written so that it cannot be
lost: the file is made under a unique temporary name (``O_EXCL``) with its header, renamed over the target
at once, and then grows in chunks: kind 4, u32 length, u32 CRC-32 of the records that follow, the records
(kinds 1-3, and kind 5: a command applied, f64 time and the JSON ``[t, service, entity, call, args]``, so
the header never grows with the commands). In 1.2 a sensor record holds one new sample of one sensor
(``{name: reading}``), written when the sensor samples (the recorder ticks at the fastest recorded sensor's
rate, so a 100 Hz IMU keeps all its samples); a camera's image is stored once per rendered frame as kind 7:
f64 time, u32 JSON length, JSON ``{"name", "format": "png", "width", "height"}``, the PNG bytes. A chunk
goes to the operating system at every checkpoint, every
:data:`CHUNK_BYTES` and every :data:`CHUNK_WALL` wall seconds; finishing writes the last chunk and an end
record (kind 6, length 0), with no second copy of the file. A recording cut short (SIGKILL, a full disk, a
power cut) reads up to its last whole chunk; :attr:`Simlog.truncated` says what was cut.

A recording is data: the reader checks every header key's presence, type and range, every record's
length, time and finiteness, and never runs code it names. Paths in the header (scene, controller) are
relative to the recording's folder, so a recording moves with its scene.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import platform
import struct
import tempfile
import time as wallclock
import zlib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO

import mujoco
import numpy as np
import numpy.typing as npt

from meshtool.errors import OutputError
from meshtool.files.nesting import DocumentLimitError, bounded
from meshtool.files.outdir import AtomicFile
from meshtool.formats import output_named
from simrun.errors import SimrunError
from simrun.run.commands import Command, parse_command
from simrun.safeio import FileReadError, open_regular, read_regular
from simrun.world.world import MAX_TIMESTEP, MIN_TIMESTEP, World

MAGIC = output_named("simlog").magic[0]  # the formats registry's row
MAJOR, MINOR = 1, 1
#: The minor version of chunked recordings (``Recorder(live=True)``).
CHUNKED_MINOR = 2
FRAME, CHECKPOINT, SENSORS, CHUNK, COMMAND, END, IMAGE = 1, 2, 3, 4, 5, 6, 7
#: Bytes of records gathered before a chunk is written (live recordings).
CHUNK_BYTES = 1 << 20
#: Longest wall time records wait before their chunk is written, seconds (live recordings).
CHUNK_WALL = 0.5
STATE = mujoco.mjtState.mjSTATE_INTEGRATION
#: Largest header accepted, bytes.
MAX_HEADER_BYTES = 16 * 1024 * 1024
#: Frame periods accepted, seconds.
MIN_FRAME_PERIOD, MAX_FRAME_PERIOD = 1e-5, 60.0
#: Largest state size accepted (numbers per frame).
MAX_STATE_SIZE = 10_000_000
_HEADER: dict[str, tuple[type, ...]] = {
    "mujoco": (str,),
    "platform": (str,),
    "scene": (str,),
    "scene_sha256": (str,),
    "seed": (int,),
    "timestep": (int, float),
    "state_size": (int,),
    "frame_period": (int, float),
    "commands": (list,),
    "sensors": (list,),
    "controller": (str, type(None)),
}


class SimlogError(SimrunError, ValueError):
    """A ``.simlog`` is truncated, corrupt, or of an unknown major version."""


def state_of(model: mujoco.MjModel, data: mujoco.MjData) -> npt.NDArray[np.float64]:
    """The full integration state of ``data``."""
    state = np.empty(mujoco.mj_stateSize(model, STATE))
    mujoco.mj_getState(model, data, state, STATE)
    return state


@dataclass(frozen=True, slots=True)
class Record:
    """One frame (and, for checkpoints, the controllers' snapshots)."""

    kind: int
    time: float
    state: npt.NDArray[np.float64]
    controllers: list[dict[str, Any]] | None


class Recorder:
    """A world controller that streams frames (every ``period`` s) and checkpoints (every ``checkpoint`` s).

    Args:
        world: The world being recorded (its controllers must be added before the recorder).
        path: Output file.
        scene: The scene file the world came from (recorded with its SHA-256).
        commands: The timed commands of the run.
        period: Seconds between frames.
        checkpoint: Seconds between checkpoints.
        seed: The run's seed, recorded.
        sensors: Names of ``world.sensors`` whose latest readings are recorded with every frame.
        controller: The Python controller module the run used: its path (relative to the recording) and
            SHA-256 are recorded; ``resim`` runs it only when given on the command line with that SHA-256.
        live: Write a chunked version-1.2 recording in place (see the module): it exists from the start,
            survives a kill up to its last chunk, takes commands as they happen (:meth:`command`), and a
            failed write (a full disk) ends it, keeping what was written (:attr:`failed`), without stopping
            the simulation. ``False``: version 1.1 through a temporary file renamed at :meth:`close`.
    """

    def __init__(
        self,
        world: World,
        path: Path,
        scene: Path,
        commands: list[Command],
        period: float = 0.02,
        checkpoint: float = 1.0,
        seed: int = 0,
        sensors: tuple[str, ...] = (),
        controller: Path | None = None,
        live: bool = False,
    ) -> None:
        model = world.model
        self.world, self.period, self.checkpoint_every = world, period, checkpoint
        unknown = [n for n in sensors if n not in world.sensors]
        if unknown:
            known = ", ".join(world.sensors) or "none"
            raise SimrunError(f"no sensor named {', '.join(unknown)} (known: {known})")
        self.sensors = sensors
        self.next_time = world.time
        self.frame_period = period
        self._next_frame = world.time
        self._samples = {n: int(world.sensors[n].samples) for n in sensors}
        if live and sensors:  # tick as often as the fastest recorded sensor samples (every step for rate 0)
            rates = [float(world.sensors[n].period) for n in sensors]
            self.period = min([period, *(r if r > 0 else model.opt.timestep for r in rates)])
        #: Records written by kind (live recordings: sensor samples and images counted apiece).
        self.counts: dict[str, int] = {"frames": 0, "sensor_samples": 0, "images": 0}
        self._next_checkpoint = world.time
        if not (math.isfinite(period) and MIN_FRAME_PERIOD <= period <= MAX_FRAME_PERIOD):
            raise SimrunError(f"frame period must be in [{MIN_FRAME_PERIOD:g}, {MAX_FRAME_PERIOD:g}] s, got {period}")
        if not (math.isfinite(checkpoint) and checkpoint >= period):
            raise SimrunError(f"checkpoint interval must be at least the frame period, got {checkpoint}")
        try:
            scene_sha = hashlib.sha256(read_regular(scene, "scene")).hexdigest()
            controller_sha = hashlib.sha256(read_regular(controller, "controller")).hexdigest() if controller else None
        except FileReadError as exc:
            raise SimrunError(str(exc)) from None
        header = {
            "mujoco": mujoco.__version__,
            "platform": f"{platform.system()} {platform.machine()} Python {platform.python_version()}",
            "scene": _relative(scene, path),
            "scene_sha256": scene_sha,
            "seed": seed,
            "timestep": model.opt.timestep,
            "state_size": int(mujoco.mj_stateSize(model, STATE)),
            "frame_period": period,
            "commands": [[c.t, c.service, c.entity, c.call, list(c.args)] for c in commands],
            "sensors": list(sensors),
            "controller": _relative(controller, path) if controller else None,
            "controller_sha256": controller_sha,
        }
        raw = json.dumps(header, sort_keys=True).encode("utf-8")
        self.path = path
        self.frames = 0
        self.live = live
        #: Why a live recording ended early (a full disk), or ``None``.
        self.failed: str | None = None
        self._buffer = bytearray()
        self._last_flush = wallclock.monotonic()
        self._last_time = float(world.time)
        self._fd: int | None = None
        head = MAGIC + struct.pack("<HHI", MAJOR, CHUNKED_MINOR if live else MINOR, len(raw)) + raw
        if live:
            self._fd = _create_in_place(path, head)
            self._good = len(head)  # bytes on disk that end with a whole chunk
        else:
            try:  # streamed to a temporary file beside the target, renamed over it by close(): never a torn .simlog
                self._file = AtomicFile(path)
            except OutputError as exc:
                raise SimrunError(f"{path}: {exc.message}") from None
            self._write(head)
        world.controllers.append(self)

    def _write(self, data: bytes) -> None:
        """Append a record (live: to the chunk being gathered).

        A failed write (a full disk) drops a version-1.1 recording and says so.
        """
        if self.live:
            if self._fd is not None:
                self._buffer += data
            return
        try:
            self._file.write(data)
        except OutputError as exc:
            self.abort()
            raise SimrunError(f"{self.path}: {exc.message}; nothing recorded") from None

    def flush(self) -> None:
        """Write the records gathered so far as one chunk (live recordings; a failed write ends the recording)."""
        self._last_flush = wallclock.monotonic()
        if self._fd is None or not self._buffer:
            return
        payload = bytes(self._buffer)
        self._buffer.clear()
        chunk = struct.pack("<BII", CHUNK, len(payload) + 4, zlib.crc32(payload)) + payload
        try:
            view = memoryview(chunk)
            while view:
                view = view[os.write(self._fd, view) :]
        except OSError as exc:
            self._end(f"{self.path}: cannot write: {exc.strerror or exc}; the recording ends at t = "
                      f"{self._last_time:g} s ({self.frames} frames before the failed chunk are kept)")  # fmt: skip
            return
        self._good += len(chunk)

    def _end(self, failure: str) -> None:
        """A live recording's write failed: cut the torn chunk, close the file, remember why."""
        fd, self._fd = self._fd, None
        self.failed = failure
        self._buffer.clear()
        if fd is not None:
            with contextlib.suppress(OSError):
                os.ftruncate(fd, self._good)
            with contextlib.suppress(OSError):
                os.close(fd)

    def command(self, command: Command) -> None:
        """Record a command applied at ``command.t`` (live recordings: it goes into the next chunk)."""
        if not self.live:
            raise SimrunError("commands are recorded as they happen only in live recordings")
        entry = json.dumps([command.t, command.service, command.entity, command.call, list(command.args)])
        body = struct.pack("<d", float(command.t)) + entry.encode("utf-8")
        self._write(struct.pack("<BI", COMMAND, len(body)) + body)

    def tick(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Write a frame, or a checkpoint when one is due (live: and each recorded sensor's new samples)."""
        if self.live:
            self._tick_live(model, data)
            return
        self._frame(model, data)
        if self.sensors:
            readings = {n: _plain(self.world.sensors[n].reading) for n in self.sensors}
            extra = struct.pack("<d", float(data.time)) + json.dumps(readings).encode("utf-8")
            self._write(struct.pack("<BI", SENSORS, len(extra)) + extra)

    def _tick_live(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        kind = FRAME
        if data.time + 0.5 * model.opt.timestep >= self._next_frame:
            kind = self._frame(model, data)
            while self._next_frame <= data.time + 0.5 * model.opt.timestep:
                self._next_frame += self.frame_period
        for name in self.sensors:
            sensor = self.world.sensors[name]
            samples = int(sensor.samples)
            if samples == self._samples[name] or sensor.reading is None:
                continue
            self._samples[name] = samples
            self._sample(name, sensor.reading, float(getattr(sensor.reading, "time", data.time)))
        self._last_time = float(data.time)
        if (
            kind == CHECKPOINT
            or len(self._buffer) >= CHUNK_BYTES
            or wallclock.monotonic() - self._last_flush >= CHUNK_WALL
        ):
            self.flush()

    def _sample(self, name: str, reading: Any, time: float) -> None:
        """One new sample of a sensor: a camera's image as PNG (once per rendered frame), else as JSON."""
        rgb = getattr(reading, "rgb", None)
        if rgb is None and getattr(reading, "left", None) is not None:
            rgb = reading.left.rgb
        if isinstance(rgb, np.ndarray) and rgb.ndim == 3:
            meta = json.dumps({"name": name, "format": "png", "width": int(rgb.shape[1]), "height": int(rgb.shape[0])})
            raw = meta.encode("utf-8")
            body = struct.pack("<dI", time, len(raw)) + raw + _png(rgb)
            self._write(struct.pack("<BI", IMAGE, len(body)) + body)
            self.counts["images"] += 1
            return
        extra = struct.pack("<d", time) + json.dumps({name: _plain(reading)}).encode("utf-8")
        self._write(struct.pack("<BI", SENSORS, len(extra)) + extra)
        self.counts["sensor_samples"] += 1

    def _frame(self, model: mujoco.MjModel, data: mujoco.MjData) -> int:
        """Write a frame, or a checkpoint when one is due; its kind."""
        state = state_of(model, data)
        body = struct.pack("<d", float(data.time)) + state.tobytes()
        kind = FRAME
        if data.time + 0.5 * model.opt.timestep >= self._next_checkpoint:
            snaps = [c.snapshot() for c in self.world.controllers if c is not self]
            extra = json.dumps(snaps).encode("utf-8")
            body += struct.pack("<I", len(extra)) + extra
            kind = CHECKPOINT
            self._next_checkpoint += self.checkpoint_every
        self._write(struct.pack("<BI", kind, len(body)) + body)
        self.frames += 1
        self.counts["frames"] += 1
        return kind

    def reset(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Recording continues across resets."""

    def snapshot(self) -> dict[str, Any]:
        """The recorder holds no simulation state."""
        return {}

    def restore(self, state: dict[str, Any]) -> None:
        """Nothing to restore (see :meth:`snapshot`)."""

    def close(self, keep: bool = True) -> None:
        """Finish the recording: flush it to disk and rename it over the target (or drop it).

        A run that stopped with an error still gets its recording up to that point (every record whole:
        ``simrun test --record-failures`` keeps those); only a recording that could not be written whole
        is dropped.

        Args:
            keep: Rename the recording into place; ``False`` removes it (see :meth:`abort`).

        Raises:
            SimrunError: The recording cannot be finished (a full disk); nothing is left behind.
        """
        if self in self.world.controllers:
            self.world.controllers.remove(self)
        if self.live:
            self._close_live()
            return
        if not keep:
            self.abort()
            return
        try:
            self._file.commit()  # a second close does nothing
        except OutputError as exc:
            raise SimrunError(f"{self.path}: {exc.message}; nothing recorded") from None

    def _close_live(self) -> None:
        """Write the last chunk and the end record, flush to disk; raise the failure that ended it early."""
        self.flush()
        if self._fd is not None:
            fd = self._fd
            try:
                os.write(fd, struct.pack("<BI", END, 0))
                os.fsync(fd)
            except OSError as exc:
                self._end(f"{self.path}: cannot write: {exc.strerror or exc}; the recording ends at t = "
                          f"{self._last_time:g} s, unfinished ({self.frames} frames kept)")  # fmt: skip
            else:
                self._fd = None
                os.close(fd)
        if self.failed is not None:
            raise SimrunError(self.failed)

    def abort(self) -> None:
        """Drop the recording: the temporary file is removed (the target is left as it was).

        A live recording is already in place: it is finished as it is (:meth:`close`), never removed.
        """
        if self.live:
            with contextlib.suppress(SimrunError):
                self._close_live()
            return
        self._file.abort()
        if self in self.world.controllers:
            self.world.controllers.remove(self)


def _create_in_place(path: Path, head: bytes) -> int:
    """A new file holding ``head``, renamed over ``path``; its descriptor, open for appending.

    It is made under a unique temporary name beside ``path`` (``O_EXCL``: never another file's name).

    Raises:
        SimrunError: The folder cannot be written.
    """
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
    except (OSError, ValueError) as exc:
        raise SimrunError(f"{path}: cannot write: {getattr(exc, 'strerror', None) or exc}") from None
    try:
        view = memoryview(head)
        while view:
            view = view[os.write(fd, view) :]
        os.fchmod(fd, 0o644)
        os.replace(tmp, path)
    except OSError as exc:
        os.close(fd)
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise SimrunError(f"{path}: cannot write: {exc.strerror or exc}") from None
    return fd


def _png(rgb: npt.NDArray[Any]) -> bytes:
    """An RGB image (H, W, 3) u8 as PNG bytes (compression level 1: fast, lossless; the same bytes every run)."""
    import io

    from PIL import Image

    buffer = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(rgb)).save(buffer, format="PNG", compress_level=1)
    return buffer.getvalue()


def _relative(target: Path, recording: Path) -> str:
    """``target`` relative to the recording's folder, with ``/`` separators (absolute when on another drive)."""
    try:
        text = os.path.relpath(target.resolve(), recording.resolve().parent)
    except ValueError:  # Windows: another drive
        return target.resolve().as_posix()
    return Path(text).as_posix()


def _plain(value: Any) -> Any:
    """A sensor reading as JSON-ready data (dataclasses to dicts, arrays to lists, NaN to None)."""
    if value is None:
        return None
    if hasattr(value, "__dataclass_fields__"):
        return {k: _plain(getattr(value, k)) for k in value.__dataclass_fields__}
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value


class Simlog:
    """A recording opened for reading (records are streamed, not loaded at once).

    The header is checked when the file is opened (every key present, of its type and in range, the
    commands as strictly as a commands file); records are checked as they are read (length, kind, a
    finite state of the header's size, times that start at or after 0 and advance by at most one frame
    period, snapshots without NaN). Every error names the file and the byte offset or header key.

    Raises:
        SimlogError: Unreadable, not a ``.simlog``, a newer major version, or a bad header.
    """

    def __init__(self, path: Path) -> None:
        self.path = path
        try:
            self._file: BinaryIO = open_regular(path, "recording")
        except FileReadError as exc:
            raise SimlogError(str(exc)) from None
        self._size = os.fstat(self._file.fileno()).st_size
        complete = False
        try:
            self._read_header()
            complete = True
        finally:
            if not complete:  # a refused header: do not leave the file open
                self._file.close()

    def _read_header(self) -> None:
        path = self.path
        head = self._file.read(16)
        if len(head) < 16 or head[:8] != MAGIC:
            raise SimlogError(f"{path}: not a .simlog (bad magic number at byte 0)")
        major, minor, length = struct.unpack("<HHI", head[8:16])
        if major != MAJOR:
            raise SimlogError(f"{path}: .simlog version {major}.{minor} is newer than this reader ({MAJOR}.x)")
        if length > min(MAX_HEADER_BYTES, self._size - 16):
            raise SimlogError(f"{path}: byte 12: header length {length} runs past the end of the file")
        raw = self._file.read(length)
        try:
            header = bounded(lambda: json.loads(raw.decode("utf-8"), parse_constant=_refuse_constant))
        except DocumentLimitError as exc:
            raise SimlogError(f"{path}: byte 16: header {exc}") from None
        except (UnicodeDecodeError, json.JSONDecodeError, ValueError) as exc:
            raise SimlogError(f"{path}: byte 16: corrupt header ({exc})") from None
        if not isinstance(header, dict):
            raise SimlogError(f"{path}: byte 16: the header is not a JSON object")
        self.header: dict[str, Any] = header
        self.minor = minor
        self._start = 16 + length
        #: What was cut from a chunked recording (killed, a full disk), as one line; ``None``: it is whole.
        self.truncated: str | None = None
        self._end = self._size
        self._check_header()
        self.state_size = int(header["state_size"])
        self.timestep = float(header["timestep"])
        self.frame_period = float(header["frame_period"])
        if minor >= CHUNKED_MINOR:
            self._scan()

    def _bad(self, key: str, message: str) -> SimlogError:
        return SimlogError(f"{self.path}: header: {key}: {message}")

    def _check_header(self) -> None:
        header = self.header
        for key, kinds in _HEADER.items():
            if key not in header:
                raise self._bad(key, "missing; the file is not a complete recording")
            value = header[key]
            if isinstance(value, bool) or not isinstance(value, kinds):
                names = " or ".join("null" if k is type(None) else k.__name__ for k in kinds)
                raise self._bad(key, f"expected {names}, got {type(value).__name__}")
        if len(header["scene_sha256"]) != 64 or any(c not in "0123456789abcdef" for c in header["scene_sha256"]):
            raise self._bad("scene_sha256", "expected 64 hex digits")
        if not header["scene"]:
            raise self._bad("scene", "empty path")
        timestep = float(header["timestep"])
        if not MIN_TIMESTEP <= timestep <= MAX_TIMESTEP:
            raise self._bad("timestep", f"must be in [{MIN_TIMESTEP:g}, {MAX_TIMESTEP:g}] s, got {timestep!r}")
        period = float(header["frame_period"])
        if not MIN_FRAME_PERIOD <= period <= MAX_FRAME_PERIOD:
            raise self._bad(
                "frame_period", f"must be in [{MIN_FRAME_PERIOD:g}, {MAX_FRAME_PERIOD:g}] s, got {period!r}"
            )
        if not 1 <= header["state_size"] <= MAX_STATE_SIZE:
            raise self._bad("state_size", f"must be in [1, {MAX_STATE_SIZE}], got {header['state_size']}")
        if not all(isinstance(n, str) for n in header["sensors"]):
            raise self._bad("sensors", "expected an array of sensor names")
        controller = header["controller"]
        digest = header.get("controller_sha256")
        if controller is not None and self.minor >= 1 and not (isinstance(digest, str) and len(digest) == 64):
            raise self._bad("controller_sha256", "missing or not 64 hex digits (a controller is recorded)")
        self._commands = []
        for k, entry in enumerate(header["commands"]):

            def fail(message: str, key: str | None = None, k: int = k) -> SimlogError:
                return self._bad(f"commands[{k}]" + (f".{key}" if key else ""), message)

            if not isinstance(entry, list) or len(entry) != 5:
                raise fail("expected [t, service, entity, call, args]")
            table = dict(zip(("t", "service", "entity", "call", "args"), entry, strict=True))
            self._commands.append(parse_command(table, fail, f"{self.path}: header: commands[{k}]"))
        times = [c.t for c in self._commands]
        if times != sorted(times):
            raise self._bad("commands", "not in time order")

    def _chunks(self) -> Iterator[tuple[int, bytes]]:
        """(file offset, records) of every whole chunk of a chunked recording, in order.

        A chunk cut short, or failing its CRC-32, at the end of the file ends the recording there (noted
        in :attr:`truncated` by :meth:`_scan`); anything else malformed is an error.
        """
        self._file.seek(self._start)
        offset = self._start
        while offset < self._end:
            head = self._file.read(5)
            if len(head) < 5:
                return
            kind, length = struct.unpack("<BI", head)
            if kind == END and length == 0:
                return
            if kind != CHUNK or length < 4:
                raise SimlogError(f"{self.path}: byte {offset}: corrupt chunk (kind {kind}, {length} bytes)")
            if length > self._size - offset - 5:
                return
            body = self._file.read(length)
            if len(body) != length:
                return
            if zlib.crc32(body[4:]) != struct.unpack("<I", body[:4])[0]:
                if offset + 5 + length == self._size:
                    return
                raise SimlogError(f"{self.path}: byte {offset}: chunk fails its CRC-32 check")
            yield offset + 9, body[4:]
            offset += 5 + length

    def _scan(self) -> None:
        """Read a chunked recording's structure: where its whole chunks end, what was cut, its commands."""
        good = self._start
        for offset, body in self._chunks():
            good = offset + len(body)
            at = 0
            while at + 5 <= len(body):
                kind, length = struct.unpack("<BI", body[at : at + 5])
                if kind == COMMAND:
                    self._command(body[at + 5 : at + 5 + length], offset + at)
                at += 5 + length
            if at != len(body):
                raise SimlogError(f"{self.path}: byte {offset + at}: a record runs past the end of its chunk")
        self._file.seek(good)
        tail = self._file.read(5)
        ended = len(tail) == 5 and struct.unpack("<BI", tail) == (END, 0)
        self._end = good
        if not ended:
            kept = good - self._start
            cut = self._size - good
            self.truncated = (
                f"{self.path}: the recording was not finished (killed or out of disk space): read up to its "
                f"last whole chunk (byte {good}, {kept} bytes of records"
                + (f"; {cut} bytes after it are cut off)" if cut else ")")
            )
        times = [c.t for c in self._commands]
        if times != sorted(times):
            raise self._bad("commands", "recorded commands are not in time order")

    def _command(self, body: bytes, offset: int) -> None:
        """Check and keep one command record (a chunked recording's commands, in the order applied)."""
        k = len(self._commands)
        entry = self._json(body[8:], offset, "command record") if len(body) >= 8 else None

        def fail(message: str, key: str | None = None) -> SimlogError:
            return SimlogError(f"{self.path}: byte {offset}: command {k}" + (f".{key}" if key else "") + f": {message}")

        if not isinstance(entry, list) or len(entry) != 5:
            raise fail("expected [t, service, entity, call, args]")
        table = dict(zip(("t", "service", "entity", "call", "args"), entry, strict=True))
        self._commands.append(parse_command(table, fail, f"{self.path}: byte {offset}: command {k}"))

    def _stream(self) -> Iterator[tuple[int, int, bytes]]:
        """(offset, kind, body) of every record in order: top level (1.1), or inside whole chunks (1.2)."""
        if self.minor >= CHUNKED_MINOR:
            for start, body in self._chunks():
                at = 0
                while at + 5 <= len(body):
                    kind, length = struct.unpack("<BI", body[at : at + 5])
                    if at + 5 + length > len(body):
                        raise SimlogError(f"{self.path}: byte {start + at}: a record runs past the end of its chunk")
                    yield start + at, kind, body[at + 5 : at + 5 + length]
                    at += 5 + length
            return
        self._file.seek(self._start)
        offset = self._start
        while True:
            head = self._file.read(5)
            if not head:
                return
            if len(head) < 5:
                raise SimlogError(f"{self.path}: byte {offset}: truncated record")
            kind, length = struct.unpack("<BI", head)
            if length > self._size - offset - 5:
                raise SimlogError(f"{self.path}: byte {offset}: record of {length} bytes runs past the end of the file")
            body = self._file.read(length)
            if len(body) != length:
                raise SimlogError(f"{self.path}: byte {offset}: truncated record")
            yield offset, kind, body
            offset += 5 + length

    def scene_path(self) -> Path:
        """The recorded scene file, resolved against the recording's folder (so it works from anywhere)."""
        return self.path.parent / Path(self.header["scene"])

    def controller_sha256(self) -> str | None:
        """The recorded controller module's SHA-256 (hex), or ``None`` when the run had none."""
        if self.header["controller"] is None:
            return None
        digest = self.header.get("controller_sha256")
        return digest if isinstance(digest, str) else None

    def commands(self) -> list[Command]:
        """The recorded timed commands (checked when the file was opened)."""
        return list(self._commands)

    def sensor_readings(self) -> Iterator[tuple[float, dict[str, Any]]]:
        """The recorded sensor readings: (time, {sensor name: reading as plain data})."""
        for record in self.records(sensors=True):
            yield record.time, (record.controllers or [{}])[0]

    def images(self) -> Iterator[tuple[float, str, str, bytes]]:
        """The recorded camera images (version 1.2): (time, sensor name, format ``"png"``, the encoded bytes).

        Raises:
            SimlogError: A malformed image record (naming the byte offset).
        """
        for offset, kind, body in self._stream():
            if kind != IMAGE:
                continue
            if len(body) < 12:
                raise SimlogError(f"{self.path}: byte {offset}: image record too short")
            time, n = struct.unpack("<dI", body[:12])
            if not math.isfinite(time) or 12 + n > len(body):
                raise SimlogError(f"{self.path}: byte {offset}: corrupt image record")
            meta = self._json(body[12 : 12 + n], offset, "image record")
            if not isinstance(meta, dict) or not isinstance(meta.get("name"), str) or meta.get("format") != "png":
                raise SimlogError(f"{self.path}: byte {offset}: image record without a sensor name and PNG format")
            yield time, meta["name"], "png", body[12 + n :]

    def counts(self) -> dict[str, int]:
        """Records by kind.

        ``frames`` (checkpoints included), ``checkpoints``, ``sensor_samples`` (per sensor in 1.2:
        ``sensor_samples.NAME``), ``images`` (and ``images.NAME``), ``commands``.
        """
        counts = {"frames": 0, "checkpoints": 0, "sensor_samples": 0, "images": 0, "commands": len(self._commands)}
        for offset, kind, body in self._stream():
            if kind in (FRAME, CHECKPOINT):
                counts["frames"] += 1
                counts["checkpoints"] += kind == CHECKPOINT
            elif kind == SENSORS:
                counts["sensor_samples"] += 1
                if self.minor >= CHUNKED_MINOR:
                    for name in self._json(body[8:], offset, "sensor record"):
                        counts[f"sensor_samples.{name}"] = counts.get(f"sensor_samples.{name}", 0) + 1
        for _, name, _, _ in self.images():
            counts["images"] += 1
            counts[f"images.{name}"] = counts.get(f"images.{name}", 0) + 1
        return counts

    def records(self, sensors: bool = False) -> Iterator[Record]:
        """Every frame and checkpoint record in order (or, with ``sensors``, the sensor records).

        Raises:
            SimlogError: A truncated or malformed record, a non-finite state or time, or times that do not
                advance frame by frame (naming the byte offset).
        """
        frame_bytes = 8 + 8 * self.state_size
        previous: float | None = None
        step = self.frame_period + 1.5 * self.timestep + 1e-9
        for offset, kind, body in self._stream():
            length = len(body)
            if kind in (COMMAND, IMAGE) and self.minor >= CHUNKED_MINOR:
                continue  # read by _scan and images()
            if kind == SENSORS:
                if length < 8:
                    raise SimlogError(f"{self.path}: byte {offset}: sensor record too short")
                if sensors:
                    time = struct.unpack("<d", body[:8])[0]
                    if not math.isfinite(time):
                        raise SimlogError(f"{self.path}: byte {offset}: non-finite sensor record time")
                    readings = self._json(body[8:], offset, "sensor record")
                    yield Record(kind, time, np.zeros(0), [readings])
                continue
            if kind not in (FRAME, CHECKPOINT) or length < frame_bytes:
                raise SimlogError(f"{self.path}: byte {offset}: corrupt record (kind {kind}, {length} bytes)")
            if kind == FRAME and length != frame_bytes:
                raise SimlogError(f"{self.path}: byte {offset}: frame of {length} bytes, expected {frame_bytes}")
            time = struct.unpack("<d", body[:8])[0]
            state = np.frombuffer(body[8:frame_bytes], dtype=np.float64)
            if not math.isfinite(time) or time < 0:
                raise SimlogError(f"{self.path}: byte {offset}: record time {time!r} is not a finite time >= 0")
            if previous is not None and not previous < time <= previous + step:
                raise SimlogError(
                    f"{self.path}: byte {offset}: record time {time!r} s does not follow {previous!r} s "
                    f"by at most one frame period ({self.frame_period:g} s)"
                )
            if not np.isfinite(state).all():
                raise SimlogError(f"{self.path}: byte {offset}: the state at t = {time!r} s holds NaN or infinity")
            previous = time
            controllers = None
            if kind == CHECKPOINT:
                if length < frame_bytes + 4:
                    raise SimlogError(f"{self.path}: byte {offset}: checkpoint too short")
                (n,) = struct.unpack("<I", body[frame_bytes : frame_bytes + 4])
                if frame_bytes + 4 + n != length:
                    raise SimlogError(f"{self.path}: byte {offset}: checkpoint snapshot length {n} does not fit")
                controllers = self._json(body[frame_bytes + 4 :], offset, "checkpoint")
                if not isinstance(controllers, list) or not all(isinstance(c, dict) for c in controllers):
                    raise SimlogError(f"{self.path}: byte {offset}: checkpoint snapshots are not a list of objects")
            if not sensors:
                yield Record(kind, time, state, controllers)

    def _json(self, raw: bytes, offset: int, what: str) -> Any:
        try:
            return bounded(lambda: json.loads(raw.decode("utf-8"), parse_constant=_refuse_constant))
        except DocumentLimitError as exc:
            raise SimlogError(f"{self.path}: byte {offset}: {what} {exc}") from None
        except (UnicodeDecodeError, ValueError) as exc:
            raise SimlogError(f"{self.path}: byte {offset}: corrupt {what} ({exc})") from None

    def close(self) -> None:
        """Close the file."""
        self._file.close()


def _refuse_constant(name: str) -> float:
    """JSON's ``NaN`` is refused in recordings; ``Infinity`` is kept (a drive's never-commanded clock is -inf)."""
    if name == "NaN":
        raise ValueError("NaN in the data")
    return float(name.replace("Infinity", "inf"))


def check_scene(log: Simlog, scene: Path) -> None:
    """Refuse to replay against a scene file that changed since the recording."""
    try:
        digest = hashlib.sha256(read_regular(scene, "scene")).hexdigest()
    except FileReadError as exc:
        raise SimlogError(f"{log.path}: recorded scene: {exc}") from None
    if digest != log.header["scene_sha256"]:
        raise SimlogError(f"{scene} changed since {log.path} was recorded (SHA-256 differs)")


def check_model(log: Simlog, world: World) -> None:
    """Refuse a world whose state size or timestep differs from the recording's."""
    size = int(mujoco.mj_stateSize(world.model, STATE))
    if size != log.state_size:
        raise SimlogError(f"{log.path}: header: state_size is {log.state_size}, the scene's model has {size}")
    if world.model.opt.timestep != log.timestep:
        raise SimlogError(f"{log.path}: header: timestep is {log.timestep!r}, the scene's {world.model.opt.timestep!r}")


def replay_states(world: World, log: Simlog) -> Iterator[float]:
    """Set the world to each recorded frame in turn (kinematic replay); yields the frame time."""
    check_model(log, world)
    model, data = world.model, world.data
    for record in log.records():
        mujoco.mj_setState(model, data, record.state, STATE)
        mujoco.mj_forward(model, data)
        yield record.time


class _Comparator:
    """Checks, at each recorded frame time, that the re-simulated state equals the recorded one."""

    def __init__(self, frames: list[Record], period: float, start: float) -> None:
        self.frames, self.period, self.next_time = frames, period, start + period
        self.compared = 0
        self.mismatch: float | None = None

    def tick(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        while self.frames and self.frames[0].time < data.time - 0.5 * model.opt.timestep:
            self.frames.pop(0)
        if self.frames and abs(self.frames[0].time - data.time) <= 0.5 * model.opt.timestep:
            record = self.frames.pop(0)
            self.compared += 1
            if self.mismatch is None and state_of(model, data).tobytes() != record.state.tobytes():
                self.mismatch = record.time

    def reset(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Nothing to reset."""

    def snapshot(self) -> dict[str, Any]:
        """Not part of checkpoints (it is added after them)."""
        return {}

    def restore(self, state: dict[str, Any]) -> None:
        """Nothing to restore."""


def resimulate(world: World, log: Simlog, start: float) -> tuple[int, float | None]:
    """Re-simulate from the last checkpoint at or before ``start`` with the recorded commands.

    The world's controllers must be those of the recording, in the same order (the scene's bindings and
    sensors). Each recorded frame after the checkpoint is compared with the re-simulated state at the same
    point of the step (after the controllers' ticks).

    Returns:
        The number of frames compared and the time of the first frame that differs (``None``: bit-identical).
    """
    if not math.isfinite(start):
        raise SimlogError(f"--from must be a finite time, got {start}")
    model, data = world.model, world.data
    checkpoint: Record | None = None
    later: list[Record] = []
    last_time = 0.0
    for record in log.records():
        last_time = record.time
        if record.kind == CHECKPOINT and record.time <= start + 1e-12:
            checkpoint, later = record, []
        elif checkpoint is not None:
            later.append(record)
    if checkpoint is None:
        raise SimlogError(f"{log.path}: no checkpoint at or before {start} s")
    controllers = list(world.controllers)
    snaps = checkpoint.controllers or []
    if len(controllers) != len(snaps):
        raise SimlogError(f"{log.path}: the world has {len(controllers)} controllers, the recording {len(snaps)}")
    check_model(log, world)
    mujoco.mj_setState(model, data, checkpoint.state, STATE)
    mujoco.mj_forward(model, data)
    for k, (controller, snap) in enumerate(zip(controllers, snaps, strict=True)):
        problem = _misfit(controller.snapshot(), snap, "")
        if problem:
            raise SimlogError(
                f"{log.path}: checkpoint at t = {checkpoint.time:g} s: snapshot {k} ({type(controller).__name__}) "
                f"does not fit: {problem}"
            )
        try:
            controller.restore(snap)
        except (KeyError, TypeError, ValueError, IndexError) as exc:
            raise SimlogError(
                f"{log.path}: checkpoint at t = {checkpoint.time:g} s: snapshot {k} does not fit "
                f"{type(controller).__name__} ({type(exc).__name__}: {exc})"
            ) from None
    world.reschedule()
    comparator = _Comparator(later, log.frame_period, checkpoint.time)
    world.controllers.append(comparator)
    commands = [c for c in log.commands() if c.t > checkpoint.time + 1e-12]
    dt = model.opt.timestep
    try:
        while data.time < last_time + 0.5 * dt and comparator.frames:
            while commands and commands[0].t <= data.time + 0.5 * dt:
                commands.pop(0).apply(world)
            world.step(1)
    except (KeyError, TypeError, ValueError, IndexError, OverflowError) as exc:
        raise SimlogError(
            f"{log.path}: re-simulation from the checkpoint at t = {checkpoint.time:g} s failed: the recorded "
            f"controller snapshots are not usable ({type(exc).__name__}: {exc})"
        ) from None
    finally:
        world.controllers.remove(comparator)
    return comparator.compared, comparator.mismatch


def _misfit(template: Any, value: Any, where: str) -> str | None:
    """Why a recorded snapshot does not have the shape of a fresh one (``template``), or ``None``.

    Keys and JSON types must match (numbers may be ints or floats; ``None`` and empty containers in the
    template accept any value of plain JSON data).
    """
    here = where or "snapshot"
    if template is None or (isinstance(template, dict | list) and not template):
        return None
    if isinstance(template, bool) or isinstance(value, bool):
        return None if isinstance(template, bool) and isinstance(value, bool) else f"{here}: expected a boolean"
    if isinstance(template, int | float):
        return None if isinstance(value, int | float) else f"{here}: expected a number, got {type(value).__name__}"
    if isinstance(template, str):
        return None if isinstance(value, str) else f"{here}: expected a string"
    if isinstance(template, list):
        if not isinstance(value, list) or len(value) != len(template):
            return f"{here}: expected an array of {len(template)}"
        return next((p for k, t in enumerate(template) if (p := _misfit(t, value[k], f"{where}[{k}]"))), None)
    if isinstance(template, dict):
        if not isinstance(value, dict) or set(value) != set(template):
            return f"{here}: expected the keys {sorted(template)}"
        return next((p for k, t in template.items() if (p := _misfit(t, value[k], f"{where}.{k}".lstrip(".")))), None)
    return None


def truncation_note(path: Path) -> str | None:
    """What was cut from the recording at ``path`` (one line), or ``None``.

    ``None`` also for a whole, an old (version 1.1) or an unreadable recording (the command reading it
    reports that).
    """
    try:
        log = Simlog(path)
    except SimlogError:
        return None
    log.close()
    return log.truncated
