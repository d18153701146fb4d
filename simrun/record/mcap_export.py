"""A ``.simlog`` as MCAP with Foxglove's well-known schemas, written by the Foxglove SDK (``foxglove-sdk``).

``simrun replay X.simlog --mcap OUT.mcap`` (and ``simrun serve --record-as mcap``) replays the recording
kinematically (:func:`simrun.record.simlog.replay_states`) and logs it through the channels the live Foxglove
stream has (:class:`simrun.record.foxglove_channels.FoxgloveChannels`: topics, schemas and frames are listed
there), with log times in nanoseconds of simulated time (``round(t * 1e9)``) and the same time in each
message's ``timestamp``:

* every recorded frame (every 0.02 s): ``/clock``, ``/tf`` (every body from ``world``), ``/NAME/pose`` per
  robot, ``/NAME/joint_states`` per robot with actuated joints, and ``/scene`` (the bodies' geoms) at the
  first frame and every second after;
* ``/NAME/odometry``: ``foxglove.PoseInFrame`` per drive service, at each checkpoint (every second): the
  service's odometry estimate (x, y, heading) in the frame ``NAME/odom``, which ``/tf`` places at the robot's
  pose of the first frame (the odometry origin of a run recorded from its start);
* ``/sensors/NAME``: recorded sensor readings (``--record-sensors``), one message per sample: a laser as
  ``foxglove.LaserScan``, a webcam as ``foxglove.RawImage`` (``rgb8``) and ``/sensors/NAME/compressed``
  (``foxglove.CompressedImage``, JPEG), an IMU as JSON ``simrun.Imu``, any other sensor as JSON (its reading's
  fields).

Messages are protobuf, with the schemas the SDK embeds, so Foxglove and any MCAP reader with protobuf
support decode them. The file is written beside the target and renamed over it when complete.

:class:`McapStream` writes the same MCAP while a ``.simlog`` is being recorded (``simrun serve --record-as
mcap``): the :class:`~simrun.record.simlog.Recorder` hands it each frame, checkpoint, sample and image as it
writes them (its ``listener``), and it logs them through the same channels and the same rules as the export
(a frame's state set on a data of its own, as the replay sets it), so the messages of every channel are the
ones :func:`export_mcap` writes from the finished recording (same topics, counts, log times and bytes; only
their order across channels and so the chunks differ: the export logs frames first, then readings, then
images). The MCAP is in place from the start and ends a chunk whenever the recording does (every checkpoint,
every second of simulated time): a server killed outright leaves an MCAP whose whole chunks readers read.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from meshtool.formats import check_suffix
from simrun.errors import SimrunError
from simrun.outfile import check_output, scene_files
from simrun.record.foxglove_channels import TF_TOPIC, WORLD_FRAME, FoxgloveChannels
from simrun.record.simlog import CHECKPOINT, Simlog, SimlogError, check_model, check_scene, replay_states
from simrun.run.session import prepare
from simrun.scene.scene_file import load_scene

__all__ = ["TF_TOPIC", "WORLD_FRAME", "McapStream", "McapSummary", "export_mcap", "open_writer", "temporary_beside"]


@dataclass
class McapSummary:
    """What :func:`export_mcap` wrote: the file, and messages per topic."""

    path: Path
    messages: dict[str, int] = field(default_factory=dict)
    size: int = 0


def _ns(t: float) -> int:
    return round(t * 1e9)


def export_mcap(log_path: Path, out: Path) -> McapSummary:
    """Write the recording ``log_path`` as MCAP to ``out`` (see the module for topics and schemas).

    Raises:
        SimrunError: A bad recording, a changed scene, or an output that cannot be written.
    """
    check_output(out, inputs=[log_path])
    wrong = check_suffix(out, "mcap")
    if wrong is not None:
        raise SimrunError(wrong, path=str(out))
    log = Simlog(log_path)
    try:
        scene = log.scene_path()
        check_scene(log, scene)
        world = load_scene(scene)
        check_model(log, world)
        prepare(world)
        check_output(out, inputs=[log_path, *scene_files(scene)], world=world)  # nor a file the scene reads
        return _write(world, log, out)
    finally:
        log.close()


def _write(world: Any, log: Simlog, out: Path) -> McapSummary:
    import foxglove
    from PIL import Image

    from simrun.record.replay_edits import edited_states, has_edits
    from simrun.services.drive_service import DriveService

    for name in log.header["sensors"]:
        if name not in world.sensors:
            raise SimrunError(f"{log.path}: header: sensors: {name!r} is not a sensor of the recorded scene")
    tmp = temporary_beside(out)
    context = foxglove.Context()
    ok = False
    try:
        writer = open_writer(tmp, context)
        channels = FoxgloveChannels(world, context, sensors=log.header["sensors"])
        drives = [(k, c.name) for k, c in enumerate(world.controllers) if isinstance(c, DriveService)]
        edited = has_edits(log)  # simrun serve --edit: the edits applied as the frames come, channels following
        checkpoints = {round(r.time, 9): r.controllers for r in log.records(edits=edited) if r.kind == CHECKPOINT}
        recorded = world.model
        for t in (edited_states if edited else replay_states)(world, log):
            channels.refresh()
            channels.frame()
            # odometry from the checkpoints' snapshots, by controller index: only while no edit changed the model
            snaps = (checkpoints.get(round(t, 9)) or []) if world.model is recorded else []
            for k, name in drives if snaps else ():
                if k < len(snaps) and "odom" in snaps[k]:
                    channels.odometry(name, t, snaps[k]["odom"])
        readings = _Readings(channels, log.path, world, log.header["sensors"])
        for frame_time, sample in log.sensor_readings():
            for name, reading in sample.items():
                readings.reading(name, frame_time, reading)
        images = getattr(log, "images", None)  # recordings 1.2+: each rendered image once, as PNG
        for t, name, _, data in images() if images is not None else ():
            if name in readings.cameras:
                try:
                    with Image.open(io.BytesIO(data)) as png:
                        rgb = np.asarray(png.convert("RGB"))
                except (OSError, ValueError, Image.DecompressionBombError) as exc:
                    raise SimlogError(f"{log.path}: the image of {name!r} at t = {t:g} s: not a PNG ({exc})") from None
                readings.image(name, t, rgb)
        writer.close()
        os.chmod(tmp, 0o644)
        os.replace(tmp, out)
        ok = True
    except OSError as exc:
        raise SimrunError(f"cannot write {out}: {exc.strerror or exc}") from None
    except RuntimeError as exc:  # the Foxglove SDK's writer: FoxgloveError (a full disk: "I/O error from writing")
        if "FoxgloveError" not in str(exc):
            raise
        raise SimrunError(f"cannot write {out}: {exc}") from None
    finally:
        if not ok:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
    return McapSummary(out, dict(channels.counts), out.stat().st_size)


def temporary_beside(out: Path) -> str:
    """A new empty file beside ``out`` (``O_EXCL``, named ``.NAME.*.tmp``), its path.

    Raises:
        SimrunError: It cannot be made (the folder is missing or not writable).
    """
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent)
    except (OSError, ValueError) as exc:
        raise SimrunError(f"cannot write {out}: {getattr(exc, 'strerror', None) or exc}") from None
    os.close(fd)
    return tmp


def open_writer(path: str, context: Any) -> Any:
    """foxglove-sdk's MCAP writer on ``path``, a sink of ``context`` (zstd chunks of at most 1 MiB).

    The one writer set-up of every MCAP simrun writes: the export, :class:`McapStream` and the live Foxglove
    server's ``--foxglove-mcap`` (:mod:`simrun.serve.foxglove_live`).
    """
    import foxglove

    options = foxglove.mcap.MCAPWriteOptions(compression=foxglove.mcap.MCAPCompression.Zstd)
    return foxglove.open_mcap(path, allow_overwrite=True, context=context, writer_options=options)


class _Readings:
    """The recorded sensor readings as messages: one per sample (at the sample's time), images apart.

    The one rule of the export and of :class:`McapStream`. ``source``: the recording, named in errors.
    """

    def __init__(self, channels: FoxgloveChannels, source: Path, world: Any, sensors: list[str]) -> None:
        from simrun.sensors.cameras import Webcam

        self.channels, self.source = channels, source
        self.cameras = {n for n in sensors if isinstance(world.sensors[n], Webcam)}
        self._sampled: dict[str, float] = {}

    def reading(self, name: str, frame_time: float, reading: Any) -> None:
        """A recorded reading (plain data, as the ``.simlog`` holds it) of sensor ``name`` at ``frame_time`` s."""
        if reading is None:
            return
        # every frame repeats the latest reading (1.1): one message per sample, at the sample's time
        t = reading["time"] if isinstance(reading, dict) and "time" in reading else frame_time
        if isinstance(t, bool) or not isinstance(t, int | float) or not 0 <= t < 1e12:
            raise SimlogError(f"{self.source}: the reading of sensor {name!r} at t = {frame_time:g} s: its time "
                              f"{t!r} is not a time in seconds")  # fmt: skip
        t = float(t)
        if self._sampled.get(name) == t:
            return
        self._sampled[name] = t
        if name in self.cameras and not (isinstance(reading, dict) and "rgb" in reading):
            return  # a recording that keeps its images apart (:meth:`image`)
        self._log(name, t, reading)

    def image(self, name: str, t: float, rgb: Any) -> None:
        """Camera ``name``'s image (H, W, 3) u8 rendered at ``t`` s."""
        self._log(name, t, {"time": t, "rgb": rgb})

    def _log(self, name: str, t: float, reading: Any) -> None:
        """Log one recorded sensor reading; a reading of the wrong shape is the recording's error (one line)."""
        try:
            self.channels.sensor(name, t, reading)
        except (KeyError, TypeError, ValueError, IndexError, AttributeError, OverflowError) as exc:
            raise SimlogError(
                f"{self.source}: the reading of sensor {name!r} at t = {t:g} s does not fit its sensor "
                f"({type(exc).__name__}: {exc})"
            ) from None


class _Replayed:
    """The world seen through ``data``, a data of its own on the world's model (what the export's replay sets)."""

    def __init__(self, world: Any, data: Any) -> None:
        self._world, self.data = world, data

    def __getattr__(self, name: str) -> Any:
        return getattr(self._world, name)

    def __iter__(self) -> Any:
        return iter(self._world)

    def __len__(self) -> int:
        return len(self._world)


class McapStream:
    """The MCAP of a ``.simlog`` being recorded, written as it is recorded (see the module).

    A :class:`~simrun.record.simlog.Recorder` ``listener`` (its methods run in the recording's thread).
    The file is made beside ``out`` and renamed over it by :meth:`start` (once the recording exists); a
    failed write (a full disk) ends the MCAP, keeping its whole chunks, and never the simulation.

    Args:
        world: The world being recorded (compiled, its controllers added; only its model is read).
        out: The ``.mcap`` to write.
        source: The ``.simlog`` recorded (named in errors).
        sensors: The recorded sensors' names (each gets its channels).

    Attributes:
        failed: Why the MCAP ended early, or ``None``.

    Raises:
        SimrunError: ``out`` cannot be made.
    """

    def __init__(self, world: Any, out: Path, source: Path, sensors: tuple[str, ...] = ()) -> None:
        import foxglove
        import mujoco

        from simrun.services.drive_service import DriveService

        wrong = check_suffix(out, "mcap")
        if wrong is not None:
            raise SimrunError(wrong, path=str(out))
        self.out, self.source = out, source
        self.failed: str | None = None
        self._model = world.model
        data = mujoco.MjData(world.model)  # a freshly loaded scene's state, as the export's world has it
        mujoco.mj_forward(world.model, data)
        self._data = data
        # the checkpoint's snapshots are of every controller before the recorder (appended last), as in the export
        self._drives = [(k, c.name) for k, c in enumerate(world.controllers) if isinstance(c, DriveService)]
        self._tmp: str | None = temporary_beside(out)
        self._writer: Any = None
        try:
            context = foxglove.Context()
            self._writer = open_writer(self._tmp, context)
            self.channels = FoxgloveChannels(_Replayed(world, data), context, sensors=sensors)
            self._readings = _Readings(self.channels, source, world, list(sensors))
        except BaseException as exc:  # whatever stops it (Ctrl+C included), no writer or file is left; re-raised
            self.close()
            self._drop()
            if isinstance(exc, RuntimeError) and "FoxgloveError" in str(exc):
                raise SimrunError(f"cannot write {out}: {exc}") from None
            raise

    def frame(self, state: Any, snapshots: list[Any] | None) -> None:
        """A recorded frame: its integration state (f64), and at a checkpoint the controllers' snapshots."""
        import mujoco

        from simrun.record.simlog import STATE

        if self._writer is None:
            return
        with self._guard():
            mujoco.mj_setState(self._model, self._data, state, STATE)
            mujoco.mj_forward(self._model, self._data)
            self.channels.frame()
            t = float(self._data.time)
            for k, name in self._drives if snapshots else ():
                assert snapshots is not None
                if k < len(snapshots) and "odom" in snapshots[k]:
                    self.channels.odometry(name, t, snapshots[k]["odom"])

    def sample(self, name: str, time: float, text: str) -> None:
        """A recorded sample of sensor ``name`` taken at ``time`` s, as its JSON ``{name: reading}``."""
        if self._writer is not None:
            with self._guard():
                self._readings.reading(name, time, json.loads(text)[name])

    def image(self, name: str, time: float, rgb: Any) -> None:
        """Camera ``name``'s image (H, W, 3) u8 rendered at ``time`` s (stored once in the recording)."""
        if self._writer is not None and name in self._readings.cameras:
            with self._guard():
                self._readings.image(name, time, rgb)

    def flush(self) -> None:
        """End the chunk being written and hand it to the operating system (the recording wrote a chunk)."""
        if self._writer is not None:
            with self._guard():
                self._writer.flush()

    def close(self) -> None:
        """Finish the MCAP (its summary); a second call does nothing.

        Raises:
            SimrunError: The MCAP ended early or cannot be finished (a full disk): its whole chunks stay.
        """
        writer, self._writer = self._writer, None
        if writer is not None:
            with self._guard():
                writer.close()
        if self.failed is not None:
            raise SimrunError(self.failed)

    @contextlib.contextmanager
    def _guard(self) -> Any:
        """A failed write ends the MCAP (remembered in :attr:`failed`), never the recording's thread."""
        try:
            yield
        except Exception as exc:  # whatever it is (an edit's new state size too), the world goes on
            if isinstance(exc, SimrunError):
                why = str(exc)
            elif isinstance(exc, OSError | RuntimeError):
                why = f"cannot write {self.out}: {getattr(exc, 'strerror', None) or exc}"
            else:
                why = f"{self.out}: {type(exc).__name__}: {exc}"
            self.failed = self.failed or f"{why}; the MCAP ends there"
            writer, self._writer = self._writer, None
            if writer is not None:
                with contextlib.suppress(Exception):
                    writer.close()

    def start(self) -> None:
        """Put the MCAP in place of ``out`` (the recording exists; a failure leaves ``out`` as it was)."""
        assert self._tmp is not None
        with self._guard():
            os.chmod(self._tmp, 0o644)
            os.replace(self._tmp, self.out)
            self._tmp = None
        self._drop()  # what a failed rename left

    def discard(self) -> None:
        """The recording could not start: close the writer and remove the file, never put in place."""
        with contextlib.suppress(SimrunError):
            self.close()
        self._drop()

    def _drop(self) -> None:
        if self._tmp is not None:
            with contextlib.suppress(OSError):
                os.unlink(self._tmp)
            self._tmp = None
