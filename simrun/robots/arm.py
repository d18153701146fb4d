"""Articulated arms (MSRS's articulated entities): the arm entity, its servo design and the built-in arms.

An arm is a tree of segments; each segment is a capsule along its local +Z, attached to the end of its parent
segment (by default the one before it; the first to the arm's base) by a joint: one degree of freedom
(:class:`ArmJoint`, a hinge or a slide) or up to six (:class:`SixDof`: three linear and three angular axes,
each locked, free or limited, with its own drive and spring), as the seeds' joints. A degree of freedom is
passive (``drive="none"``) or driven by a position or velocity servo. Joints are named ``ARM/<segment>``
(``ARM/<segment>/<axis>`` for a :class:`SixDof`).

Defaults that make an arm behave: a link never collides with its parent segment or the arm's base; gravity
compensation is per joint (on for driven joints, off for passive ones, so a free joint swings) and acts as
joint torques on the arm's own joints, so whatever carries the arm (a mobile base on its wheels) carries its
full weight (:meth:`ArticulatedArm.before_step`); position servos are critically damped for the largest
inertia their joint can see (no overshoot; settling time in :func:`servo_design`).

The built-in arms :class:`KukaLBR3` and :class:`LynxL6` are here too; the service that commands an arm,
:class:`~simrun.robots.arm_service.ArmService`, lives in :mod:`simrun.robots.arm_service`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, ClassVar

import mujoco
import numpy as np

from simrun.errors import EntityError
from simrun.robots.arm_joints import (
    AXES,
    DRIVES,
    ArmJoint,
    Segment,
    Segments,
    SixDof,
    _check_joint,
    _hinge,
    _replace,
)
from simrun.robots.contract import Robot
from simrun.world.entity import BuildContext, Entity, check_positive

__all__ = [
    "AXES",
    "DRIVES",
    "ArmJoint",
    "ArticulatedArm",
    "LYNX_GRIPPER_OPENING",
    "KukaLBR3",
    "LynxL6",
    "Segment",
    "Segments",
    "SixDof",
    "servo_design",
]


@dataclass(kw_only=True)
class ArticulatedArm(Entity, Robot):
    """An arm from ``segments`` (base first), on a fixed base cylinder.

    Attributes:
        segments: The links; each hangs from its ``parent`` (default: the one before it).
        base_radius: Metres.
        base_height: Metres.
        base_mass: kg.
        color: RGBA of the links.
    """

    TYPE: ClassVar[str] = "ArticulatedArm"
    segments: Segments = field(default_factory=Segments)
    base_radius: float = 0.06
    base_height: float = 0.05
    base_mass: float = 1.0
    color: tuple[float, float, float, float] = (0.9, 0.5, 0.1, 1.0)

    def __post_init__(self) -> None:
        if not isinstance(self.segments, Segments):
            self.segments = Segments(self.segments)
        self._carry: tuple[mujoco.MjModel | None, _Carry | None] = (None, None)

    def before_step(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Make the base carry the arm's weight: cancel what gravity compensation puts on a free joint above.

        MuJoCo's body gravity compensation is an external anti-gravity force at each link's centre of mass,
        mapped through the link's Jacobian onto every degree of freedom above it. On the arm's own hinges
        and slides that is the joint torque that holds the link up; on a free joint above the arm (a mobile
        base's) it would lift the whole robot by the compensated weight, and its wheels would carry none of it.
        When the arm hangs below a free joint, this applies the compensated links' weight (``sum m_i g``
        acting at their centres of mass, as a force and a moment about the arm base body's centre of mass,
        world frame) to the arm's base body through ``data.xfrc_applied``, which maps onto the dofs above
        the arm only: the compensation stays as joint torques on the arm, the base carries the full weight.
        It uses the centres of mass of the state about to be stepped (``mj_kinematics`` of ``qpos``: a function
        of the state alone, so a run restored from a checkpoint carries exactly what the recorded run carried),
        the model's current masses, ``body_gravcomp`` and gravity. An arm welded to the world does nothing here.
        """
        cached, carry = self._carry
        if cached is not model:
            carry = _Carry.plan(model, self.name if self.parent is None else f"{self.parent}/{self.name}")
            self._carry = (model, carry)
        if carry is not None:
            mujoco.mj_kinematics(model, data)
            carry.apply(model, data)

    def joint_names(self, full_name: str) -> list[str]:
        """Full names of the commanded (actuated or passive, not mimicking) joints, base to tip."""
        return [name for s in self.segments for name, joint in s.dofs(full_name) if joint.mimic is None]

    def build(self, body: Any, ctx: BuildContext) -> None:
        """The tree of bodies, joints, servo actuators, contact exclusions and gripper couplings."""
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
        where = f"{self.TYPE} {self.name!r}"
        names = [s.name for s in self.segments]
        if len(set(names)) != len(names) or any("/" in n or not n for n in names):
            raise EntityError(f"{where}: segment names must be unique, without '/'")
        seen: set[str] = set()
        for segment, parent_name in zip(self.segments, self.parents().values(), strict=True):
            if parent_name is not None and parent_name not in seen:
                raise EntityError(
                    f"{where}: segment {segment.name!r} hangs from {parent_name!r}, not defined before it"
                )
            check_positive(self, length=segment.length, radius=segment.radius, mass=segment.mass)
            for _, joint in segment.dofs(ctx.full_name):
                _check_joint(joint, f"{where}: joint of {segment.name!r}")
            seen.add(segment.name)
        design = servo_design(self, ctx.full_name)
        built: dict[str, tuple[Any, float, float]] = {}  # name -> (body, length, gravcomp)
        for segment, parent_name in zip(self.segments, self.parents().values(), strict=True):
            parent, z, inherited = built[parent_name] if parent_name else (body, self.base_height, 1.0)
            dofs = segment.dofs(ctx.full_name)
            pos = [segment.offset[0], segment.offset[1], z + segment.offset[2]]
            child = parent.add_body(name=ctx.name(segment.name), pos=pos)
            child.gravcomp = _gravcomp([j for _, j in dofs], inherited)
            link = child.add_geom(
                name=ctx.name(f"{segment.name}/geom"),
                type=mujoco.mjtGeom.mjGEOM_CAPSULE,
                fromto=[0, 0, 0, 0, 0, segment.length],
                size=[segment.radius, 0, 0],
                mass=segment.mass,
                rgba=list(self.color),
            )
            # hard links: stiff contacts whose friction does not creep, so a gripper's hold is a hold
            link.solref, link.solimp, link.solmix = [0.005, 1.0], [0.99, 0.999, 0.001, 0.5, 2.0], 1000.0
            for name, joint in dofs:
                self._joint(child, name, joint, ctx, design)
            # a link never touches its parent or the base (MuJoCo filters parent-child contacts only between
            # moving bodies; an arm's base welded to the world would collide with the first link)
            ctx.spec.add_exclude(bodyname1=ctx.name(segment.name), bodyname2=parent.name)
            if parent.name != body.name:
                ctx.spec.add_exclude(bodyname1=ctx.name(segment.name), bodyname2=body.name)
            built[segment.name] = (child, segment.length, float(child.gravcomp))
        self._couple(ctx)

    def _couple(self, ctx: BuildContext) -> None:
        """Equality constraints of mimicking joints (a gripper's second finger); sibling fingers don't collide."""
        for segment in self.segments:
            for name, joint in segment.dofs(ctx.full_name):
                if joint.mimic is None:
                    continue
                leader = next((s for s in self.segments if s.name == joint.mimic), None)
                leading = leader.dofs(ctx.full_name) if leader is not None else []
                if len(leading) != 1:
                    raise EntityError(
                        f"{self.TYPE} {self.name!r}: {segment.name!r} mimics {joint.mimic!r}, which must be a "
                        "segment with one unlocked joint"
                    )
                eq = ctx.spec.add_equality(
                    name=f"{name}/mimic",
                    type=mujoco.mjtEq.mjEQ_JOINT,
                    objtype=mujoco.mjtObj.mjOBJ_JOINT,
                    name1=name,
                    name2=leading[0][0],
                )
                eq.data[:5] = [0.0, joint.mimic_ratio, 0.0, 0.0, 0.0]
                eq.solref, eq.solimp = [0.005, 1.0], [0.99, 0.999, 0.001, 0.5, 2.0]  # a stiff linkage
                ctx.spec.add_exclude(bodyname1=ctx.name(segment.name), bodyname2=ctx.name(joint.mimic))

    def _joint(
        self, child: Any, name: str, joint: ArmJoint, ctx: BuildContext, design: dict[str, dict[str, float]]
    ) -> None:
        kind = mujoco.mjtJoint.mjJNT_HINGE if joint.kind == "hinge" else mujoco.mjtJoint.mjJNT_SLIDE
        j = child.add_joint(
            name=name,
            type=kind,
            axis=list(joint.axis),
            damping=joint.damping,
            stiffness=joint.spring,
            springref=joint.spring_ref,
            armature=joint.armature,
        )
        if joint.limits is not None:
            j.limited = mujoco.mjtLimited.mjLIMITED_TRUE
            j.range = list(joint.limits)
        if joint.drive == "none" or joint.mimic is not None:
            return
        act = ctx.spec.add_actuator(name=name, target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        if joint.drive == "position":
            act.set_to_position(kp=joint.kp, kv=design[name]["kv"])  # critically damped (servo_design)
        else:
            act.set_to_velocity(kv=joint.kv)
        act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
        act.forcerange = [-joint.max_force, joint.max_force]
        if joint.drive == "position" and joint.limits is not None:
            act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
            act.ctrlrange = list(joint.limits)

    def parents(self) -> dict[str, str | None]:
        """Each segment's parent segment (``None``: the base)."""
        result: dict[str, str | None] = {}
        previous: str | None = None
        for segment in self.segments:
            result[segment.name] = segment.parent if segment.parent is not None else previous
            previous = segment.name
        return result


@dataclass(frozen=True, slots=True)
class _Carry:
    """The bodies of an arm below a free joint: ``base`` (body id) and its gravity-compensated ``links``."""

    base: int
    links: Any  # int array of body ids

    @staticmethod
    def plan(model: mujoco.MjModel, full_name: str) -> _Carry | None:
        """The arm's carry plan, or ``None`` when no free joint is above its base (nothing to carry)."""
        base = model.body(full_name).id
        links = [b for b in range(model.nbody) if _above(model, b, base) and model.body_gravcomp[b] != 0]
        body, free = base, False
        while body > 0 and not free:
            first, count = model.body_jntadr[body], model.body_jntnum[body]
            free = any(model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE for j in range(first, first + count))
            body = model.body_parentid[body]
        return _Carry(base, np.asarray(links, dtype=int)) if free and links else None

    def apply(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Set the base body's applied wrench to the compensated links' weight (see ``before_step``)."""
        weights = model.body_mass[self.links] * model.body_gravcomp[self.links]
        total = float(weights.sum())
        gravity = model.opt.gravity
        centre = weights @ data.xipos[self.links] / total if total else data.xipos[self.base]
        wrench = data.xfrc_applied[self.base]
        wrench[:3] = total * gravity
        wrench[3:] = total * np.cross(centre - data.xipos[self.base], gravity)


def _above(model: mujoco.MjModel, body: int, ancestor: int) -> bool:
    """Whether ``ancestor`` is ``body`` or one of its parents."""
    while body > 0:
        if body == ancestor:
            return True
        body = int(model.body_parentid[body])
    return ancestor == 0


#: Most segments of one arm. The servo design sums, for each joint, over every segment below it (a chain of
#: ``n`` segments: ``n^2 / 2`` terms); MuJoCo arms have tens of segments.
MAX_ARM_SEGMENTS = 1000


def servo_design(arm: ArticulatedArm, full_name: str) -> dict[str, dict[str, float]]:
    """The design of each position servo of an arm, by full joint name.

    Each entry: ``kp``, ``kv`` (N m s / rad or N s / m), ``inertia`` (the largest the joint can see, kg m^2 or
    kg), ``damping_ratio``, ``natural_frequency`` (rad/s) and ``settling_time`` (s, to 2 %).

    The inertia bound comes from the segments' geometry: the joint's armature plus, for its segment and every
    segment below it, the capsule's inertia about its centre (as a cylinder of length + 2 radius) plus its
    mass times the square of the farthest its centre can be from the joint (the chain stretched out). With
    ``kv = 2 zeta sqrt(kp I) - damping`` the servo is at least as damped as asked in every pose.

    The segments below each segment are listed in one pass up the tree from every segment, and the sums are
    added in the segments' order: the work is the number of (segment, segment below it) pairs.

    Raises:
        EntityError: The arm has more than :data:`MAX_ARM_SEGMENTS` segments.
    """
    segments = list(arm.segments)
    if len(segments) > MAX_ARM_SEGMENTS:
        raise EntityError(
            f"{arm.TYPE} {arm.name!r}: {len(segments)} segments, more than {MAX_ARM_SEGMENTS} "
            "(an arm's servo design grows with the square of its segments; split it into several arms)"
        )
    parents = arm.parents()
    length: dict[str, float] = {}
    for segment in segments:
        length.setdefault(segment.name, segment.length)  # the first of a name, as a search would find
    reach: dict[str, float] = {}  # distance from a segment's origin to the arm base, along the chain
    for segment in segments:
        parent = parents[segment.name]
        reach[segment.name] = (reach[parent] + length[parent] if parent else 0.0) + float(
            np.linalg.norm(segment.offset)
        )
    below = _below(segments, parents)
    # per link, the terms that do not depend on the joint (the same expressions, so the same floats)
    masses = [link.mass for link in segments]
    owns = []
    for link in segments:
        span = link.length + 2 * link.radius
        owns.append(link.mass * (2 * (3 * link.radius**2 + span**2) / 12 + link.radius**2 / 2))
    centres = [reach[link.name] for link in segments]
    halves = [link.length / 2 for link in segments]
    result: dict[str, dict[str, float]] = {}
    for k, segment in enumerate(segments):
        links = below[k]
        origin = reach[segment.name]
        for name, joint in segment.dofs(full_name):
            if joint.drive != "position" or joint.mimic is not None:
                continue
            inertia = joint.armature
            if joint.kind == "slide":
                for i in links:
                    inertia += masses[i]
            else:
                for i in links:
                    distance = centres[i] - origin + halves[i]
                    inertia += owns[i] + masses[i] * distance**2
            kp, zeta = joint.kp, joint.damping_ratio
            if zeta is None:
                kv = joint.kv
                zeta = (kv + joint.damping) / (2 * math.sqrt(kp * inertia))
            else:
                kv = max(0.0, 2 * zeta * math.sqrt(kp * inertia) - joint.damping)
            wn = math.sqrt(kp / inertia)
            result[name] = {
                "kp": kp,
                "kv": kv,
                "inertia": inertia,
                "damping_ratio": zeta,
                "natural_frequency": wn,
                "settling_time": _settling_time(zeta, wn),
            }
    return result


def _below(segments: list[Segment], parents: dict[str, str | None]) -> list[list[int]]:
    """For each segment, the indices of itself and every segment below it, in the segments' order.

    Each segment is added to the lists of its ancestors, found by walking up its parents once (at most one
    step per segment, so parents that form a cycle cannot loop).
    """
    named: dict[str, list[int]] = {}
    for k, segment in enumerate(segments):
        named.setdefault(segment.name, []).append(k)
    below: list[list[int]] = [[] for _ in segments]
    for k, segment in enumerate(segments):
        current: str | None = segment.name
        for _ in range(len(segments) + 1):
            if current is None:
                break
            for j in named.get(current, ()):
                below[j].append(k)
            current = parents.get(current)
    return below


def _settling_time(zeta: float, wn: float) -> float:
    """2 % settling time of a second-order step response, s."""
    if zeta < 1.0:
        return 4.0 / (zeta * wn)
    if zeta == 1.0:
        return 5.83 / wn
    slow = wn * (zeta - math.sqrt(zeta * zeta - 1.0))
    return 4.0 / slow


def _gravcomp(dofs: list[ArmJoint], inherited: float) -> float:
    """Gravity compensation of a segment's body: explicit, else on when every degree of freedom is driven."""
    if not dofs:
        return inherited  # a locked segment is carried like its parent
    explicit = [j.gravity_compensation for j in dofs if j.gravity_compensation is not None]
    if explicit:
        return 1.0 if all(explicit) else 0.0
    return 1.0 if all(j.drive != "none" and j.mimic is None for j in dofs) or any(j.mimic for j in dofs) else 0.0


@dataclass(kw_only=True)
class KukaLBR3(ArticulatedArm):
    """A KUKA LBR3-style 7-DOF arm (alternating roll and pitch axes, about 0.9 m reach)."""

    TYPE: ClassVar[str] = "KukaLBR3"
    segments: Segments = field(
        default_factory=lambda: Segments(
            (
                Segment("link1", 0.20, 0.06, 2.0, _hinge((0, 0, 1), 170, 300, 150)),
                Segment("link2", 0.20, 0.06, 2.0, _hinge((0, 1, 0), 120, 300, 150)),
                Segment("link3", 0.20, 0.05, 1.5, _hinge((0, 0, 1), 170, 200, 100)),
                Segment("link4", 0.20, 0.05, 1.5, _hinge((0, -1, 0), 120, 200, 100)),
                Segment("link5", 0.19, 0.04, 1.0, _hinge((0, 0, 1), 170, 100, 40)),
                Segment("link6", 0.08, 0.04, 0.5, _hinge((0, 1, 0), 120, 50, 30)),
                Segment("link7", 0.05, 0.03, 0.2, _hinge((0, 0, 1), 170, 20, 20)),
            )
        )
    )
    base_radius: float = 0.1
    base_mass: float = 4.0


#: Lynx gripper opening between the fingers' inner faces, fully open, metres: Lynxmotion's "Little Grip"
#: (LG-NS), the gripper of the L6 and AL5 arms, opens to 1.25 in (31.75 mm); a 3 cm object has 0.9 mm a side.
LYNX_GRIPPER_OPENING = 1.25 * 0.0254
_FINGER_RADIUS, _FINGER_ROOT = 0.004, 0.004  # capsule radius; each finger's axis sits this far off the middle
#: Lynx gripper fingers: each slides 0 (closed, touching in the middle) to its share of the full opening.
_FINGER = ArmJoint(
    axis=(0, 1, 0),
    kind="slide",
    limits=(0.0, LYNX_GRIPPER_OPENING / 2 + _FINGER_RADIUS - _FINGER_ROOT),
    kp=300,
    damping=1.0,
    max_force=5,
    armature=0.001,
)


@dataclass(kw_only=True)
class LynxL6(ArticulatedArm):
    """A Lynxmotion L6-style arm: base, shoulder, elbow, wrist pitch, wrist roll and a two-finger gripper.

    The gripper's fingers hang from the wrist roll on opposite sides and open symmetrically: one servo drives
    ``finger_left`` (its target is the opening of each finger, 0 to 0.015875 m: 31.75 mm between the fingers,
    :data:`LYNX_GRIPPER_OPENING`), ``finger_right`` mirrors it.
    """

    TYPE: ClassVar[str] = "LynxL6"
    segments: Segments = field(
        default_factory=lambda: Segments(
            (
                Segment("base_rotate", 0.02, 0.03, 0.1, _hinge((0, 0, 1), 90, 5, 2)),
                Segment("shoulder", 0.12, 0.015, 0.08, _hinge((0, 1, 0), 90, 5, 2)),
                Segment("elbow", 0.12, 0.012, 0.06, _hinge((0, 1, 0), 135, 4, 1.5)),
                Segment("wrist", 0.05, 0.01, 0.03, _hinge((0, 1, 0), 90, 2, 1)),
                Segment("wrist_rotate", 0.02, 0.01, 0.02, _hinge((0, 0, 1), 90, 1, 0.5)),
                Segment("finger_left", 0.04, _FINGER_RADIUS, 0.01, _FINGER, offset=(0.0, _FINGER_ROOT, 0.0)),
                Segment(
                    "finger_right",
                    0.04,
                    _FINGER_RADIUS,
                    0.01,
                    _replace(_FINGER, axis=(0, -1, 0), mimic="finger_left"),
                    offset=(0.0, -_FINGER_ROOT, 0.0),
                    parent="wrist_rotate",
                ),
            )
        )
    )
    base_radius: float = 0.05
    base_height: float = 0.03
    base_mass: float = 0.3
    color: tuple[float, float, float, float] = (0.1, 0.1, 0.1, 1.0)
