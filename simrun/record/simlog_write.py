"""Writing ``.simlog`` recordings: :class:`Recorder`, a world controller that streams frames and checkpoints.

The layout is described in :mod:`simrun.record.simlog`.
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
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt

from meshtool.errors import OutputError
from meshtool.files.outdir import AtomicFile
from simrun.errors import SimrunError
from simrun.record.simlog_format import (
    CHECKPOINT,
    CHUNK,
    CHUNK_BYTES,
    CHUNK_WALL,
    CHUNKED_MINOR,
    COMMAND,
    EDIT,
    END,
    FRAME,
    IMAGE,
    MAGIC,
    MAJOR,
    MAX_FRAME_PERIOD,
    MIN_FRAME_PERIOD,
    MINOR,
    RESET,
    SENSORS,
    STATE,
    state_of,
)
from simrun.run.commands import Command
from simrun.safeio import FileReadError, read_regular
from simrun.world.world import World


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
        listener: Live recordings: told what goes into the chunks as it is written (``simrun serve
            --record-as mcap``: :class:`simrun.record.mcap_export.McapStream`): ``frame(state, snapshots)``
            (the integration state, f64; the controllers' snapshots as the checkpoint's JSON holds them, or
            ``None`` for a plain frame), ``sample(name, time, text)`` (the sample's JSON ``{name: reading}``),
            ``image(name, time, rgb)`` ((H, W, 3) u8, the image stored as PNG) and ``flush()`` (a chunk went
            to the operating system).
        prelude: Live recordings: the edits that made the world from its scene before the recording started
            (``simrun serve --edit``), as (simulated time s, ``EditRecord.to_json``, state size before, after):
            written as edit records before the first checkpoint, and the header's ``state_size`` is the scene
            model's (the size before the first), so ``simrun resim`` rebuilds the edited world first.
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
        listener: Any = None,
        prelude: Sequence[tuple[float, str, int, int]] = (),
    ) -> None:
        model = world.model
        self.listener = listener
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
            # the scene's model: with a prelude (edits before the recording), the one before the first edit
            "state_size": int(prelude[0][2]) if prelude else int(mujoco.mj_stateSize(model, STATE)),
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
        self._resets = world.mujoco_resets
        if prelude and not live:
            raise SimrunError("edits before a recording are recorded only in live recordings")
        for t, text, _, size in prelude:  # the edits that made this world from the scene, before its checkpoint
            self.edit(t, text, size)
        if live:  # the checkpoint of this instant first: a recording started while the world runs resimulates from it
            model, data = world.model, world.data
            self._frame(model, data)
            while self._next_frame <= data.time + 0.5 * model.opt.timestep:
                self._next_frame += self.frame_period
            self.flush()

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
        if self.listener is not None:
            self.listener.flush()

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

    def edit(self, t: float, text: str, state_size: int) -> None:
        """Record an edit of the world applied at ``t`` (live recordings; ``simrun serve --edit``).

        ``text``: the edit's ``EditRecord.to_json``; ``state_size``: the edited model's, which the frames after it have.
        """
        if not self.live:
            raise SimrunError("edits are recorded as they happen only in live recordings")
        body = struct.pack("<dI", float(t), int(state_size)) + text.encode("utf-8")
        self._write(struct.pack("<BI", EDIT, len(body)) + body)

    def tick(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Write a frame, or a checkpoint when one is due (live: and each recorded sensor's new samples)."""
        if self.world.mujoco_resets != self._resets:
            self._reset()
        if self.live:
            self._tick_live(model, data)
            return
        self._frame(model, data)
        if self.sensors:
            readings = {n: _plain(self.world.sensors[n].reading) for n in self.sensors}
            extra = struct.pack("<d", float(data.time)) + json.dumps(readings).encode("utf-8")
            self._write(struct.pack("<BI", SENSORS, len(extra)) + extra)

    def _reset(self) -> None:
        """A reset record: MuJoCo reset the world (an unstable simulation) since the last tick; the clock went on."""
        world = self.world
        count = world.mujoco_resets - self._resets
        self._resets = world.mujoco_resets
        info = json.dumps({"count": count, "warnings": world.warnings()}, sort_keys=True).encode("utf-8")
        body = struct.pack("<d", float(world.last_reset)) + info
        self._write(struct.pack("<BI", RESET, len(body)) + body)
        self.counts["resets"] = self.counts.get("resets", 0) + count

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
            if self.listener is not None:
                self.listener.image(name, time, rgb)
            return
        text = json.dumps({name: _plain(reading)})
        extra = struct.pack("<d", time) + text.encode("utf-8")
        self._write(struct.pack("<BI", SENSORS, len(extra)) + extra)
        self.counts["sensor_samples"] += 1
        if self.listener is not None:
            self.listener.sample(name, time, text)

    def _frame(self, model: mujoco.MjModel, data: mujoco.MjData) -> int:
        """Write a frame, or a checkpoint when one is due; its kind."""
        state = state_of(model, data)
        body = struct.pack("<d", float(data.time)) + state.tobytes()
        kind = FRAME
        text = None
        if data.time + 0.5 * model.opt.timestep >= self._next_checkpoint:
            snaps = [c.snapshot() for c in self.world.controllers if c is not self]
            text = json.dumps(snaps)
            extra = text.encode("utf-8")
            body += struct.pack("<I", len(extra)) + extra
            kind = CHECKPOINT
            self._next_checkpoint += self.checkpoint_every
        self._write(struct.pack("<BI", kind, len(body)) + body)
        if self.listener is not None and self.live:
            self.listener.frame(state, None if text is None else json.loads(text))
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
