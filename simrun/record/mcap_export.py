"""A ``.simlog`` as MCAP with Foxglove's well-known schemas, written by the Foxglove SDK (``foxglove-sdk``).

``simrun replay X.simlog --mcap OUT.mcap`` (and ``simrun serve --record-as mcap``) replays the recording
kinematically (:func:`simrun.record.simlog.replay_states`) and writes, with log times in nanoseconds of simulated
time (``round(t * 1e9)``) and the same time in each message's ``timestamp``:

* ``/tf``: ``foxglove.FrameTransforms``, every recorded frame: one transform per body from ``world`` to the
  body (``xpos`` metres and ``xquat``, MuJoCo's body frames, Z up), so the 3D panel shows every body;
* ``/NAME/pose``: ``foxglove.PoseInFrame`` per robot (:func:`simrun.robots.contract.robots`: every robot
  entity), every frame: its root body's pose in ``world`` (ground truth);
* ``/NAME/odometry``: ``foxglove.PoseInFrame`` per drive service, at each checkpoint (every second): the
  service's odometry estimate (x, y, heading) in the frame ``NAME/odom``, which ``/tf`` places at the robot's
  pose of the first frame (the odometry origin of a run recorded from its start);
* ``/sensors/NAME``: recorded sensor readings (``--record-sensors``): a laser as ``foxglove.LaserScan`` in
  the frame of the body it is mounted on (``body``, else the robot's root; the scan origin ``height`` above
  it), a webcam as ``foxglove.RawImage`` (``rgb8``),
  any other sensor as JSON (``message_encoding`` ``json``, its reading's fields).

Messages are protobuf, with the schemas the SDK embeds, so Foxglove and any MCAP reader with protobuf
support decode them. The file is written beside the target and renamed over it when complete.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from meshtool.formats import check_suffix
from simrun.errors import SimrunError
from simrun.outfile import check_output, scene_files
from simrun.record.simlog import CHECKPOINT, Simlog, check_model, check_scene, replay_states
from simrun.run.session import prepare
from simrun.scene.scene_file import load_scene

#: Topic of every body's transform.
TF_TOPIC = "/tf"
#: The fixed frame all transforms hang from.
WORLD_FRAME = "world"


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
    from foxglove import channels as fc
    from foxglove import messages as fm

    from simrun.robots.contract import robots as robot_contracts
    from simrun.sensors.laser import LaserRangeFinder
    from simrun.services.drive_service import DriveService

    model, data = world.model, world.data
    bodies = [(b, model.body(b).name or f"body{b}") for b in range(1, model.nbody)]
    contracts = robot_contracts(world)
    robots = [(name, int(model.body(r.root).id)) for name, r in contracts.items()]
    drives = [(k, c.name) for k, c in enumerate(world.controllers) if isinstance(c, DriveService)]
    bases = {c.name: c.wheels.base for c in world.controllers if isinstance(c, DriveService)}
    counts: dict[str, int] = {}
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
        tf = fc.FrameTransformsChannel(TF_TOPIC, context=context)
        poses = {name: fc.PoseInFrameChannel(f"/{name}/pose", context=context) for name, _ in robots}
        odometry = {name: fc.PoseInFrameChannel(f"/{name}/odometry", context=context) for _, name in drives}
        sensors = _sensor_channels(world, log, context)

        def count(topic: str) -> None:
            counts[topic] = counts.get(topic, 0) + 1

        def stamp(t: float) -> Any:
            ns = _ns(t)
            return fm.Timestamp(ns // 1_000_000_000, ns % 1_000_000_000)

        def pose(position: Any, wxyz: Any) -> Any:
            w, x, y, z = (float(v) for v in wxyz)
            return fm.Pose(
                position=fm.Vector3(x=float(position[0]), y=float(position[1]), z=float(position[2])),
                orientation=fm.Quaternion(x=x, y=y, z=z, w=w),
            )

        checkpoints = {round(r.time, 9): r.controllers or [] for r in log.records() if r.kind == CHECKPOINT}
        first = True
        for t in replay_states(world, log):
            transforms = [
                fm.FrameTransform(
                    timestamp=stamp(t),
                    parent_frame_id=WORLD_FRAME,
                    child_frame_id=name,
                    translation=fm.Vector3(
                        x=float(data.xpos[b][0]), y=float(data.xpos[b][1]), z=float(data.xpos[b][2])
                    ),
                    rotation=fm.Quaternion(
                        x=float(data.xquat[b][1]),
                        y=float(data.xquat[b][2]),
                        z=float(data.xquat[b][3]),
                        w=float(data.xquat[b][0]),
                    ),
                )
                for b, name in bodies
            ]
            if first:  # the odometry frames: each robot's pose at the first frame, heading only (Z up)
                for _, name in drives:
                    b = int(model.body(bases[name]).id)
                    yaw = _yaw(data.xquat[b])
                    transforms.append(
                        fm.FrameTransform(
                            timestamp=stamp(t),
                            parent_frame_id=WORLD_FRAME,
                            child_frame_id=f"{name}/odom",
                            translation=fm.Vector3(x=float(data.xpos[b][0]), y=float(data.xpos[b][1]), z=0.0),
                            rotation=fm.Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)),
                        )
                    )
                first = False
            tf.log(fm.FrameTransforms(transforms=transforms), log_time=_ns(t))
            count(TF_TOPIC)
            for name, b in robots:
                poses[name].log(
                    fm.PoseInFrame(timestamp=stamp(t), frame_id=WORLD_FRAME, pose=pose(data.xpos[b], data.xquat[b])),
                    log_time=_ns(t),
                )
                count(f"/{name}/pose")
            snaps = checkpoints.get(round(t, 9))
            if snaps:
                for k, name in drives:
                    if k < len(snaps) and "odom" in snaps[k]:
                        _, x, y, theta, _, _ = (float(v) for v in snaps[k]["odom"])
                        half = theta / 2
                        message = fm.PoseInFrame(
                            timestamp=stamp(t),
                            frame_id=f"{name}/odom",
                            pose=fm.Pose(
                                position=fm.Vector3(x=x, y=y, z=0.0),
                                orientation=fm.Quaternion(x=0.0, y=0.0, z=math.sin(half), w=math.cos(half)),
                            ),
                        )
                        odometry[name].log(message, log_time=_ns(t))
                        count(f"/{name}/odometry")
        sampled: dict[str, float] = {}
        for frame_time, readings in log.sensor_readings():
            for name, reading in readings.items():
                if name not in sensors or reading is None:
                    continue
                # every frame repeats the latest reading: one message per sample, at the sample's time
                t = float(reading["time"]) if isinstance(reading, dict) and "time" in reading else frame_time
                if sampled.get(name) == t:
                    continue
                sampled[name] = t
                channel, kind, sensor = sensors[name]
                topic = f"/sensors/{name}"
                if kind == "laser":
                    assert isinstance(sensor, LaserRangeFinder)
                    angles = np.asarray(reading["angles"], dtype=float)
                    scan = fm.LaserScan(
                        timestamp=stamp(t),
                        frame_id=model.body(sensor.mounting.bind(model)).name,
                        pose=fm.Pose(
                            position=fm.Vector3(x=0.0, y=0.0, z=float(sensor.mount_height(model))),
                            orientation=fm.Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
                        ),
                        start_angle=float(angles[0]),
                        end_angle=float(angles[-1]),
                        ranges=[float("nan") if r is None else float(r) for r in reading["ranges"]],
                        intensities=[],
                    )
                    channel.log(scan, log_time=_ns(t))
                elif kind == "image":
                    rgb = np.asarray(reading["rgb"], dtype=np.uint8)
                    height, width = rgb.shape[:2]
                    image = fm.RawImage(
                        timestamp=stamp(t),
                        frame_id=sensor.entity,
                        width=width,
                        height=height,
                        encoding="rgb8",
                        step=width * 3,
                        data=rgb.tobytes(),
                    )
                    channel.log(image, log_time=_ns(t))
                else:
                    channel.log(json.dumps(reading, sort_keys=True), log_time=_ns(t))
                count(topic)
        writer.close()
        os.chmod(tmp, 0o644)
        os.replace(tmp, out)
        ok = True
    except OSError as exc:
        raise SimrunError(f"cannot write {out}: {exc.strerror or exc}") from None
    finally:
        if not ok:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
    return McapSummary(out, counts, out.stat().st_size)


def _yaw(wxyz: Any) -> float:
    w, x, y, z = (float(v) for v in wxyz)
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def _sensor_channels(world: Any, log: Simlog, context: Any) -> dict[str, tuple[Any, str, Any]]:
    """A channel per recorded sensor: (channel, ``laser``/``image``/``json``, the sensor)."""
    import foxglove
    from foxglove import channels as fc

    from simrun.sensors.cameras import Webcam
    from simrun.sensors.laser import LaserRangeFinder

    out: dict[str, tuple[Any, str, Any]] = {}
    for name in log.header["sensors"]:
        sensor = world.sensors.get(name)
        if sensor is None:
            raise SimrunError(f"{log.path}: header: sensors: {name!r} is not a sensor of the recorded scene")
        topic = f"/sensors/{name}"
        if isinstance(sensor, LaserRangeFinder):
            out[name] = (fc.LaserScanChannel(topic, context=context), "laser", sensor)
        elif isinstance(sensor, Webcam):
            out[name] = (fc.RawImageChannel(topic, context=context), "image", sensor)
        else:
            schema = {"type": "object", "title": type(sensor).__name__}
            out[name] = (
                foxglove.Channel(topic, schema=schema, message_encoding="json", context=context),
                "json",
                sensor,
            )
    return out
