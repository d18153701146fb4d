"""Differential-drive robots (MSRS's DifferentialDriveEntity) and ready robots with real dimensions.

The robot's body origin is on the ground between the wheels' contact points; +X is forward, +Y left.
Two driven wheels on hinge joints (``left_wheel``, ``right_wheel``, axes +Y) with motor actuators whose
torque is ``power * motor_torque_scaling`` (power in [-1, 1]); a caster sphere with frictionless contact
(condim 1) so it carries weight but never steers. Parameter names follow MSRS (docs/robots.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import mujoco

from simrun.entity import BuildContext, Entity, check_positive
from simrun.errors import EntityError

_QUAT_Y_AXIS = [math.cos(math.pi / 4), math.sin(math.pi / 4), 0.0, 0.0]  # cylinder axis Z -> Y


@dataclass(kw_only=True)
class DifferentialDrive(Entity):
    """A two-wheeled robot with a caster.

    Attributes:
        mass: Chassis mass, kg (wheels add ``wheel_mass`` each).
        chassis_dimensions: (length along X, width along Y, height), metres.
        chassis_clearance: Gap between the ground and the chassis bottom, metres.
        wheel_radius: Metres.
        wheel_width: Metres.
        wheel_mass: kg per wheel.
        axle_offset: Axle position along X from the chassis centre, metres (positive: forward).
        caster_radius: Metres; the caster sits at the rear (front when the axle is behind the centre).
        motor_torque_scaling: Wheel torque in N m at power 1 (MSRS ``MotorTorqueScaling``).
        wheel_friction: Sliding friction of the tyres.
        color: RGBA of the chassis.
        visual_mesh: Optional ``.mbin`` (an asset name or path) drawn on the chassis, massless and without
            contacts (group 2); the chassis box stays the collision shape.
        visual_offset: Position of the visual mesh on the body, metres.
    """

    TYPE: ClassVar[str] = "DifferentialDrive"

    free: bool = True
    mass: float = 0.454
    chassis_dimensions: tuple[float, float, float] = (0.13, 0.09, 0.09)
    chassis_clearance: float = 0.015
    wheel_radius: float = 0.025
    wheel_width: float = 0.008
    wheel_mass: float = 0.01
    axle_offset: float = 0.03
    caster_radius: float = 0.0125
    motor_torque_scaling: float = 0.04
    wheel_friction: float = 1.2
    color: tuple[float, float, float, float] = (0.2, 0.4, 0.8, 1.0)
    visual_mesh: str | None = None
    visual_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @property
    def track(self) -> float:
        """Distance between the wheels' mid-planes, metres."""
        return self.chassis_dimensions[1] + self.wheel_width + 0.002

    def build(self, body: Any, ctx: BuildContext) -> None:
        """Chassis, wheels with hinge joints and motors, caster."""
        length, width, height = self.chassis_dimensions
        check_positive(
            self,
            mass=self.mass,
            length=length,
            width=width,
            height=height,
            wheel_radius=self.wheel_radius,
            wheel_width=self.wheel_width,
            caster_radius=self.caster_radius,
            motor_torque_scaling=self.motor_torque_scaling,
            wheel_mass=self.wheel_mass,
        )
        if abs(self.axle_offset) >= length / 2:
            raise EntityError(f"{self.TYPE} {self.name!r}: axle_offset must lie within the chassis length")
        bottom = self.chassis_clearance
        body.add_geom(
            name=ctx.name("chassis"),
            type=mujoco.mjtGeom.mjGEOM_BOX,
            size=[length / 2, width / 2, height / 2],
            pos=[0.0, 0.0, bottom + height / 2],
            mass=self.mass,
            rgba=list(self.color),
        )
        caster_x = -math.copysign(length / 2 - self.caster_radius, self.axle_offset or 1.0)
        caster = body.add_geom(
            name=ctx.name("caster"),
            type=mujoco.mjtGeom.mjGEOM_SPHERE,
            size=[self.caster_radius, 0, 0],
            pos=[caster_x, 0.0, self.caster_radius],
            mass=0.001,
            rgba=[0.3, 0.3, 0.3, 1.0],
        )
        # frictionless: carries weight, never steers. MuJoCo takes the larger condim of a contact pair unless one
        # geom has priority, so the caster gets priority over the ground.
        caster.condim, caster.priority, caster.friction = 1, 2, [0.0, 0.0, 0.0]
        body.add_site(name=ctx.name("centre"), pos=[0.0, 0.0, bottom + height / 2])
        if self.visual_mesh:
            path = ctx.base_dir / ctx.asset_paths.get(self.visual_mesh, self.visual_mesh)
            for k, (mesh, material) in enumerate(ctx.assets.mesh(path, 1.0).visual):
                geom = body.add_geom(
                    name=ctx.name(f"visual{k}"),
                    type=mujoco.mjtGeom.mjGEOM_MESH,
                    meshname=mesh,
                    pos=list(self.visual_offset),
                )
                geom.group, geom.contype, geom.conaffinity, geom.density = 2, 0, 0, 0.0
                if material:
                    geom.material = material
        for side, sign in (("left", 1.0), ("right", -1.0)):
            wheel = body.add_body(
                name=ctx.name(f"{side}_wheel"), pos=[self.axle_offset, sign * self.track / 2, self.wheel_radius]
            )
            wheel.add_joint(
                name=ctx.name(f"{side}_wheel"), type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 1, 0], damping=0.0001
            )
            tyre = wheel.add_geom(
                name=ctx.name(f"{side}_tyre"),
                type=mujoco.mjtGeom.mjGEOM_CYLINDER,
                size=[self.wheel_radius, self.wheel_width / 2, 0],
                quat=_QUAT_Y_AXIS,
                mass=self.wheel_mass,
                rgba=[0.1, 0.1, 0.1, 1.0],
            )
            tyre.friction = [self.wheel_friction, 0.005, 0.0001]
            motor = ctx.spec.add_actuator(
                name=ctx.name(f"{side}_motor"), target=ctx.name(f"{side}_wheel"), trntype=mujoco.mjtTrn.mjTRN_JOINT
            )
            motor.gear[0] = self.motor_torque_scaling
            motor.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
            motor.ctrlrange = [-1.0, 1.0]


@dataclass(kw_only=True)
class BoeBot(DifferentialDrive):
    """Parallax Boe-Bot: 0.454 kg, chassis 0.09 x 0.09 x 0.13 m, wheels r 0.025 m, caster r 0.0125 m."""

    TYPE: ClassVar[str] = "BoeBot"


@dataclass(kw_only=True)
class Pioneer3DX(DifferentialDrive):
    """MobileRobots Pioneer 3-DX: 9 kg, 0.455 x 0.381 x 0.237 m, wheels r 0.0975 m."""

    TYPE: ClassVar[str] = "Pioneer3DX"
    mass: float = 9.0
    chassis_dimensions: tuple[float, float, float] = (0.455, 0.33, 0.16)
    chassis_clearance: float = 0.06
    wheel_radius: float = 0.0975
    wheel_width: float = 0.047
    wheel_mass: float = 0.4
    axle_offset: float = 0.05
    caster_radius: float = 0.038
    motor_torque_scaling: float = 6.0
    color: tuple[float, float, float, float] = (0.75, 0.1, 0.1, 1.0)


@dataclass(kw_only=True)
class IRobotCreate(DifferentialDrive):
    """iRobot Create: 2.2 kg, round body ~0.33 m (modelled as a box), wheels r 0.036 m, track 0.26 m."""

    TYPE: ClassVar[str] = "IRobotCreate"
    mass: float = 2.2
    chassis_dimensions: tuple[float, float, float] = (0.3, 0.23, 0.06)
    chassis_clearance: float = 0.01
    wheel_radius: float = 0.036
    wheel_width: float = 0.02
    wheel_mass: float = 0.1
    axle_offset: float = -0.001  # axle through the centre; the caster goes in front
    caster_radius: float = 0.018
    motor_torque_scaling: float = 1.0
    color: tuple[float, float, float, float] = (0.85, 0.85, 0.85, 1.0)


@dataclass(kw_only=True)
class LegoNxtTribot(DifferentialDrive):
    """LEGO Mindstorms NXT Tribot: 0.6 kg, wheels r 0.028 m, track ~0.11 m."""

    TYPE: ClassVar[str] = "LegoNxtTribot"
    mass: float = 0.6
    chassis_dimensions: tuple[float, float, float] = (0.16, 0.08, 0.1)
    chassis_clearance: float = 0.01
    wheel_radius: float = 0.028
    wheel_width: float = 0.02
    wheel_mass: float = 0.02
    axle_offset: float = 0.04
    caster_radius: float = 0.014
    motor_torque_scaling: float = 0.3
    color: tuple[float, float, float, float] = (0.9, 0.7, 0.1, 1.0)
