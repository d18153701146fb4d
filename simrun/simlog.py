r"""``.simlog`` recordings: versioned, streamed to disk in records, replayable and re-simulatable bit-exactly.

Layout (little-endian): 8-byte magic ``\x89SIMLOG\n``, u16 major, u16 minor, u32 header length, the header
as UTF-8 JSON (MuJoCo version, platform, scene path and SHA-256, seed, timestep, state size, frame period,
the timed commands), then records: u8 kind, u32 length, payload. Kind 1, a frame: f64 time and the full
integration state (``mj_getState(mjSTATE_INTEGRATION)``, f64 array). Kind 2, a checkpoint: a frame
followed by the JSON snapshots of every world controller (drive and arm services, sensors). Records are
written as the run goes, so memory stays bounded; the reader streams them back.
"""

from __future__ import annotations

import hashlib
import json
import platform
import struct
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO

import mujoco
import numpy as np
import numpy.typing as npt

from simrun.errors import SimrunError
from simrun.play import Command
from simrun.world import World

MAGIC = b"\x89SIMLOG\n"
MAJOR, MINOR = 1, 0
FRAME, CHECKPOINT, SENSORS = 1, 2, 3
STATE = mujoco.mjtState.mjSTATE_INTEGRATION


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
        controller: Path of a Python controller module the run used (re-loaded by ``resim``).
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
        controller: str | None = None,
    ) -> None:
        model = world.model
        self.world, self.period, self.checkpoint_every = world, period, checkpoint
        unknown = [n for n in sensors if n not in world.sensors]
        if unknown:
            known = ", ".join(world.sensors) or "none"
            raise SimrunError(f"no sensor named {', '.join(unknown)} (known: {known})")
        self.sensors = sensors
        self.next_time = world.time
        self._next_checkpoint = world.time
        header = {
            "mujoco": mujoco.__version__,
            "platform": f"{platform.system()} {platform.machine()} Python {platform.python_version()}",
            "scene": str(scene),
            "scene_sha256": hashlib.sha256(scene.read_bytes()).hexdigest(),
            "seed": seed,
            "timestep": model.opt.timestep,
            "state_size": int(mujoco.mj_stateSize(model, STATE)),
            "frame_period": period,
            "commands": [[c.t, c.service, c.entity, c.call, list(c.args)] for c in commands],
            "sensors": list(sensors),
            "controller": controller,
        }
        raw = json.dumps(header, sort_keys=True).encode("utf-8")
        try:
            self._file: BinaryIO = open(path, "wb")  # noqa: SIM115 - closed by close()
        except OSError as exc:
            raise SimrunError(f"{path}: cannot write: {exc.strerror}") from None
        self._file.write(MAGIC + struct.pack("<HHI", MAJOR, MINOR, len(raw)) + raw)
        self.frames = 0
        world.controllers.append(self)

    def tick(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Write a frame, or a checkpoint when one is due."""
        state = state_of(model, data)
        body = struct.pack("<d", float(data.time)) + state.tobytes()
        kind = FRAME
        if data.time + 0.5 * model.opt.timestep >= self._next_checkpoint:
            snaps = [c.snapshot() for c in self.world.controllers if c is not self]
            extra = json.dumps(snaps).encode("utf-8")
            body += struct.pack("<I", len(extra)) + extra
            kind = CHECKPOINT
            self._next_checkpoint += self.checkpoint_every
        self._file.write(struct.pack("<BI", kind, len(body)) + body)
        self.frames += 1
        if self.sensors:
            readings = {n: _plain(self.world.sensors[n].reading) for n in self.sensors}
            extra = struct.pack("<d", float(data.time)) + json.dumps(readings).encode("utf-8")
            self._file.write(struct.pack("<BI", SENSORS, len(extra)) + extra)

    def reset(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Recording continues across resets."""

    def snapshot(self) -> dict[str, Any]:
        """The recorder holds no simulation state."""
        return {}

    def close(self) -> None:
        """Flush and close the file."""
        self._file.close()
        if self in self.world.controllers:
            self.world.controllers.remove(self)


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
    """A recording opened for reading (records are streamed, not loaded at once)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        try:
            self._file: BinaryIO = open(path, "rb")  # noqa: SIM115 - closed by close()
        except OSError as exc:
            raise SimlogError(f"{path}: cannot be read: {exc.strerror}") from None
        head = self._file.read(16)
        if len(head) < 16 or head[:8] != MAGIC:
            raise SimlogError(f"{path}: not a .simlog (bad magic number)")
        major, minor, length = struct.unpack("<HHI", head[8:16])
        if major != MAJOR:
            raise SimlogError(f"{path}: .simlog version {major}.{minor} is newer than this reader ({MAJOR}.x)")
        raw = self._file.read(length)
        try:
            self.header: dict[str, Any] = json.loads(raw.decode("utf-8"))
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise SimlogError(f"{path}: corrupt header ({exc})") from None
        self._start = 16 + length
        self.state_size = int(self.header["state_size"])

    def commands(self) -> list[Command]:
        """The recorded timed commands."""
        return [Command(float(t), s, e, c, tuple(a)) for t, s, e, c, a in self.header["commands"]]

    def sensor_readings(self) -> Iterator[tuple[float, dict[str, Any]]]:
        """The recorded sensor readings: (time, {sensor name: reading as plain data})."""
        for record in self.records(sensors=True):
            yield record.time, (record.controllers or [{}])[0]

    def records(self, sensors: bool = False) -> Iterator[Record]:
        """Every frame and checkpoint record in order (or, with ``sensors``, the sensor records).

        Raises:
            SimlogError: A truncated or malformed record (naming its byte offset).
        """
        self._file.seek(self._start)
        offset = self._start
        frame_bytes = 8 + 8 * self.state_size
        while True:
            head = self._file.read(5)
            if not head:
                return
            if len(head) < 5:
                raise SimlogError(f"{self.path}: truncated record at byte {offset}")
            kind, length = struct.unpack("<BI", head)
            body = self._file.read(length)
            if kind == SENSORS and len(body) == length and length >= 8:
                offset += 5 + length
                if sensors:
                    try:
                        yield Record(
                            kind, struct.unpack("<d", body[:8])[0], np.zeros(0), [json.loads(body[8:].decode("utf-8"))]
                        )
                    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
                        raise SimlogError(f"{self.path}: corrupt sensor record ({exc})") from None
                continue
            if len(body) != length or kind not in (FRAME, CHECKPOINT) or length < frame_bytes:
                raise SimlogError(f"{self.path}: corrupt or truncated record at byte {offset}")
            time = struct.unpack("<d", body[:8])[0]
            state = np.frombuffer(body[8:frame_bytes], dtype=np.float64)
            controllers = None
            if kind == CHECKPOINT:
                (n,) = struct.unpack("<I", body[frame_bytes : frame_bytes + 4])
                try:
                    controllers = json.loads(body[frame_bytes + 4 : frame_bytes + 4 + n].decode("utf-8"))
                except (UnicodeDecodeError, json.JSONDecodeError) as exc:
                    raise SimlogError(f"{self.path}: corrupt checkpoint at byte {offset} ({exc})") from None
            if not sensors:
                yield Record(kind, time, state, controllers)
            offset += 5 + length

    def close(self) -> None:
        """Close the file."""
        self._file.close()


def check_scene(log: Simlog, scene: Path) -> None:
    """Refuse to replay against a scene file that changed since the recording."""
    digest = hashlib.sha256(scene.read_bytes()).hexdigest()
    if digest != log.header["scene_sha256"]:
        raise SimlogError(f"{scene} changed since {log.path} was recorded (SHA-256 differs)")


def replay_states(world: World, log: Simlog) -> Iterator[float]:
    """Set the world to each recorded frame in turn (kinematic replay); yields the frame time."""
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


def resimulate(world: World, log: Simlog, start: float) -> tuple[int, float | None]:
    """Re-simulate from the last checkpoint at or before ``start`` with the recorded commands.

    The world's controllers must be those of the recording, in the same order (the scene's bindings and
    sensors). Each recorded frame after the checkpoint is compared with the re-simulated state at the same
    point of the step (after the controllers' ticks).

    Returns:
        The number of frames compared and the time of the first frame that differs (``None``: bit-identical).
    """
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
    mujoco.mj_setState(model, data, checkpoint.state, STATE)
    mujoco.mj_forward(model, data)
    for controller, snap in zip(controllers, snaps, strict=True):
        controller.restore(snap)
    comparator = _Comparator(later, float(log.header["frame_period"]), checkpoint.time)
    world.controllers.append(comparator)
    commands = [c for c in log.commands() if c.t > checkpoint.time + 1e-12]
    dt = model.opt.timestep
    try:
        while data.time < last_time + 0.5 * dt and comparator.frames:
            while commands and commands[0].t <= data.time + 0.5 * dt:
                commands.pop(0).apply(world)
            world.step(1)
    finally:
        world.controllers.remove(comparator)
    return comparator.compared, comparator.mismatch
