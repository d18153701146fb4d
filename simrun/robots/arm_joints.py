"""Joint and segment specifications of articulated arms, and their scene-file tables.

A segment is a capsule along its local +Z attached to its parent by a joint: one degree of freedom
(:class:`ArmJoint`, a hinge or a slide) or up to six (:class:`SixDof`). :mod:`simrun.robots.arm` builds arms from these
and re-exports every name here.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields
from typing import Any

from simrun.errors import EntityError

DRIVES = ("position", "velocity", "none")
AXES = ("x", "y", "z", "rx", "ry", "rz")
_AXIS_VECTORS = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}


@dataclass(frozen=True, slots=True)
class ArmJoint:
    """One degree of freedom.

    Attributes:
        axis: Joint axis in the segment frame.
        kind: ``hinge`` (radians) or ``slide`` (metres).
        limits: (low, high) in radians or metres, or ``None`` for no limit.
        locked: Weld the segment to its parent (no joint).
        drive: ``position`` (servo with gain ``kp``), ``velocity`` (gain ``kv``) or ``none`` (passive).
        kp: Position gain, N m / rad (or N / m).
        kv: Velocity gain of a velocity servo, N m s / rad (or N s / m). A position servo's damping is
            derived (critical damping), unless ``damping_ratio`` is ``None``, when ``kv`` is used as is.
        spring: Spring stiffness towards ``spring_ref``, N m / rad (or N / m).
        spring_ref: Spring rest position.
        damping: Passive joint damping, N m s / rad (or N s / m).
        max_force: Actuator force limit, N m (or N).
        armature: Rotor inertia added to the joint, kg m^2 (or kg).
        gravity_compensation: Cancel gravity on the segment's body; ``None``: on for driven joints, off for
            passive ones (so a free joint swings as a pendulum).
        damping_ratio: Damping ratio of a position servo, 1 = critical; ``None`` uses ``kv``.
        mimic: Name of another segment whose (single) joint this one follows, ``position = mimic_ratio * that
            position`` (an equality constraint, as a gripper's second finger); it gets no actuator and is not
            commanded.
        mimic_ratio: See ``mimic``.
    """

    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    kind: str = "hinge"
    limits: tuple[float, float] | None = None
    locked: bool = False
    drive: str = "position"
    kp: float = 50.0
    kv: float = 5.0
    spring: float = 0.0
    spring_ref: float = 0.0
    damping: float = 2.0
    max_force: float = 50.0
    armature: float = 0.01
    gravity_compensation: bool | None = None
    damping_ratio: float | None = 1.0
    mimic: str | None = None
    mimic_ratio: float = 1.0


@dataclass(frozen=True, slots=True)
class SixDof:
    """A joint with up to six degrees of freedom: linear ``x``, ``y``, ``z`` and angular ``rx``, ``ry``, ``rz``.

    Each axis (in the segment frame) is locked (``None``) or an :class:`ArmJoint` (its ``axis`` and ``kind``
    are set by the axis): free (no limits) or limited, driven or passive, with a spring. MuJoCo gets one
    slide or hinge per unlocked axis, in the order above, named ``ARM/<segment>/<axis>``.
    """

    x: ArmJoint | None = None
    y: ArmJoint | None = None
    z: ArmJoint | None = None
    rx: ArmJoint | None = None
    ry: ArmJoint | None = None
    rz: ArmJoint | None = None

    def axes(self) -> list[tuple[str, ArmJoint]]:
        """The unlocked axes as (name, joint with the axis' kind and direction)."""
        result = []
        for name in AXES:
            joint = getattr(self, name)
            if joint is None or joint.locked:
                continue
            kind = "slide" if len(name) == 1 else "hinge"
            result.append((name, _replace(joint, axis=_AXIS_VECTORS[name[-1]], kind=kind)))
        return result


@dataclass(frozen=True, slots=True)
class Segment:
    """One link: a capsule of ``length`` along +Z from the end of its parent segment (+``offset``).

    Attributes:
        name: Unique in the arm, without ``/``.
        length: Metres.
        radius: Metres.
        mass: kg.
        joint: How it is attached: one degree of freedom, or a :class:`SixDof`.
        offset: Added to the attachment point, metres, in the parent segment's frame.
        parent: Name of the segment it hangs from; ``None``: the one before it (the base for the first).
    """

    name: str
    length: float
    radius: float = 0.03
    mass: float = 0.5
    joint: ArmJoint | SixDof = field(default_factory=ArmJoint)
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    parent: str | None = None

    def dofs(self, prefix: str) -> list[tuple[str, ArmJoint]]:
        """(full joint name, joint) of every unlocked degree of freedom."""
        if isinstance(self.joint, SixDof):
            return [(f"{prefix}/{self.name}/{axis}", joint) for axis, joint in self.joint.axes()]
        return [] if self.joint.locked else [(f"{prefix}/{self.name}", self.joint)]

    def to_scene(self) -> dict[str, Any]:
        """The segment as a scene-file table (defaults left out)."""
        table: dict[str, Any] = {"name": self.name, "length": self.length}
        for key, default in (("radius", 0.03), ("mass", 0.5), ("parent", None)):
            if getattr(self, key) != default:
                table[key] = getattr(self, key)
        if self.offset != (0.0, 0.0, 0.0):
            table["offset"] = list(self.offset)
        if isinstance(self.joint, SixDof):
            table["joint"] = {a: _joint_table(j) for a in AXES if (j := getattr(self.joint, a)) is not None}
        elif self.joint != ArmJoint():
            table["joint"] = _joint_table(self.joint)
        return table

    @classmethod
    def from_scene(cls, table: Any, where: str) -> Segment:
        """A segment from a scene-file table; ``where`` names it in errors."""
        if not isinstance(table, dict):
            raise EntityError(f"{where}: expected a table")
        known = {"name", "length", "radius", "mass", "joint", "offset", "parent"}
        _known_keys(table, known, where)
        if not isinstance(table.get("name"), str):
            raise EntityError(f"{where}.name: every segment needs a name string")
        values: dict[str, Any] = {"name": table["name"]}
        for key in ("length", "radius", "mass"):
            if key in table:
                values[key] = _number(table[key], f"{where}.{key}")
        if "offset" in table:
            values["offset"] = _numbers(table["offset"], 3, f"{where}.offset")
        if "parent" in table:
            if not isinstance(table["parent"], str):
                raise EntityError(f"{where}.parent: expected a segment name")
            values["parent"] = table["parent"]
        if "length" not in values:
            raise EntityError(f"{where}.length: every segment needs a length")
        joint = table.get("joint")
        if joint is not None:
            if not isinstance(joint, dict):
                raise EntityError(f"{where}.joint: expected a table")
            if set(joint) & set(AXES):
                _known_keys(joint, set(AXES), f"{where}.joint")
                axes = {a: _joint_from_table(joint[a], f"{where}.joint.{a}") for a in AXES if a in joint}
                values["joint"] = SixDof(**axes)
            else:
                values["joint"] = _joint_from_table(joint, f"{where}.joint")
        return cls(**values)


class Segments(tuple[Segment, ...]):
    """The segments of an arm (a tuple that scene files read and write as an array of tables)."""

    __slots__ = ()

    @classmethod
    def from_scene(cls, value: Any, where: str) -> Segments:
        """Segments from a scene file's array of tables."""
        if not isinstance(value, list):
            raise EntityError(f"{where}: expected an array of segment tables")
        return cls(Segment.from_scene(table, f"{where}[{k}]") for k, table in enumerate(value))

    def to_scene(self) -> list[dict[str, Any]]:
        """The scene-file array of tables."""
        return [segment.to_scene() for segment in self]


def _check_joint(joint: ArmJoint, where: str) -> None:
    if joint.drive not in DRIVES or joint.kind not in ("hinge", "slide"):
        raise EntityError(f"{where}: kind must be hinge or slide, drive one of {', '.join(DRIVES)}")
    if joint.limits is not None and not joint.limits[0] < joint.limits[1]:
        raise EntityError(f"{where}: limits must be (low, high) with low < high")
    for key in ("kp", "kv", "spring", "damping", "max_force", "armature"):
        value = getattr(joint, key)
        if not (math.isfinite(value) and value >= 0):
            raise EntityError(f"{where}: {key} must be a finite number >= 0, got {value}")
    if joint.drive == "position" and joint.kp <= 0:
        raise EntityError(f"{where}: a position servo needs kp > 0")
    if joint.damping_ratio is not None and not (math.isfinite(joint.damping_ratio) and joint.damping_ratio > 0):
        raise EntityError(f"{where}: damping_ratio must be positive")


def _replace(joint: ArmJoint, **changes: Any) -> ArmJoint:
    values = {f.name: getattr(joint, f.name) for f in fields(joint)}
    values.update(changes)
    return ArmJoint(**values)


def _joint_table(joint: ArmJoint) -> dict[str, Any]:
    default = ArmJoint()
    table = {}
    for key, value in asdict(joint).items():
        if value != getattr(default, key) and value is not None:
            table[key] = list(value) if isinstance(value, tuple) else value
    return table


def _joint_from_table(table: Any, where: str) -> ArmJoint:
    if not isinstance(table, dict):
        raise EntityError(f"{where}: expected a table")
    names = {f.name for f in fields(ArmJoint)}
    _known_keys(table, names, where)
    values: dict[str, Any] = {}
    for key, value in table.items():
        if key == "axis":
            values[key] = _numbers(value, 3, f"{where}.axis")
        elif key == "limits":
            values[key] = _numbers(value, 2, f"{where}.limits")
        elif key in ("kind", "drive", "mimic"):
            if not isinstance(value, str):
                raise EntityError(f"{where}.{key}: expected a string")
            values[key] = value
        elif key in ("locked", "gravity_compensation"):
            if not isinstance(value, bool):
                raise EntityError(f"{where}.{key}: expected true or false")
            values[key] = value
        else:
            values[key] = _number(value, f"{where}.{key}")
    joint = ArmJoint(**values)
    _check_joint(joint, where)
    return joint


def _known_keys(table: dict[str, Any], known: set[str], where: str) -> None:
    for key in table:
        if key not in known:
            raise EntityError(f"{where}.{key}: unknown key (known: {', '.join(sorted(known))})")


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise EntityError(f"{where}: expected a number, got {value!r}")
    return float(value)


def _numbers(value: Any, n: int, where: str) -> tuple[float, ...]:
    if not isinstance(value, list | tuple) or len(value) != n:
        raise EntityError(f"{where}: expected {n} numbers")
    return tuple(_number(v, f"{where}[{k}]") for k, v in enumerate(value))


def _hinge(axis: tuple[float, float, float], limit_deg: float, kp: float, force: float) -> ArmJoint:
    limit = math.radians(limit_deg)
    return ArmJoint(axis=axis, limits=(-limit, limit), kp=kp, damping=kp / 50, max_force=force)
