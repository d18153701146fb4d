"""Articulated arms (MSRS's articulated entities) and the arm service.

An arm is a chain of segments; each segment is a capsule along its local +Z, joined to the previous one by
a hinge (or, for gripper fingers, a slide) joint that is locked (no joint), free (passive), or driven by a
position or velocity servo, with an optional spring and damper. Joints are named ``ARM/<segment>``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, ClassVar

import mujoco
import numpy as np

from simrun.entity import BuildContext, Entity, check_positive
from simrun.errors import EntityError
from simrun.world import World

DRIVES = ("position", "velocity", "none")


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
        kv: Velocity gain, N m s / rad.
        spring: Spring stiffness towards ``spring_ref``.
        spring_ref: Spring rest position.
        damping: Joint damping.
        max_force: Actuator force limit.
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


@dataclass(frozen=True, slots=True)
class Segment:
    """One link: a capsule of ``length`` along +Z starting at the previous segment's end (+``offset``)."""

    name: str
    length: float
    radius: float = 0.03
    mass: float = 0.5
    joint: ArmJoint = field(default_factory=ArmJoint)
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(kw_only=True)
class ArticulatedArm(Entity):
    """A serial arm from ``segments`` (base first), with a fixed base cylinder."""

    TYPE: ClassVar[str] = "ArticulatedArm"
    segments: tuple[Segment, ...] = ()
    base_radius: float = 0.06
    base_height: float = 0.05
    base_mass: float = 1.0
    color: tuple[float, float, float, float] = (0.9, 0.5, 0.1, 1.0)

    def joint_names(self, full_name: str) -> list[str]:
        """Full names of the actuated or passive joints, base to tip."""
        return [f"{full_name}/{s.name}" for s in self.segments if not s.joint.locked]

    def build(self, body: Any, ctx: BuildContext) -> None:
        """The chain of bodies, joints and servo actuators."""
        if not self.segments:
            raise EntityError(f"{self.TYPE} {self.name!r}: no segments")
        check_positive(self, base_radius=self.base_radius, base_height=self.base_height, base_mass=self.base_mass)
        body.add_geom(
            name=ctx.name("base"),
            type=mujoco.mjtGeom.mjGEOM_CYLINDER,
            size=[self.base_radius, self.base_height / 2, 0],
            pos=[0, 0, self.base_height / 2],
            mass=self.base_mass,
            rgba=[0.3, 0.3, 0.3, 1.0],
        )
        parent, z = body, self.base_height
        names = set()
        for segment in self.segments:
            if segment.name in names or "/" in segment.name:
                raise EntityError(f"{self.TYPE} {self.name!r}: segment names must be unique, without '/'")
            names.add(segment.name)
            check_positive(self, length=segment.length, radius=segment.radius, mass=segment.mass)
            joint = segment.joint
            if joint.drive not in DRIVES or joint.kind not in ("hinge", "slide"):
                raise EntityError(f"{self.TYPE} {self.name!r}: joint of {segment.name!r} has a bad kind or drive")
            pos = [segment.offset[0], segment.offset[1], z + segment.offset[2]]
            child = parent.add_body(name=ctx.name(segment.name), pos=pos)
            child.gravcomp = 1.0  # servos hold the arm against gravity (no steady-state sag)
            child.add_geom(
                name=ctx.name(f"{segment.name}/geom"),
                type=mujoco.mjtGeom.mjGEOM_CAPSULE,
                fromto=[0, 0, 0, 0, 0, segment.length],
                size=[segment.radius, 0, 0],
                mass=segment.mass,
                rgba=list(self.color),
            )
            if not joint.locked:
                self._joint(child, segment, ctx)
            parent, z = child, segment.length

    def _joint(self, child: Any, segment: Segment, ctx: BuildContext) -> None:
        joint = segment.joint
        name = ctx.name(segment.name)
        kind = mujoco.mjtJoint.mjJNT_HINGE if joint.kind == "hinge" else mujoco.mjtJoint.mjJNT_SLIDE
        j = child.add_joint(
            name=name,
            type=kind,
            axis=list(joint.axis),
            damping=joint.damping,
            stiffness=joint.spring,
            springref=joint.spring_ref,
            armature=0.01,
        )
        if joint.limits is not None:
            j.limited = mujoco.mjtLimited.mjLIMITED_TRUE
            j.range = list(joint.limits)
        if joint.drive == "none":
            return
        act = ctx.spec.add_actuator(name=name, target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        if joint.drive == "position":
            act.set_to_position(kp=joint.kp, kv=joint.kv * 0.2)
        else:
            act.set_to_velocity(kv=joint.kv)
        act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
        act.forcerange = [-joint.max_force, joint.max_force]
        if joint.drive == "position" and joint.limits is not None:
            act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
            act.ctrlrange = list(joint.limits)


def _hinge(axis: tuple[float, float, float], limit_deg: float, kp: float, force: float) -> ArmJoint:
    limit = math.radians(limit_deg)
    return ArmJoint(axis=axis, limits=(-limit, limit), kp=kp, kv=kp / 10, damping=kp / 50, max_force=force)


@dataclass(kw_only=True)
class KukaLBR3(ArticulatedArm):
    """A KUKA LBR3-style 7-DOF arm (alternating roll and pitch axes, about 0.9 m reach)."""

    TYPE: ClassVar[str] = "KukaLBR3"
    segments: tuple[Segment, ...] = (
        Segment("link1", 0.20, 0.06, 2.0, _hinge((0, 0, 1), 170, 300, 150)),
        Segment("link2", 0.20, 0.06, 2.0, _hinge((0, 1, 0), 120, 300, 150)),
        Segment("link3", 0.20, 0.05, 1.5, _hinge((0, 0, 1), 170, 200, 100)),
        Segment("link4", 0.20, 0.05, 1.5, _hinge((0, -1, 0), 120, 200, 100)),
        Segment("link5", 0.19, 0.04, 1.0, _hinge((0, 0, 1), 170, 100, 40)),
        Segment("link6", 0.08, 0.04, 0.5, _hinge((0, 1, 0), 120, 50, 30)),
        Segment("link7", 0.05, 0.03, 0.2, _hinge((0, 0, 1), 170, 20, 20)),
    )
    base_radius: float = 0.1
    base_mass: float = 4.0


@dataclass(kw_only=True)
class LynxL6(ArticulatedArm):
    """A Lynxmotion L6-style arm: base, shoulder, elbow, wrist pitch, wrist roll and a two-finger gripper."""

    TYPE: ClassVar[str] = "LynxL6"
    segments: tuple[Segment, ...] = (
        Segment("base_rotate", 0.02, 0.03, 0.1, _hinge((0, 0, 1), 90, 5, 2)),
        Segment("shoulder", 0.12, 0.015, 0.08, _hinge((0, 1, 0), 90, 5, 2)),
        Segment("elbow", 0.12, 0.012, 0.06, _hinge((0, 1, 0), 135, 4, 1.5)),
        Segment("wrist", 0.05, 0.01, 0.03, _hinge((0, 1, 0), 90, 2, 1)),
        Segment("wrist_rotate", 0.02, 0.01, 0.02, _hinge((0, 0, 1), 90, 1, 0.5)),
        Segment(
            "finger_left",
            0.04,
            0.005,
            0.01,
            ArmJoint(axis=(0, 1, 0), kind="slide", limits=(0.0, 0.015), kp=20, kv=2, max_force=5),
            offset=(0.0, 0.01, 0.0),
        ),
    )
    base_radius: float = 0.05
    base_height: float = 0.03
    base_mass: float = 0.3
    color: tuple[float, float, float, float] = (0.1, 0.1, 0.1, 1.0)


@dataclass(frozen=True, slots=True)
class JointStates:
    """Positions (rad or m) and velocities of an arm's joints, base to tip."""

    time: float
    names: tuple[str, ...]
    positions: tuple[float, ...]
    velocities: tuple[float, ...]


class ArmService:
    """Commands for an articulated arm: joint targets now, or a smooth move over a duration.

    Args:
        world: The world.
        entity: Full name of an :class:`ArticulatedArm` entity.
        rate: Update rate of interpolated moves, Hz.
    """

    def __init__(self, world: World, entity: str, rate: float = 50.0) -> None:
        arm = world.entity(entity)
        if not isinstance(arm, ArticulatedArm):
            raise EntityError(f"{entity!r} is a {arm.TYPE}, not an articulated arm")
        self.world, self.name, self.arm = world, entity, arm
        self.joints = arm.joint_names(entity)
        self.period = 1.0 / rate
        self.next_time = world.time
        self._move: tuple[float, float, Any, Any] | None = None
        world.controllers.append(self)

    @property
    def busy(self) -> bool:
        """Whether a ``move_to`` is in progress."""
        return self._move is not None

    def joint_states(self) -> JointStates:
        """Current joint positions and velocities."""
        data = self.world.data
        return JointStates(
            float(data.time),
            tuple(self.joints),
            tuple(float(data.joint(j).qpos[0]) for j in self.joints),
            tuple(float(data.joint(j).qvel[0]) for j in self.joints),
        )

    def set_joint_targets(self, targets: list[float] | tuple[float, ...]) -> None:
        """Servo targets for every driven joint, base to tip (cancels a move)."""
        self._check(targets)
        self._move = None
        self._apply(np.asarray(targets, dtype=float))

    def move_to(self, joint_positions: list[float] | tuple[float, ...], duration: float) -> None:
        """Move smoothly (cosine profile in joint space) to ``joint_positions`` over ``duration`` seconds."""
        self._check(joint_positions)
        if duration <= 0:
            raise EntityError("move duration must be positive")
        start = np.asarray(self.joint_states().positions)
        t0 = float(self.world.data.time)
        self._move = (t0, duration, start, np.asarray(joint_positions, dtype=float))

    def tick(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Advance an interpolated move."""
        if self._move is None:
            return
        t0, duration, start, goal = self._move
        s = min(1.0, (data.time - t0) / duration)
        blend = 0.5 - 0.5 * math.cos(math.pi * s)
        self._apply(start + (goal - start) * blend, model, data)
        if s >= 1.0:
            self._move = None

    def reset(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """After ``World.reset``: no move in progress."""
        self._move = None

    def snapshot(self) -> dict[str, Any]:
        """The move in progress, as JSON-ready values (for checkpoints)."""
        move = None
        if self._move is not None:
            t0, duration, start, goal = self._move
            move = [t0, duration, [float(v) for v in start], [float(v) for v in goal]]
        return {"move": move, "next_time": self.next_time}

    def restore(self, state: dict[str, Any]) -> None:
        """Inverse of :meth:`snapshot`."""
        move = state["move"]
        self._move = (
            None if move is None else (float(move[0]), float(move[1]), np.asarray(move[2]), np.asarray(move[3]))
        )
        self.next_time = float(state["next_time"])

    def _check(self, values: Any) -> None:
        if len(values) != len(self.joints):
            raise EntityError(f"{self.name!r} has {len(self.joints)} joints, got {len(values)} values")

    def _apply(self, targets: Any, model: mujoco.MjModel | None = None, data: mujoco.MjData | None = None) -> None:
        model = model or self.world.model
        data = data or self.world.data
        for joint, target in zip(self.joints, targets, strict=True):
            actuator = model.actuator(joint).id if joint in _actuator_names(model) else None
            if actuator is not None:
                data.ctrl[actuator] = target


def _actuator_names(model: mujoco.MjModel) -> set[str]:
    return {model.actuator(k).name for k in range(model.nu)}
