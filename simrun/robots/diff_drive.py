"""Differential-drive robots (MSRS's DifferentialDriveEntity): a chassis, two driven wheels, casters.

Frame: the robot's body origin is on the ground at the midpoint of the drive axle (between the wheels'
contact points); +X is forward, +Y left, +Z up. A turn in place keeps the origin where it is, and odometry
(:mod:`simrun.services.drive_service`) reports this point.

Two driven wheels on hinge joints (``left_wheel``, ``right_wheel``, axes +Y) with a DC-motor actuator each
(:class:`simrun.robots.wheels.DCMotor`): torque = ``stall_torque * (power - wheel_speed / no_load_speed)``
(power in [-1, 1]), limited to the stall torque (the motor driver's current limit). At full power a wheel
without load turns at ``no_load_speed``; held still it pushes with ``stall_torque``. A caster sphere with
frictionless contact (condim 1) carries weight and never steers; a second one on the other side of the axle
is optional (the Create's rear wheel: with its weight over the axle a single caster lets it rock onto its chassis).
Parameter names follow MSRS (docs/robots.md), each ready robot
names the source of its numbers in ``SOURCES``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import mujoco

from simrun.errors import EntityError
from simrun.robots.contract import Robot
from simrun.robots.wheels import DCMotor, Wheels
from simrun.world.entity import BuildContext, Entity, check_positive

_QUAT_Y_AXIS = [math.cos(math.pi / 4), math.sin(math.pi / 4), 0.0, 0.0]  # cylinder axis Z -> Y
CHASSIS_SHAPES = ("box", "disc")


@dataclass(kw_only=True)
class DifferentialDrive(Entity, Robot):
    """A two-wheeled robot with a caster; the defaults are the seed's Boe-Bot.

    Attributes:
        mass: Chassis mass, kg (the wheels add ``wheel_mass`` each, the caster ``caster_mass``).
        chassis_dimensions: (length along X, width along Y, height), metres; for a ``disc`` chassis the
            length is the diameter and the width must equal it.
        chassis_shape: ``box`` or ``disc`` (a vertical cylinder).
        chassis_clearance: Gap between the ground and the chassis bottom, metres.
        wheel_radius: Metres.
        wheel_width: Metres.
        wheel_mass: kg per wheel.
        track: Distance between the wheels' mid-planes, metres; ``None``: the chassis width (MSRS puts the
            wheel centres on the chassis sides, at +-width/2).
        axle_offset: Axle position along X ahead of the chassis centre, metres (negative: behind it).
        caster_radius: Metres.
        caster_offset: Caster centre along X from the axle, metres (negative: behind the axle); ``None``:
            at the chassis end away from the axle, one caster radius inside.
        caster_mass: kg (each caster).
        second_caster_offset: Centre along X from the axle of a second caster on the other side of the axle,
            metres (the iRobot Create's rear wheel); ``None``: no second caster.
        second_caster_radius: Metres; ``None``: ``caster_radius``. Both casters touch the ground.
        stall_torque: Wheel torque at power 1 with the wheel held still, N m (after the gearbox).
        no_load_speed: Wheel speed at power 1 without load, rad/s (after the gearbox).
        motor_torque_scaling: MSRS's ``MotorTorqueScaling`` with its MSRS meaning: ``SetMotorTorque(p)`` asked
            for an axle speed of ``p * MotorTorqueScaling`` rad/s. When given it replaces ``no_load_speed``
            (so a scene written for MSRS drives as fast as it did there); ``None``: the published motor.
        wheel_friction: Sliding friction of the tyres.
        color: RGBA of the chassis.
        visual_mesh: Optional ``.mbin`` (an asset name or path) drawn on the chassis, massless and without
            contacts (group 2); the chassis stays the collision shape.
        visual_offset: Position of the visual mesh in the body frame, metres.
    """

    TYPE: ClassVar[str] = "DifferentialDrive"
    #: Where each number of a ready robot comes from (docs/robots.md repeats them).
    SOURCES: ClassVar[dict[str, str]] = {}

    free: bool = True
    mass: float = 0.454
    chassis_dimensions: tuple[float, float, float] = (0.13, 0.09, 0.09)
    chassis_shape: str = "box"
    chassis_clearance: float = 0.015
    wheel_radius: float = 0.025
    wheel_width: float = 0.010
    wheel_mass: float = 0.01
    track: float | None = None
    axle_offset: float = 0.02
    caster_radius: float = 0.0125
    caster_offset: float | None = -0.055
    caster_mass: float = 0.001
    second_caster_offset: float | None = None
    second_caster_radius: float | None = None
    stall_torque: float = 0.268
    no_load_speed: float = 50 * math.pi / 30
    motor_torque_scaling: float | None = None
    wheel_friction: float = 1.2
    color: tuple[float, float, float, float] = (0.2, 0.4, 0.8, 1.0)
    visual_mesh: str | None = None
    visual_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @property
    def separation(self) -> float:
        """Distance between the wheels' mid-planes (the track), metres."""
        return self.chassis_dimensions[1] if self.track is None else self.track

    @property
    def wheel_speed_limit(self) -> float:
        """Wheel speed at full power without load, rad/s (``motor_torque_scaling`` when given)."""
        return self.no_load_speed if self.motor_torque_scaling is None else self.motor_torque_scaling

    @property
    def top_speed(self) -> float:
        """Surface speed of a wheel at full power without load, m/s."""
        return self.wheel_speed_limit * self.wheel_radius

    @property
    def total_mass(self) -> float:
        """Chassis, wheels and casters, kg."""
        casters = 1 if self.second_caster_offset is None else 2
        return self.mass + 2 * self.wheel_mass + casters * self.caster_mass

    @property
    def motor(self) -> DCMotor:
        """Each wheel's DC motor (``no_load_speed``, or ``motor_torque_scaling`` when given)."""
        return DCMotor(self.stall_torque, self.wheel_speed_limit)

    def driven_wheels(self, full_name: str, model: mujoco.MjModel, base: str) -> Wheels:
        """The two wheels ``NAME/left_wheel`` and ``NAME/right_wheel``: ``wheel_radius`` and the track as given."""
        return Wheels(
            f"{full_name}/left_wheel",
            f"{full_name}/right_wheel",
            f"{full_name}/left_motor",
            f"{full_name}/right_motor",
            self.wheel_radius,
            self.separation,
            self.motor,
            base,
        )

    def casters(self) -> list[tuple[str, float, float]]:
        """(geom suffix, centre along X from the axle in metres, radius in metres) of each caster."""
        result = [("caster", self.caster_x(), self.caster_radius)]
        if self.second_caster_offset is not None:
            radius = self.caster_radius if self.second_caster_radius is None else self.second_caster_radius
            result.append(("second_caster", self.second_caster_offset, radius))
        return result

    def caster_x(self) -> float:
        """Caster centre along X in the body frame (from the axle), metres."""
        if self.caster_offset is not None:
            return self.caster_offset
        length = self.chassis_dimensions[0]
        return -self.axle_offset - math.copysign(length / 2 - self.caster_radius, self.axle_offset or 1.0)

    def validate(self) -> None:
        """Raise :class:`EntityError` for parameters that cannot make a robot."""
        length, width, height = self.chassis_dimensions
        check_positive(
            self,
            mass=self.mass,
            length=length,
            width=width,
            height=height,
            wheel_radius=self.wheel_radius,
            wheel_width=self.wheel_width,
            wheel_mass=self.wheel_mass,
            track=self.track,
            caster_radius=self.caster_radius,
            caster_mass=self.caster_mass,
            second_caster_radius=self.second_caster_radius,
            stall_torque=self.stall_torque,
            no_load_speed=self.no_load_speed,
            motor_torque_scaling=self.motor_torque_scaling,
            wheel_friction=self.wheel_friction,
        )
        where = f"{self.TYPE} {self.name!r}"
        if self.chassis_shape not in CHASSIS_SHAPES:
            raise EntityError(f"{where}: chassis_shape must be one of {', '.join(CHASSIS_SHAPES)}")
        if self.chassis_shape == "disc" and not math.isclose(length, width):
            raise EntityError(f"{where}: a disc chassis needs length == width (the diameter), got {length}, {width}")
        if not (math.isfinite(self.axle_offset) and abs(self.axle_offset) < length / 2):
            raise EntityError(f"{where}: axle_offset must lie within the chassis length (|offset| < {length / 2})")
        if not (math.isfinite(self.chassis_clearance) and self.chassis_clearance >= 0):
            raise EntityError(f"{where}: chassis_clearance must be >= 0")
        caster = self.caster_x()
        if not (math.isfinite(caster) and abs(caster) >= self.caster_radius + 1e-6):
            raise EntityError(f"{where}: caster_offset must put the caster away from the axle (|x| > radius)")
        second = self.second_caster_offset
        if second is not None and not (
            math.isfinite(second) and abs(second) >= self.casters()[1][2] + 1e-6 and second * caster < 0
        ):
            raise EntityError(
                f"{where}: second_caster_offset must put the second caster on the other side of the axle from "
                f"the first (x {caster}), farther than its radius"
            )
        if self.separation <= self.wheel_width:
            raise EntityError(f"{where}: the track must be wider than a wheel")

    def build(self, body: Any, ctx: BuildContext) -> None:
        """Chassis, wheels with hinge joints and DC motors, caster."""
        self.validate()
        length, width, height = self.chassis_dimensions
        centre = [-self.axle_offset, 0.0, self.chassis_clearance + height / 2]
        if self.chassis_shape == "disc":
            shape, size = mujoco.mjtGeom.mjGEOM_CYLINDER, [length / 2, height / 2, 0.0]
        else:
            shape, size = mujoco.mjtGeom.mjGEOM_BOX, [length / 2, width / 2, height / 2]
        body.add_geom(
            name=ctx.name("chassis"), type=shape, size=size, pos=centre, mass=self.mass, rgba=list(self.color)
        )
        for suffix, x, radius in self.casters():
            caster = body.add_geom(
                name=ctx.name(suffix),
                type=mujoco.mjtGeom.mjGEOM_SPHERE,
                size=[radius, 0, 0],
                pos=[x, 0.0, radius],
                mass=self.caster_mass,
                rgba=[0.3, 0.3, 0.3, 1.0],
            )
            # frictionless: carries weight, never steers. MuJoCo takes the larger condim of a contact pair unless
            # one geom has priority, so the caster gets priority over the ground.
            caster.condim, caster.priority, caster.friction = 1, 2, [0.0, 0.0, 0.0]
        body.add_site(name=ctx.name("centre"), pos=centre)
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
        motor = self.motor
        for side, sign in (("left", 1.0), ("right", -1.0)):
            wheel = body.add_body(
                name=ctx.name(f"{side}_wheel"), pos=[0.0, sign * self.separation / 2, self.wheel_radius]
            )
            wheel.add_joint(
                name=ctx.name(f"{side}_wheel"), type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 1, 0], damping=0.0001
            )
            # the contact shape is an ellipsoid (one contact point in the wheel's mid-plane, as a real tyre's
            # patch, where a cylinder's two rim points scrub when turning), stiff and with a near-hard friction
            # impedance so the tyre does not creep under drive torque; solmix makes it win over the ground's
            # defaults while the friction stays the larger of the two. A cylinder is drawn in its place.
            tyre = wheel.add_geom(
                name=ctx.name(f"{side}_tyre"),
                type=mujoco.mjtGeom.mjGEOM_ELLIPSOID,
                size=[self.wheel_radius, self.wheel_width / 2, self.wheel_radius],
                mass=self.wheel_mass,
                rgba=[0.1, 0.1, 0.1, 1.0],
            )
            tyre.friction = [self.wheel_friction, 0.005, 0.0001]
            tyre.solref, tyre.solimp, tyre.solmix = [0.005, 1.0], [0.99, 0.999, 0.001, 0.5, 2.0], 1000.0
            tyre.group = 3
            look = wheel.add_geom(
                name=ctx.name(f"{side}_wheel_visual"),
                type=mujoco.mjtGeom.mjGEOM_CYLINDER,
                size=[self.wheel_radius, self.wheel_width / 2, 0],
                quat=_QUAT_Y_AXIS,
                rgba=[0.1, 0.1, 0.1, 1.0],
            )
            look.group, look.contype, look.conaffinity, look.density = 2, 0, 0, 0.0
            motor.add_to(ctx.spec, ctx.name(f"{side}_motor"), ctx.name(f"{side}_wheel"))
