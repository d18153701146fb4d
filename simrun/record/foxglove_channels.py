"""The world's state as Foxglove messages: one set of channels for the live stream and for MCAP alike.

:class:`FoxgloveChannels` makes, in one ``foxglove.Context``, every channel a world has, and turns the world's
state into messages of Foxglove's well-known schemas (protobuf, the schemas foxglove-sdk embeds). The live
server (:mod:`simrun.serve.foxglove_live`, its session MCAP included) and the ``.simlog`` to MCAP export
(:mod:`simrun.record.mcap_export`) both log through it, so topics, schemas and frames agree. Topics:

========================  ===========================  ===========================================================
topic                     schema                       what, when
========================  ===========================  ===========================================================
``/clock``                ``simrun.Clock`` (JSON)      the simulation time (``{"sec", "nsec"}``), every frame
``/tf``                   ``foxglove.FrameTransforms`` every body's pose from ``world`` (``xpos`` m, ``xquat``),
                                                       every frame
``/tf_static``            ``foxglove.FrameTransforms`` with drives: each drive's ``NAME/odom`` frame (its root's
                                                       pose when made: the start; heading only), with ``/scene``
``/scene``                ``foxglove.SceneUpdate``     one entity per body (frame = body), its geoms as cubes,
                                                       spheres and cylinders; the first frame, then every
                                                       :data:`SCENE_PERIOD` simulated seconds (late clients)
``/NAME/pose``            ``foxglove.PoseInFrame``     each robot's root body in ``world`` (ground truth),
                                                       every frame (:func:`simrun.robots.contract.robots`)
``/NAME/joint_states``    ``foxglove.JointStates``     each robot with actuated joints: position (rad or m) and
                                                       velocity (rad/s or m/s), every frame
``/NAME/odometry``        ``foxglove.PoseInFrame``     each drive service's estimate (x, y, heading) in
                                                       ``NAME/odom``, when the caller gives one
``/sensors/NAME``         per sensor kind              a laser: ``foxglove.LaserScan`` (frame: its body, origin
                                                       ``height`` above it); a webcam: ``foxglove.RawImage``
                                                       (``rgb8``) and, at ``/sensors/NAME/compressed``,
                                                       ``foxglove.CompressedImage`` (JPEG, quality
                                                       :data:`JPEG_QUALITY`); an IMU:
                                                       ``simrun.Imu`` (JSON); any other: JSON of its reading
========================  ===========================  ===========================================================

Foxglove has no well-known schema for a clock or an IMU, so those are JSON with a JSON schema. Log times and
every ``timestamp`` are nanoseconds of simulated time (``round(t * 1e9)``). Given the same states and
readings in the same order, the messages are the same bytes (nothing reads the wall clock).
"""

from __future__ import annotations

import dataclasses
import io
import json
import math
from collections.abc import Iterable
from typing import Any

import mujoco
import numpy as np

#: Topic of every body's transform.
TF_TOPIC = "/tf"
#: Topic of the drives' odometry frames (fixed in ``world``).
TF_STATIC_TOPIC = "/tf_static"
#: Topic of the simulation clock.
CLOCK_TOPIC = "/clock"
#: Topic of the scene's entities.
SCENE_TOPIC = "/scene"
#: The fixed frame all transforms hang from.
WORLD_FRAME = "world"
#: Simulated seconds between repeats of the scene entities.
SCENE_PERIOD = 1.0
#: JPEG quality of camera images.
JPEG_QUALITY = 80

CLOCK_SCHEMA: dict[str, Any] = {
    "title": "simrun.Clock",
    "type": "object",
    "properties": {"sec": {"type": "integer"}, "nsec": {"type": "integer"}},
}
IMU_SCHEMA: dict[str, Any] = {
    "title": "simrun.Imu",
    "type": "object",
    "description": "Body-frame angular velocity (rad/s), linear acceleration (m/s^2, with gravity), orientation "
    "(w, x, y, z) in world",
    "properties": {
        "timestamp": {"type": "object", "properties": {"sec": {"type": "integer"}, "nsec": {"type": "integer"}}},
        "frame_id": {"type": "string"},
        "gyro": {"type": "array", "items": {"type": "number"}},
        "accelerometer": {"type": "array", "items": {"type": "number"}},
        "orientation": {"type": "array", "items": {"type": "number"}},
    },
}


def ns(t: float) -> int:
    """Simulated seconds as integer nanoseconds (the log time)."""
    return round(t * 1e9)


def plain(value: Any) -> Any:
    """A reading (dataclass, dict, NumPy array, tuple) as JSON-ready values."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        return plain(value.tolist())
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, (np.floating, np.integer, np.bool_)):
        return value.item()
    return value


def _get(reading: Any, key: str) -> Any:
    return reading[key] if isinstance(reading, dict) else getattr(reading, key)


def encode_jpeg(rgb: Any, quality: int = JPEG_QUALITY) -> bytes:
    """An RGB image (H, W, 3) u8 as JPEG bytes."""
    from PIL import Image

    buffer = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(np.asarray(rgb, dtype=np.uint8))).save(buffer, format="JPEG", quality=quality)
    return buffer.getvalue()


class FoxgloveChannels:
    """Every Foxglove channel of a world, in ``context`` (see the module for topics and schemas).

    Args:
        world: The world (compiled; its state is read by :meth:`frame`, in the caller's thread).
        context: The ``foxglove.Context`` whose sinks (WebSocket server, MCAP writer) get the messages.
        sensors: Names of the sensors that get a channel (``None``: every sensor of the world).

    Attributes:
        topics: Schema name by topic, in creation order.
        counts: Messages logged by topic.
    """

    def __init__(self, world: Any, context: Any, sensors: Iterable[str] | None = None) -> None:
        self.world = world
        self._context = context
        self._only = None if sensors is None else tuple(sensors)
        self.topics: dict[str, str] = {}
        self.counts: dict[str, int] = {}
        self._channels: dict[str, Any] = {}
        #: The drive services (entity name -> root body id), whose odometry :meth:`odometry` logs.
        self.drives: dict[str, int] = {}
        self._odom: dict[str, tuple[float, float, float]] = {}
        self._scene_ids: set[str] = set()
        self._shape: tuple[Any, ...] = ()
        self.refresh()

    def refresh(self) -> tuple[list[str], list[str]]:
        """Follow the world after an edit: channels for what is new, none for what is gone, frames by name.

        Called by the live server after an edit (:mod:`simrun.serve.foxglove_live`) and cheap when nothing
        changed (the model, the services and the sensors are compared by identity and name). A topic that
        stays keeps its channel (a client's subscription goes on); a new robot, drive or sensor gets its
        channels (advertised to connected clients); a removed one's channels are closed (unadvertised); the
        body tables are rebuilt by name for the new model, and the next :meth:`frame` sends ``/scene`` again
        (with deletions of the bodies gone). A drive's ``NAME/odom`` origin is kept; a new drive's is its root
        now. With the ``sensors`` the channels were made for, only those of them the world still has.

        Returns:
            (topics added, topics removed), in creation order / sorted.
        """
        import foxglove
        from foxglove import channels as fc

        from simrun.robots.contract import robots
        from simrun.sensors.cameras import Webcam
        from simrun.sensors.laser import LaserRangeFinder
        from simrun.sensors.robot_state import IMU
        from simrun.services.drive_service import DriveService

        world, context = self.world, self._context
        model = world.model
        shape = (
            id(model),
            tuple(id(c) for c in world.controllers),
            tuple((n, id(v)) for n, v in world.sensors.items()),
        )
        if shape == self._shape:
            return [], []
        self._shape = shape
        self._bodies = [(b, model.body(b).name or f"body{b}") for b in range(1, model.nbody)]
        wanted: dict[str, tuple[str, Any]] = {}  # topic -> (schema name, a function making its channel)

        def want(topic: str, schema: str, make: Any) -> None:
            wanted[topic] = (schema, make)

        def json_channel(schema: dict[str, Any]) -> Any:
            return lambda topic: foxglove.Channel(topic, schema=schema, message_encoding="json", context=context)

        def typed(cls: Any) -> Any:
            return lambda topic: cls(topic, context=context)

        want(CLOCK_TOPIC, "simrun.Clock", json_channel(CLOCK_SCHEMA))
        want(TF_TOPIC, "foxglove.FrameTransforms", typed(fc.FrameTransformsChannel))
        want(SCENE_TOPIC, "foxglove.SceneUpdate", typed(fc.SceneUpdateChannel))
        self._robots: list[tuple[str, int, list[int]]] = []
        for name, robot in robots(world).items():
            joints = [int(model.joint(j).id) for j in robot.joints]
            self._robots.append((name, int(model.body(robot.root).id), joints))
            want(f"/{name}/pose", "foxglove.PoseInFrame", typed(fc.PoseInFrameChannel))
            if joints:
                want(f"/{name}/joint_states", "foxglove.JointStates", typed(fc.JointStatesChannel))
        self.drives = {}
        for controller in world.controllers:
            if isinstance(controller, DriveService):
                self.drives[controller.name] = int(model.body(controller.wheels.base).id)
                want(f"/{controller.name}/odometry", "foxglove.PoseInFrame", typed(fc.PoseInFrameChannel))
        self._sensors: dict[str, tuple[str, Any]] = {}
        names = world.sensors if self._only is None else [n for n in self._only if n in world.sensors]
        for name in names:
            sensor = world.sensors[name]
            topic = f"/sensors/{name}"
            if isinstance(sensor, LaserRangeFinder):
                self._sensors[name] = ("laser", sensor)
                want(topic, "foxglove.LaserScan", typed(fc.LaserScanChannel))
            elif isinstance(sensor, Webcam):
                self._sensors[name] = ("image", sensor)
                want(topic, "foxglove.RawImage", typed(fc.RawImageChannel))
                want(f"{topic}/compressed", "foxglove.CompressedImage", typed(fc.CompressedImageChannel))
            elif isinstance(sensor, IMU):
                self._sensors[name] = ("imu", sensor)
                want(topic, "simrun.Imu", json_channel(IMU_SCHEMA))
            else:
                title = type(sensor).__name__
                self._sensors[name] = ("json", sensor)
                want(topic, title, json_channel({"type": "object", "title": title}))
        if self.drives:
            want(TF_STATIC_TOPIC, "foxglove.FrameTransforms", typed(fc.FrameTransformsChannel))
        removed = sorted(t for t in self.topics if wanted.get(t, ("",))[0] != self.topics[t])
        for topic in removed:
            self._channels.pop(topic).close()
            del self.topics[topic]
        added = [t for t in wanted if t not in self.topics]
        for topic in added:
            schema, make = wanted[topic]
            self._channels[topic] = make(topic)
            self.topics[topic] = schema
        data = world.data  # the odometry origins: each drive's root when first seen (x, y, heading)
        self._odom = {
            n: self._odom.get(n) or (float(data.xpos[b][0]), float(data.xpos[b][1]), _yaw(data.xquat[b]))
            for n, b in self.drives.items()
        }
        self._next_scene = -math.inf
        return added, removed

    def _log(self, topic: str, message: Any, t: float) -> None:
        self._channels[topic].log(message, log_time=ns(t))
        self.counts[topic] = self.counts.get(topic, 0) + 1

    def frame(self) -> list[str]:
        """Log the world's current state at its time: clock, transforms, scene (when due), poses, joints.

        Returns:
            The topics logged.
        """
        from foxglove import messages as fm

        model, data = self.world.model, self.world.data
        t = float(data.time)
        stamp = _stamp(t)
        logged = [CLOCK_TOPIC, TF_TOPIC]
        self._log(CLOCK_TOPIC, json.dumps({"sec": ns(t) // 1_000_000_000, "nsec": ns(t) % 1_000_000_000}), t)
        transforms = [
            fm.FrameTransform(
                timestamp=stamp,
                parent_frame_id=WORLD_FRAME,
                child_frame_id=name,
                translation=_vector(data.xpos[b]),
                rotation=_quaternion(data.xquat[b]),
            )
            for b, name in self._bodies
        ]
        self._log(TF_TOPIC, fm.FrameTransforms(transforms=transforms), t)
        if t + 0.5 * model.opt.timestep >= self._next_scene:
            self._log(SCENE_TOPIC, self._scene(stamp), t)
            logged.append(SCENE_TOPIC)
            if self.drives:
                self._log(TF_STATIC_TOPIC, self._odom_frames(stamp), t)
                logged.append(TF_STATIC_TOPIC)
            self._next_scene = t + SCENE_PERIOD
        for name, root, joints in self._robots:
            pose = fm.Pose(position=_vector(data.xpos[root]), orientation=_quaternion(data.xquat[root]))
            self._log(f"/{name}/pose", fm.PoseInFrame(timestamp=stamp, frame_id=WORLD_FRAME, pose=pose), t)
            logged.append(f"/{name}/pose")
            if joints:
                states = [
                    fm.JointState(
                        name=model.joint(j).name,
                        position=float(data.qpos[model.jnt_qposadr[j]]),
                        velocity=float(data.qvel[model.jnt_dofadr[j]]),
                    )
                    for j in joints
                ]
                self._log(f"/{name}/joint_states", fm.JointStates(timestamp=stamp, joints=states), t)
                logged.append(f"/{name}/joint_states")
        return logged

    def _odom_frames(self, stamp: Any) -> Any:
        """Each drive's ``NAME/odom`` frame: its root's pose when the channels were made, heading only (Z up)."""
        from foxglove import messages as fm

        return fm.FrameTransforms(
            transforms=[
                fm.FrameTransform(
                    timestamp=stamp,
                    parent_frame_id=WORLD_FRAME,
                    child_frame_id=f"{name}/odom",
                    translation=fm.Vector3(x=x, y=y, z=0.0),
                    rotation=fm.Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)),
                )
                for name, (x, y, yaw) in self._odom.items()
            ]
        )

    def odometry(self, name: str, t: float, odom: Iterable[float]) -> None:
        """Log drive ``name``'s odometry ``(time, x, y, theta, ...)`` (m, rad) at ``t``, in frame ``NAME/odom``."""
        from foxglove import messages as fm

        _, x, y, theta = (float(v) for v in list(odom)[:4])
        half = theta / 2
        message = fm.PoseInFrame(
            timestamp=_stamp(t),
            frame_id=f"{name}/odom",
            pose=fm.Pose(
                position=fm.Vector3(x=x, y=y, z=0.0),
                orientation=fm.Quaternion(x=0.0, y=0.0, z=math.sin(half), w=math.cos(half)),
            ),
        )
        self._log(f"/{name}/odometry", message, t)

    def sensor(self, name: str, t: float, reading: Any) -> list[str]:
        """Log sensor ``name``'s ``reading`` (its dataclass, or the recorded dict) taken at ``t``.

        Returns:
            The topics logged (none when the sensor has no channel or there is no reading).
        """
        from foxglove import messages as fm

        if name not in self._sensors or reading is None:
            return []
        kind, sensor = self._sensors[name]
        topic = f"/sensors/{name}"
        stamp = _stamp(t)
        model = self.world.model
        message: Any
        if kind == "laser":
            angles = [float(a) for a in _get(reading, "angles")]
            message = fm.LaserScan(
                timestamp=stamp,
                frame_id=model.body(sensor.mounting.bind(model)).name,
                pose=fm.Pose(
                    position=fm.Vector3(x=0.0, y=0.0, z=float(sensor.mount_height(model))),
                    orientation=fm.Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
                ),
                start_angle=angles[0],
                end_angle=angles[-1],
                ranges=[float("nan") if r is None else float(r) for r in _get(reading, "ranges")],
                intensities=[],
            )
        elif kind == "image":
            rgb = np.asarray(_get(reading, "rgb"), dtype=np.uint8)
            height, width = rgb.shape[:2]
            frame = sensor.mount or WORLD_FRAME
            raw = fm.RawImage(timestamp=stamp, frame_id=frame, width=width, height=height, encoding="rgb8",
                              step=width * 3, data=rgb.tobytes())  # fmt: skip
            self._log(topic, raw, t)
            jpeg = fm.CompressedImage(timestamp=stamp, frame_id=frame, data=encode_jpeg(rgb), format="jpeg")
            self._log(f"{topic}/compressed", jpeg, t)
            return [topic, f"{topic}/compressed"]
        elif kind == "imu":
            values = plain(reading)
            message = json.dumps(
                {
                    "timestamp": {"sec": ns(t) // 1_000_000_000, "nsec": ns(t) % 1_000_000_000},
                    "frame_id": model.body(sensor.mounting.bind(model)).name,
                    "gyro": values["gyro"],
                    "accelerometer": values["accelerometer"],
                    "orientation": values["orientation"],
                },
                sort_keys=True,
            )
        else:
            message = json.dumps(plain(reading), sort_keys=True)
        self._log(topic, message, t)
        return [topic]

    def _scene(self, stamp: Any) -> Any:
        """One ``SceneEntity`` per body with geoms (frame: the body), its geoms as primitives (a mesh: its box)."""
        from foxglove import messages as fm

        model = self.world.model
        by_body: dict[int, list[int]] = {}
        for g in range(model.ngeom):
            if int(model.geom_group[g]) < 3:  # groups 3+ are collision-only or hidden by convention
                by_body.setdefault(int(model.geom_bodyid[g]), []).append(g)
        entities = []
        for b in sorted(by_body):
            cubes, spheres, cylinders = [], [], []
            for g in by_body[b]:
                kind, size, rgba = int(model.geom_type[g]), model.geom_size[g], model.geom_rgba[g]
                color = fm.Color(r=float(rgba[0]), g=float(rgba[1]), b=float(rgba[2]), a=float(rgba[3]))
                pose = fm.Pose(position=_vector(model.geom_pos[g]), orientation=_quaternion(model.geom_quat[g]))
                if kind == mujoco.mjtGeom.mjGEOM_SPHERE:
                    d = 2 * float(size[0])
                    spheres.append(fm.SpherePrimitive(pose=pose, size=fm.Vector3(x=d, y=d, z=d), color=color))
                elif kind == mujoco.mjtGeom.mjGEOM_ELLIPSOID:
                    spheres.append(fm.SpherePrimitive(pose=pose, size=_vector(2 * size), color=color))
                elif kind in (mujoco.mjtGeom.mjGEOM_CYLINDER, mujoco.mjtGeom.mjGEOM_CAPSULE):
                    d, h = 2 * float(size[0]), 2 * float(size[1])
                    if kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
                        h += d
                    cylinders.append(
                        fm.CylinderPrimitive(
                            pose=pose, size=fm.Vector3(x=d, y=d, z=h), bottom_scale=1.0, top_scale=1.0, color=color
                        )
                    )
                elif kind == mujoco.mjtGeom.mjGEOM_BOX:
                    cubes.append(fm.CubePrimitive(pose=pose, size=_vector(2 * size), color=color))
                elif kind == mujoco.mjtGeom.mjGEOM_PLANE:
                    x = 2 * float(size[0]) or 20.0
                    y = 2 * float(size[1]) or 20.0
                    cubes.append(fm.CubePrimitive(pose=pose, size=fm.Vector3(x=x, y=y, z=0.001), color=color))
                elif kind == mujoco.mjtGeom.mjGEOM_MESH:  # its bounding box, centred where MuJoCo puts it
                    centre, half = model.geom_aabb[g][:3], model.geom_aabb[g][3:]
                    rotation = np.zeros(9)
                    mujoco.mju_quat2Mat(rotation, model.geom_quat[g])
                    box_pose = fm.Pose(
                        position=_vector(model.geom_pos[g] + rotation.reshape(3, 3) @ centre),
                        orientation=_quaternion(model.geom_quat[g]),
                    )
                    cubes.append(fm.CubePrimitive(pose=box_pose, size=_vector(2 * half), color=color))
            name = model.body(b).name or (WORLD_FRAME if b == 0 else f"body{b}")
            entities.append(
                fm.SceneEntity(
                    timestamp=stamp,
                    frame_id=WORLD_FRAME if b == 0 else name,
                    id=name,
                    frame_locked=True,
                    cubes=cubes,
                    spheres=spheres,
                    cylinders=cylinders,
                )
            )
        ids = {model.body(b).name or (WORLD_FRAME if b == 0 else f"body{b}") for b in by_body}
        gone = sorted(self._scene_ids - ids)  # bodies an edit removed: deleted from the scene by id
        self._scene_ids = ids
        deletions = [
            fm.SceneEntityDeletion(timestamp=stamp, type=fm.SceneEntityDeletionType.MatchingId, id=i) for i in gone
        ]
        return fm.SceneUpdate(deletions=deletions, entities=entities)


def _stamp(t: float) -> Any:
    from foxglove import messages as fm

    n = ns(t)
    return fm.Timestamp(n // 1_000_000_000, n % 1_000_000_000)


def _vector(v: Any) -> Any:
    from foxglove import messages as fm

    return fm.Vector3(x=float(v[0]), y=float(v[1]), z=float(v[2]))


def _quaternion(wxyz: Any) -> Any:
    from foxglove import messages as fm

    w, x, y, z = (float(v) for v in wxyz)
    return fm.Quaternion(x=x, y=y, z=z, w=w)


def _yaw(wxyz: Any) -> float:
    w, x, y, z = (float(v) for v in wxyz)
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
