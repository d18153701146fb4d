"""The tables of the one registry: every entity, service and sensor type a scene file may name.

Each :class:`SceneType` names its class by ``module:Class``, imported on first use (:meth:`SceneType.load`),
so this module imports no other simrun module and the modules it names may import :mod:`simrun.world.world`
freely: there is no cycle. Services and sensors are world controllers: both implement :class:`Controller`, the
protocol the world's stepping loop, checkpoints (``.simlog``) and ``save_scene(state="current")`` rely on.
What a type's keys are is :mod:`simrun.world.registry.key_schema`; how a table becomes its constructor's
arguments is :mod:`simrun.world.registry.conversion`.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any, Literal, Protocol, runtime_checkable

from simrun.errors import EntityError

Group = Literal["entities", "services", "sensors"]
GROUPS: tuple[Group, ...] = ("entities", "services", "sensors")


@runtime_checkable
class Controller(Protocol):
    """What a service or sensor is to the world: ticked on the simulation clock, checkpointed, reset.

    Attributes:
        next_time: Simulated time of the next tick, seconds (the world advances it by ``period``).
        period: Seconds between ticks; 0 ticks before every step.
    """

    next_time: float
    period: float

    def tick(self, model: Any, data: Any) -> None:
        """Act or sample (``model``/``data``: the world's ``MjModel``/``MjData``); controls hold until the next tick."""

    def reset(self, model: Any, data: Any) -> None:
        """Back to the state after construction (``World.reset``)."""

    def snapshot(self) -> dict[str, Any]:
        """Everything needed to continue bit for bit (JSON-ready): checkpoints and ``save_scene(state="current")``."""

    def restore(self, state: dict[str, Any]) -> None:
        """Inverse of :meth:`snapshot`."""


@dataclass(frozen=True, slots=True)
class SceneType:
    """One scene type.

    Attributes:
        name: The ``type`` value in a scene file (``Box``, ``DriveService``, ``GPS``).
        group: ``entities``, ``services`` or ``sensors``.
        target: ``module:Class``.
        summary: One line for the documentation.
        binds: Services and sensors: the key naming what it is attached to (``entity``, ``camera``, ``rig``).
    """

    name: str
    group: Group
    target: str
    summary: str
    binds: str = "entity"

    def load(self) -> Any:
        """The class (imported now)."""
        module, name = self.target.split(":")
        return getattr(importlib.import_module(module), name)


def _types(group: Group, rows: list[tuple[str, str, str]], **extra: Any) -> list[SceneType]:
    return [SceneType(name, group, target, summary, **extra) for name, target, summary in rows]


_ENTITIES = _types(
    "entities",
    [
        ("Box", "simrun.entities.shapes:Box", "A box of `dimensions` (m)."),
        ("Sphere", "simrun.entities.shapes:Sphere", "A sphere of `radius` (m)."),
        ("Capsule", "simrun.entities.shapes:Capsule", "A capsule of `radius` and cylinder `length` (m) along Z."),
        ("Cylinder", "simrun.entities.shapes:Cylinder", "A cylinder of `radius` and `length` (m) along Z."),
        (
            "MeshEntity",
            "simrun.entities.mesh_entity:MeshEntity",
            "A meshtool `.mbin` asset: visual mesh and collision hulls.",
        ),
        (
            "UrdfRobot",
            "simrun.robots.urdf_robot:UrdfRobot",
            "A robot imported from a URDF file (meshes through meshtool).",
        ),
        ("MjcfRobot", "simrun.robots.mjcf_robot:MjcfRobot", "Any MJCF model, attached through MjSpec under `NAME/`."),
        ("Ground", "simrun.entities.environment:Ground", "An infinite plane, optionally textured."),
        ("HeightField", "simrun.entities.environment:HeightField", "Terrain from a grey-scale image or numbers."),
        ("Sky", "simrun.entities.environment:Sky", "A sky box (colour gradient or image)."),
        ("Light", "simrun.entities.environment:Light", "A directional, spot or point light."),
        ("Camera", "simrun.entities.environment:Camera", "A named camera (`main = true`: the default view)."),
        ("StereoRig", "simrun.sensors.cameras:StereoRig", "Two cameras `NAME/left` and `NAME/right` a baseline apart."),
        ("ArticulatedArm", "simrun.robots.arm:ArticulatedArm", "An arm of segments and joints with position servos."),
        ("KukaLBR3", "simrun.robots.arm:KukaLBR3", "KUKA LBR3: seven revolute joints, published link lengths."),
        ("LynxL6", "simrun.robots.arm:LynxL6", "Lynx 6: five joints and a two-finger gripper."),
    ],
)
_ROBOTS = _types(
    "entities",
    [
        (
            "DifferentialDrive",
            "simrun.robots.diff_drive:DifferentialDrive",
            "A two-wheeled robot of given dimensions and motors.",
        ),
        ("BoeBot", "simrun.robots.catalogue:BoeBot", "Parallax Boe-Bot (published dimensions and servo speed)."),
        ("Pioneer3DX", "simrun.robots.catalogue:Pioneer3DX", "Adept MobileRobots Pioneer 3-DX."),
        ("IRobotCreate", "simrun.robots.catalogue:IRobotCreate", "iRobot Create."),
        ("LegoNxtTribot", "simrun.robots.catalogue:LegoNxtTribot", "LEGO Mindstorms NXT TriBot."),
    ],
)
_SERVICES = _types(
    "services",
    [
        (
            "DriveService",
            "simrun.services.drive_service:DriveService",
            "Wheel speed control, odometry, drive/rotate commands.",
        ),
        ("ArmService", "simrun.robots.arm_service:ArmService", "Joint targets, trajectories and gripper of an arm."),
        (
            "JointService",
            "simrun.services.joint_service:JointService",
            "Targets, trajectories, state of any model's joints.",
        ),
    ],
)
_SENSORS = _types(
    "sensors",
    [
        ("LaserRangeFinder", "simrun.sensors.laser:LaserRangeFinder", "A planar laser scan (SICK LMS style)."),
        ("Bumper", "simrun.sensors.robot_state:Bumper", "Contact of a geom (default `chassis`) with anything else."),
        ("Encoders", "simrun.sensors.robot_state:Encoders", "Angles and speeds of the named joints."),
        ("GPS", "simrun.sensors.robot_state:GPS", "World position (with noise)."),
        ("IMU", "simrun.sensors.robot_state:IMU", "Angular velocity, linear acceleration and orientation."),
        ("IRDistance", "simrun.sensors.range_cone:IRDistance", "A narrow infrared range cone (short range)."),
        ("Sonar", "simrun.sensors.range_cone:Sonar", "A wide sonar range cone."),
    ],
)
_CAMERAS = [
    SceneType(
        "Webcam", "sensors", "simrun.sensors.cameras:Webcam", "RGB (and depth) images of a named camera.", "camera"
    ),
    SceneType("StereoCamera", "sensors", "simrun.sensors.cameras:StereoCamera", "Both images of a `StereoRig`.", "rig"),
]

#: Every scene type by name (names are unique across groups), in documentation order.
REGISTRY: dict[str, SceneType] = {t.name: t for t in (*_ENTITIES, *_ROBOTS, *_SERVICES, *_SENSORS, *_CAMERAS)}


def names(group: Group) -> tuple[str, ...]:
    """The type names of one group, in registry order."""
    return tuple(name for name, t in REGISTRY.items() if t.group == group)


def scene_type(group: Group, name: Any) -> SceneType:
    """The registered type ``name`` of ``group``.

    Raises:
        EntityError: Not a type of that group (the message lists the known ones).
    """
    found = REGISTRY.get(name) if isinstance(name, str) else None
    if found is None or found.group != group:
        singular = {"entities": "entity", "services": "service", "sensors": "sensor"}[group]
        raise EntityError(f"unknown {singular} type {name!r} (known: {', '.join(names(group))})")
    return found


def load(group: Group, name: Any) -> Any:
    """The class of a registered type (see :func:`scene_type`)."""
    return scene_type(group, name).load()
