"""The robot contract: what every robot entity has, read from the world's compiled model.

Every robot entity (the differential drives and the catalogue robots, the arms, ``MjcfRobot``, ``UrdfRobot``)
is a :class:`Robot`, and :func:`is_robot` is the one test of "is this a robot" that the drive service,
teleoperation (``simrun view``), ``simrun play``'s summary, recordings, MCAP channels and the dashboard use.
:func:`describe` says what a robot has, as a :class:`RobotDescription`:

* its **bodies** (full names, model order): every body named ``NAME`` or ``NAME/...`` that no other entity
  owns (a child entity ``NAME/cam`` owns its own bodies);
* its **root** (the body that moves with the robot) and how it moves: ``free`` (a free joint), ``kinematic``
  (a mocap body), ``slides`` (two or more slide joints, as ``root_slides``) or ``fixed``. The root is the
  entity's own body when that moves or is a child entity; else the first top-level body of its model that
  carries a free joint or two or more slides (an MJCF model with a free base is attached in the world, its
  entity's body a marker at the spawn point); else the entity's own body (a welded arm);
* its **actuated joints** (the joints of its bodies that an actuator drives, model order), **wheels**
  (:class:`~simrun.robots.wheels.Wheels`, or ``None``: it does not drive), **cameras** and **sites**.

A robot is **mobile** when its root moves (anything but ``fixed``): ``simrun play`` reports the distance its
root travelled, and MCAP recordings carry ``/NAME/pose`` (the root's pose) for every robot.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

import mujoco

from simrun.errors import EntityError
from simrun.sensors.mount import root_body as mount_root_body

if TYPE_CHECKING:  # the world imports the registry, which names the robot modules: no import back
    from simrun.robots.wheels import Wheels
    from simrun.world.world import World

RootKind = Literal["free", "kinematic", "slides", "fixed"]
_FREE, _SLIDE = int(mujoco.mjtJoint.mjJNT_FREE), int(mujoco.mjtJoint.mjJNT_SLIDE)


class Robot:
    """The base every robot entity implements (a mixin beside :class:`~simrun.world.entity.Entity`).

    Subclasses that drive override :meth:`driven_wheels`; everything else a robot has is read from the model.
    """

    def driven_wheels(self, full_name: str, model: mujoco.MjModel, base: str) -> Wheels | None:
        """The robot's driven wheels in the world's compiled ``model``, or ``None`` (the default: it does not drive).

        Args:
            full_name: The entity's full name.
            model: The world's compiled model.
            base: The robot's root body (full name), which odometry follows.
        """
        return None


@dataclass(frozen=True, slots=True)
class RobotDescription:
    """What a robot has (full names in the world's model).

    Attributes:
        name: The entity's full name.
        type: The entity's scene type (``BoeBot``, ``MjcfRobot``...).
        bodies: Its bodies, model order.
        root: The body that moves with the robot.
        root_kind: ``free``, ``kinematic``, ``slides`` or ``fixed`` (see the module).
        joints: Its actuated joints, model order.
        wheels: Its driven wheels, or ``None``.
        cameras: Its cameras, model order.
        sites: Its sites, model order.
    """

    name: str
    type: str
    bodies: tuple[str, ...]
    root: str
    root_kind: RootKind
    joints: tuple[str, ...]
    wheels: Wheels | None
    cameras: tuple[str, ...]
    sites: tuple[str, ...]

    @property
    def mobile(self) -> bool:
        """Whether the root moves (free, kinematic or on slides)."""
        return self.root_kind != "fixed"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (the dashboard's catalogue): every field; wheels as joints, radius and track (m)."""
        wheels = self.wheels
        return {
            "name": self.name,
            "type": self.type,
            "bodies": list(self.bodies),
            "root": self.root,
            "root_kind": self.root_kind,
            "mobile": self.mobile,
            "joints": list(self.joints),
            "wheels": None
            if wheels is None
            else {"joints": [wheels.left, wheels.right], "radius": wheels.radius, "track": wheels.track},
            "cameras": list(self.cameras),
            "sites": list(self.sites),
        }


def is_robot(entity: object) -> bool:
    """Whether an entity is a robot (implements :class:`Robot`)."""
    return isinstance(entity, Robot)


def robots(world: World) -> dict[str, RobotDescription]:
    """Every robot of the world by full name, in insertion order (compiles the world)."""
    return {name: describe(world, name) for name, entity in world if is_robot(entity)}


def describe(world: World, name: str) -> RobotDescription:
    """What the robot ``name`` has, from the world's compiled model (see the module).

    Raises:
        EntityError: No such entity, or it is not a robot.
    """
    entity = world.entity(name)
    if not isinstance(entity, Robot):
        raise EntityError(f"{name!r} is a {getattr(entity, 'TYPE', type(entity).__name__)}, not a robot", entity=name)
    model = world.model
    others = [other for other, _ in world if other != name and other.startswith(f"{name}/")]

    def owned(element: str) -> bool:
        return (element == name or element.startswith(f"{name}/")) and not any(
            element == o or element.startswith(f"{o}/") for o in others
        )

    bodies = [b for b in range(model.nbody) if owned(model.body(b).name)]
    body_set = set(bodies)
    root = root_body(model, name)
    first, count = int(model.body_jntadr[root]), int(model.body_jntnum[root])
    types = [int(t) for t in model.jnt_type[first : first + count]]
    kind: RootKind = "fixed"
    if _FREE in types:
        kind = "free"
    elif int(model.body_mocapid[root]) >= 0:
        kind = "kinematic"
    elif types.count(_SLIDE) >= 2:
        kind = "slides"
    actuated = {
        int(model.actuator_trnid[a, 0])
        for a in range(model.nu)
        if int(model.actuator_trntype[a]) == int(mujoco.mjtTrn.mjTRN_JOINT)
    }
    joints = [j for j in sorted(actuated) if int(model.jnt_bodyid[j]) in body_set and model.joint(j).name]
    root_name = model.body(root).name
    return RobotDescription(
        name=name,
        type=entity.TYPE if hasattr(entity, "TYPE") else type(entity).__name__,
        bodies=tuple(model.body(b).name for b in bodies),
        root=root_name,
        root_kind=kind,
        joints=tuple(model.joint(j).name for j in joints),
        wheels=entity.driven_wheels(name, model, root_name),
        cameras=_named(model, mujoco.mjtObj.mjOBJ_CAMERA, model.ncam, model.cam_bodyid, body_set, owned),
        sites=_named(model, mujoco.mjtObj.mjOBJ_SITE, model.nsite, model.site_bodyid, body_set, owned),
    )


def drive_wheels(world: World, name: str) -> Wheels:
    """The wheels a drive of ``name`` turns.

    Raises:
        EntityError: No such entity, not a robot, or a robot without wheels (the message says how to name them).
    """
    entity = world.entity(name)
    kind = getattr(entity, "TYPE", type(entity).__name__)
    if not isinstance(entity, Robot):
        raise EntityError(f"{name!r} is a {kind}, not a differential-drive robot (a robot with wheels)", entity=name)
    model = world.model
    wheels = entity.driven_wheels(name, model, model.body(root_body(model, name)).name)
    if wheels is None:
        how = (
            'name its two wheel joints in the entity: wheels = ["left", "right"]'
            if dataclass_has(entity, "wheels")
            else "only a robot with wheels drives (DifferentialDrive, the catalogue robots, or an MjcfRobot or "
            'UrdfRobot with wheels = ["left", "right"])'
        )
        raise EntityError(f"{kind} {name!r} has no wheels; {how}", entity=name, key="wheels")
    return wheels


def dataclass_has(entity: object, field: str) -> bool:
    """Whether the entity's dataclass declares ``field`` (a scene key)."""
    return field in getattr(entity, "__dataclass_fields__", {})


def root_body(model: mujoco.MjModel, name: str) -> int:
    """The id of the body that moves with the entity ``name`` (the rule in the module).

    The one rule, kept where sensors mount by default (:func:`simrun.sensors.mount.root_body`), so a sensor
    without ``body`` sits on the body the contract calls the robot's root.

    Raises:
        EntityError: The entity has no body in the model.
    """
    return mount_root_body(model, name)


def _named(model: mujoco.MjModel, kind: Any, count: int, body_of: Any, bodies: set[int], owned: Any) -> tuple[str, ...]:
    """Names of the elements of one kind on the robot's bodies or named under it, model order."""
    out: Iterable[str] = (mujoco.mj_id2name(model, kind, k) or "" for k in range(count) if int(body_of[k]) in bodies)
    found = [n for n in out if n]
    named = [mujoco.mj_id2name(model, kind, k) or "" for k in range(count)]
    found += [n for n in named if n and owned(n) and n not in found]
    order = {n: k for k, n in enumerate(named)}
    return tuple(sorted(found, key=lambda n: order[n]))
