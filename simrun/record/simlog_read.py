"""Reading ``.simlog`` recordings: :class:`Simlog` streams and checks them; kinematic replay of the frames.

The layout is described in :mod:`simrun.record.simlog`.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import struct
import zlib
from collections.abc import Iterator
from pathlib import Path
from typing import Any, BinaryIO

import mujoco
import numpy as np

from meshtool.files.nesting import DocumentLimitError, bounded
from simrun.record.simlog_format import (
    _HEADER,
    CHECKPOINT,
    CHUNK,
    CHUNKED_MINOR,
    COMMAND,
    EDIT,
    END,
    FRAME,
    IMAGE,
    KINDS,
    MAGIC,
    MAJOR,
    MAX_FRAME_PERIOD,
    MAX_HEADER_BYTES,
    MAX_STATE_SIZE,
    MIN_FRAME_PERIOD,
    RESET,
    SENSORS,
    STATE,
    Record,
    SimlogError,
    _refuse_constant,
)
from simrun.run.commands import Command, parse_command
from simrun.safeio import FileReadError, open_regular, read_regular
from simrun.world.world import MAX_TIMESTEP, MIN_TIMESTEP, World

_EMPTY = np.zeros(0)


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
        self._recorded = 0  # command records of a chunked recording
        #: Edit records (``simrun serve --edit``) of a chunked recording, counted when it is opened.
        self.edits = 0
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
        """Read a chunked recording's structure: where its whole chunks end, what was cut, how many commands.

        The commands themselves are parsed as they are streamed (:meth:`events`), never all held at once.
        """
        good = self._start
        for offset, body in self._chunks():
            good = offset + len(body)
            at = 0
            while at + 5 <= len(body):
                kind, length = struct.unpack("<BI", body[at : at + 5])
                self._recorded += kind == COMMAND
                self.edits += kind == EDIT
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

    def _command(self, body: bytes, offset: int, k: int, last: Command | None) -> Command:
        """Check one command record (the ``k``-th of a chunked recording; ``last``: the one before it)."""
        entry = self._json(body[8:], offset, "command record") if len(body) >= 8 else None

        def fail(message: str, key: str | None = None) -> SimlogError:
            return SimlogError(f"{self.path}: byte {offset}: command {k}" + (f".{key}" if key else "") + f": {message}")

        if not isinstance(entry, list) or len(entry) != 5:
            raise fail("expected [t, service, entity, call, args]")
        table = dict(zip(("t", "service", "entity", "call", "args"), entry, strict=True))
        command = parse_command(table, fail, f"{self.path}: byte {offset}: command {k}")
        if last is not None and command.t < last.t:
            raise fail(f"at t = {command.t!r} s, before command {k - 1} at {last.t!r} s (the clock runs backwards)")
        return command

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
        """The recorded commands: version 1.1's timed ones (checked at open), a chunked recording's as applied.

        Raises:
            SimlogError: A malformed command record of a chunked recording (read here, naming its byte).
        """
        if self.minor < CHUNKED_MINOR:
            return list(self._commands)
        return [r.command for r in self.events() if r.kind == COMMAND]

    def sensor_readings(self) -> Iterator[tuple[float, dict[str, Any]]]:
        """The recorded sensor readings: (time, {sensor name: reading as plain data}; edits do not change them)."""
        for record in self.records(sensors=True, edits=True):
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
        ``sensor_samples.NAME``), ``images`` (and ``images.NAME``), ``commands``, ``resets`` (MuJoCo's).
        """
        counts = {"frames": 0, "checkpoints": 0, "sensor_samples": 0, "images": 0, "commands": len(self._commands)}
        counts["commands"] += self._recorded
        counts["resets"] = 0
        for offset, kind, body in self._stream():
            if kind == RESET:
                counts["resets"] += 1
            elif kind in (FRAME, CHECKPOINT):
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

    def records(self, sensors: bool = False, edits: bool = False) -> Iterator[Record]:
        """Every frame and checkpoint record in order (or, with ``sensors``, the sensor records).

        A recording with edits is refused unless ``edits`` (the caller applies them:
        :func:`simrun.record.replay_edits.edited_states`; frames after an edit are of the edited model).

        Raises:
            SimlogError: A truncated or malformed record, a non-finite state or time, or times that do not
                advance frame by frame (naming the byte offset).
        """
        wanted = (SENSORS,) if sensors else (FRAME, CHECKPOINT)
        for record in self.events():
            if not edits and record.kind == COMMAND and not isinstance(record.command, Command):  # an edit: the
                # frames after it are of another model than the scene's
                raise SimlogError(
                    f"{self.path}: the world was edited at t = {record.time:g} s (simrun serve --edit): replay "
                    "exports do not show an edited world yet; simrun resim re-simulates it"
                )
            if record.kind in wanted:
                yield record

    def events(self) -> Iterator[Record]:
        """Every record in file order, checked: frames, checkpoints, sensor readings, commands (1.2), resets.

        Streamed (one record in memory at a time). Times never run backwards: frames advance by at most one
        frame period; a command or reset is at or after the frame before it.

        Raises:
            SimlogError: A truncated or malformed record, a non-finite state or time, or times that do not
                advance frame by frame (naming the byte offset).
        """
        frame_bytes = 8 + 8 * self.state_size
        previous: float | None = None
        step = self.frame_period + 1.5 * self.timestep + 1e-9
        chunked = self.minor >= CHUNKED_MINOR
        commands = 0
        last_command: Command | None = None
        for offset, kind, body in self._stream():
            length = len(body)
            if kind == IMAGE and chunked:
                continue  # read by images()
            if kind == EDIT and chunked:  # simrun serve --edit: the frames after it have the edited model's size
                edit, size = self._edit(body, offset)
                if previous is not None and edit.t < previous - 0.5 * self.timestep:
                    raise SimlogError(f"{self.path}: byte {offset}: edit at t = {edit.t!r} s comes after the frame at "
                                      f"{previous!r} s (the clock runs backwards)")  # fmt: skip
                frame_bytes = 8 + 8 * size
                # yielded as a command: an EditRecord is applied as a Command is (t, apply(world)), so
                # resimulate applies it at its step like the service commands around it
                yield Record(COMMAND, edit.t, _EMPTY, None, command=edit, offset=offset)
                continue
            if kind in (SENSORS, RESET) or (kind == COMMAND and chunked):
                what = KINDS[kind]
                if length < 8:
                    raise SimlogError(f"{self.path}: byte {offset}: {what} record too short")
                time = struct.unpack("<d", body[:8])[0]
                if not math.isfinite(time) or time < 0:
                    raise SimlogError(f"{self.path}: byte {offset}: {what} record time {time!r} is not a time >= 0")
                if kind == COMMAND:
                    command = self._command(body, offset, commands, last_command)
                    last_command = command
                    commands += 1
                    if previous is not None and command.t < previous - 0.5 * self.timestep:
                        raise SimlogError(
                            f"{self.path}: byte {offset}: command {commands - 1} at t = {command.t!r} s comes after "
                            f"the frame at {previous!r} s (the clock runs backwards)"
                        )
                    yield Record(kind, command.t, _EMPTY, None, command=command, offset=offset)
                elif kind == RESET:
                    info = self._json(body[8:], offset, "reset record")
                    if not isinstance(info, dict):
                        raise SimlogError(f"{self.path}: byte {offset}: reset record is not a JSON object")
                    if previous is not None and time < previous - 0.5 * self.timestep:
                        raise SimlogError(
                            f"{self.path}: byte {offset}: reset at t = {time!r} s comes after the frame at "
                            f"{previous!r} s (the clock runs backwards)"
                        )
                    yield Record(kind, time, _EMPTY, None, info=info, offset=offset)
                else:
                    readings = self._json(body[8:], offset, "sensor record")
                    if not isinstance(readings, dict):
                        raise SimlogError(f"{self.path}: byte {offset}: sensor record is not a JSON object")
                    yield Record(kind, time, _EMPTY, [readings], offset=offset)
                continue
            if kind not in (FRAME, CHECKPOINT) or length < frame_bytes:
                name = KINDS.get(kind, "unknown")
                raise SimlogError(f"{self.path}: byte {offset}: corrupt record (kind {kind}: {name}, {length} bytes)")
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
            yield Record(kind, time, state, controllers, offset=offset)

    def _edit(self, body: bytes, offset: int) -> tuple[Any, int]:
        """An edit record's :class:`~simrun.world.edit_apply.EditRecord` and the state size after it."""
        from simrun.world.edit import EditError
        from simrun.world.edit_apply import EditRecord

        if len(body) < 12:
            raise SimlogError(f"{self.path}: byte {offset}: edit record too short")
        _, size = struct.unpack("<dI", body[:12])
        if not 1 <= size <= MAX_STATE_SIZE:
            raise SimlogError(f"{self.path}: byte {offset}: edit record state size {size} out of range")
        try:
            edit = bounded(lambda: EditRecord.from_json(body[12:].decode("utf-8")))
        except (EditError, UnicodeDecodeError, DocumentLimitError) as exc:
            raise SimlogError(f"{self.path}: byte {offset}: corrupt edit record ({exc})") from None
        return edit, int(size)

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


#: Largest body coordinate a kinematic replay accepts, metres (the float32 of glTF and MCAP holds it).
MAX_REPLAY_COORDINATE_M = 1e30


def replay_states(world: World, log: Simlog) -> Iterator[float]:
    """Set the world to each recorded frame in turn (kinematic replay); yields the frame time.

    Raises:
        SimlogError: A malformed record, or a frame that puts a body beyond :data:`MAX_REPLAY_COORDINATE_M`
            (a corrupt state the watchable outputs cannot hold), naming the frame's time and the body.
    """
    check_model(log, world)
    for record in log.records():
        set_frame(world, log, record)
        yield record.time


def set_frame(world: World, log: Simlog, record: Record) -> None:
    """Set ``world`` to one recorded frame's state (``mj_setState`` of the full state, then ``mj_forward``).

    Raises:
        SimlogError: The frame puts a body beyond :data:`MAX_REPLAY_COORDINATE_M` (metres, world frame), naming
            the record's byte offset in ``log``, the frame's time and the body.
    """
    model, data = world.model, world.data
    mujoco.mj_setState(model, data, record.state, STATE)
    mujoco.mj_forward(model, data)
    far = np.abs(data.xpos).max(axis=1)
    if not far.max(initial=0.0) <= MAX_REPLAY_COORDINATE_M:
        body = model.body(int(np.argmax(~(far <= MAX_REPLAY_COORDINATE_M)))).name
        raise SimlogError(
            f"{log.path}: byte {record.offset}: the frame at t = {record.time!r} s puts body {body!r} beyond "
            f"{MAX_REPLAY_COORDINATE_M:g} m; the recorded state is corrupt"
        )


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
