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
"""

from __future__ import annotations

import contextlib
import io
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

__all__ = ["TF_TOPIC", "WORLD_FRAME", "McapSummary", "export_mcap"]


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

    from simrun.sensors.cameras import Webcam
    from simrun.services.drive_service import DriveService

    for name in log.header["sensors"]:
        if name not in world.sensors:
            raise SimrunError(f"{log.path}: header: sensors: {name!r} is not a sensor of the recorded scene")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent)
    except (OSError, ValueError) as exc:
        raise SimrunError(f"cannot write {out}: {getattr(exc, 'strerror', None) or exc}") from None
    os.close(fd)
    context = foxglove.Context()
    options = foxglove.mcap.MCAPWriteOptions(compression=foxglove.mcap.MCAPCompression.Zstd)
    ok = False
    try:
        writer = foxglove.open_mcap(tmp, allow_overwrite=True, context=context, writer_options=options)
        channels = FoxgloveChannels(world, context, sensors=log.header["sensors"])
        drives = [(k, c.name) for k, c in enumerate(world.controllers) if isinstance(c, DriveService)]
        checkpoints = {round(r.time, 9): r.controllers for r in log.records() if r.kind == CHECKPOINT}
        for t in replay_states(world, log):
            channels.frame()
            snaps = checkpoints.get(round(t, 9)) or []
            for k, name in drives if snaps else ():
                if k < len(snaps) and "odom" in snaps[k]:
                    channels.odometry(name, t, snaps[k]["odom"])
        cameras = {n for n in log.header["sensors"] if isinstance(world.sensors[n], Webcam)}
        sampled: dict[str, float] = {}
        for frame_time, readings in log.sensor_readings():
            for name, reading in readings.items():
                if reading is None:
                    continue
                # every frame repeats the latest reading: one message per sample, at the sample's time
                t = reading["time"] if isinstance(reading, dict) and "time" in reading else frame_time
                if isinstance(t, bool) or not isinstance(t, int | float) or not 0 <= t < 1e12:
                    raise SimlogError(f"{log.path}: the reading of sensor {name!r} at t = {frame_time:g} s: its time "
                                      f"{t!r} is not a time in seconds")  # fmt: skip
                t = float(t)
                if sampled.get(name) == t:
                    continue
                sampled[name] = t
                if name in cameras and not (isinstance(reading, dict) and "rgb" in reading):
                    continue  # a recording that keeps its images apart (below)
                _sensor(channels, log, name, t, reading)
        images = getattr(log, "images", None)  # recordings 1.2+: each rendered image once, as PNG
        for t, name, _, data in images() if images is not None else ():
            if name in cameras:
                try:
                    with Image.open(io.BytesIO(data)) as png:
                        rgb = np.asarray(png.convert("RGB"))
                except (OSError, ValueError, Image.DecompressionBombError) as exc:
                    raise SimlogError(f"{log.path}: the image of {name!r} at t = {t:g} s: not a PNG ({exc})") from None
                _sensor(channels, log, name, t, {"time": t, "rgb": rgb})
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


def _sensor(channels: FoxgloveChannels, log: Simlog, name: str, t: float, reading: Any) -> None:
    """Log one recorded sensor reading; a reading of the wrong shape is the recording's error (one line)."""
    try:
        channels.sensor(name, t, reading)
    except (KeyError, TypeError, ValueError, IndexError, AttributeError, OverflowError) as exc:
        raise SimlogError(
            f"{log.path}: the reading of sensor {name!r} at t = {t:g} s does not fit its sensor "
            f"({type(exc).__name__}: {exc})"
        ) from None
