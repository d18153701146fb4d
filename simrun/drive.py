"""Differential-drive robots (MSRS's DifferentialDriveEntity) and ready robots with published dimensions.

Frame: the robot's body origin is on the ground at the midpoint of the drive axle (between the wheels'
contact points); +X is forward, +Y left, +Z up. A turn in place keeps the origin where it is, and odometry
(:mod:`simrun.drive_service`) reports this point.

Two driven wheels on hinge joints (``left_wheel``, ``right_wheel``, axes +Y) with a DC-motor actuator each:
torque = ``stall_torque * (power - wheel_speed / no_load_speed)`` (power in [-1, 1]), limited to the
stall torque (the motor driver's current limit). At full power a wheel without load turns at
``no_load_speed``; held still it pushes with ``stall_torque``. A caster sphere with frictionless contact
(condim 1) carries weight and never steers; a second one on the other side of the axle is optional (the
Create's rear wheel: with its weight over the axle a single caster lets it rock onto its chassis).
Parameter names follow MSRS (docs/robots.md), each ready robot
names the source of its numbers in ``SOURCES``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import mujoco

from simrun.entity import BuildContext, Entity, check_positive
from simrun.errors import EntityError

_QUAT_Y_AXIS = [math.cos(math.pi / 4), math.sin(math.pi / 4), 0.0, 0.0]  # cylinder axis Z -> Y
CHASSIS_SHAPES = ("box", "disc")


@dataclass(kw_only=True)
class DifferentialDrive(Entity):
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
        speed = self.wheel_speed_limit
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
            motor = ctx.spec.add_actuator(
                name=ctx.name(f"{side}_motor"), target=ctx.name(f"{side}_wheel"), trntype=mujoco.mjtTrn.mjTRN_JOINT
            )
            # DC motor: torque = stall * power - (stall / no_load) * wheel speed (back EMF), an affine bias that
            # MuJoCo's implicit integrators treat as damping; the force limit is the driver's current limit
            motor.gaintype, motor.biastype = mujoco.mjtGain.mjGAIN_FIXED, mujoco.mjtBias.mjBIAS_AFFINE
            motor.gainprm[0] = self.stall_torque
            motor.biasprm[2] = -self.stall_torque / speed
            motor.ctrllimited = motor.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
            motor.ctrlrange = [-1.0, 1.0]
            motor.forcerange = [-self.stall_torque, self.stall_torque]


@dataclass(kw_only=True)
class BoeBot(DifferentialDrive):
    """Parallax Boe-Bot as the seed's MSRS entity: 0.454 kg chassis 0.13 x 0.09 x 0.09 m, wheels r 0.025 m.

    Track 0.09 m (wheel centres at +-chassis width / 2), wheels 0.010 m wide and 0.01 kg, axle 0.02 m ahead
    of the chassis centre, caster r 0.0125 m 0.055 m behind the axle, clearance 0.015 m. Motors: Parallax
    Continuous Rotation Servo #900-00008 (50 rpm, 38 oz-in = 0.268 N m at 6 V): top speed 0.131 m/s.
    """

    TYPE: ClassVar[str] = "BoeBot"
    SOURCES: ClassVar[dict[str, str]] = {
        "dimensions": "the seed's MSRS BoeBot entity (ChassisDimensions 0.09 x 0.09 x 0.13, Mass 0.454, "
        "FrontWheelRadius 0.025, FrontWheelWidth 0.010, FrontWheelMass 0.01, CasterWheelRadius 0.0125, "
        "ChassisClearance 0.015, axle 0.02 ahead of the chassis centre, caster 0.055 behind the axle)",
        "motor": "Parallax Continuous Rotation Servo #900-00008 datasheet: 0-50 rpm, torque 38 oz-in at 6 V",
        "motor_torque_scaling": "seed MotorTorqueScaling 30 (MSRS: axle speed 30 rad/s at power 1); "
        "BoeBot(motor_torque_scaling=30) reproduces it",
    }


@dataclass(kw_only=True)
class Pioneer3DX(DifferentialDrive):
    """Adept MobileRobots Pioneer 3-DX: 9 kg in all, 0.455 m long, 0.381 m wide, 0.237 m high, wheels 0.195 m.

    Wheels 0.0475 m wide on a 0.3335 m track (0.381 m over the tyres), rear caster 0.076 m, clearance
    0.06 m, 1.2 m/s top speed.
    """

    TYPE: ClassVar[str] = "Pioneer3DX"
    SOURCES: ClassVar[dict[str, str]] = {
        "dimensions": "Adept MobileRobots Pioneer 3-DX datasheet: length 455 mm, width 381 mm, height 237 mm, "
        "weight 9 kg, drive wheels 195.3 mm diameter x 47.5 mm, rear caster 76 mm, ground clearance 60 mm",
        "motor": "Adept MobileRobots P3-DX datasheet: max. speed 1.2 m/s (no-load wheel speed 1.2 / 0.0975 "
        "rad/s); stall torque 6 N m per wheel estimated as twice the torque to climb the published 25 % grade "
        "with the published 17 kg payload",
        "axle_offset": "axle 0.05 m ahead of the chassis centre: MSRS's Pioneer3DX entity, FRONT_AXLE_DEPTH_OFFSET "
        "= -0.05 ('distance of the axle from the center of robot')",
    }
    mass: float = 9.0 - 2 * 0.4 - 0.001
    chassis_dimensions: tuple[float, float, float] = (0.455, 0.276, 0.177)
    chassis_clearance: float = 0.06
    wheel_radius: float = 0.0975
    wheel_width: float = 0.0475
    wheel_mass: float = 0.4
    track: float | None = 0.381 - 0.0475
    axle_offset: float = 0.05
    caster_radius: float = 0.038
    caster_offset: float | None = None
    stall_torque: float = 6.0
    no_load_speed: float = 1.2 / 0.0975
    color: tuple[float, float, float, float] = (0.75, 0.1, 0.1, 1.0)


@dataclass(kw_only=True)
class IRobotCreate(DifferentialDrive):
    """iRobot Create: a 0.33 m disc, 2.2 kg in all, wheels r 0.036 m on a 0.258 m track, 0.5 m/s top speed.

    The axle runs through the disc's centre; a front caster (r 0.018 m, 0.13 m ahead of the axle) and the
    rear wheel that ships with the Create (r 0.015 m, 0.13 m behind it) carry the rest, so the robot stands
    level on four supports (with its weight over the axle, a front caster alone lets it rock back onto the
    chassis rim whenever the wheels pull).
    """

    TYPE: ClassVar[str] = "IRobotCreate"
    SOURCES: ClassVar[dict[str, str]] = {
        "dimensions": "iRobot Create Owner's Guide and Open Interface v2 manual: 0.33 m (13 in) round body, "
        "wheel base 258 mm, wheel diameter 72 mm, mass 2.2 kg without battery; height estimated",
        "supports": "TurtleBot's Create model (github.com/turtlebot/turtlebot, turtlebot_description/urdf/base/"
        "create.urdf.xacro): drive wheels on the axle through the centre, front_castor_joint at x +0.13 m "
        "(sphere r 0.018 m), rear_castor_joint at x -0.13 m (sphere r 0.015 m); the Create kit includes this "
        "back wheel (Tod E. Kurt, 'iRobot Create Robot Review', hackingroomba.com, 2007: 'back wheel'). "
        "simrun puts both casters on the ground",
        "motor": "Create Open Interface v2: Drive velocity -500..500 mm/s (no-load wheel speed 0.5 / 0.036 "
        "rad/s); stall torque 1.2 N m per wheel estimated (no published figure)",
    }
    mass: float = 2.2 - 2 * 0.1 - 2 * 0.001
    chassis_dimensions: tuple[float, float, float] = (0.33, 0.33, 0.06)
    chassis_shape: str = "disc"
    chassis_clearance: float = 0.012
    wheel_radius: float = 0.036
    wheel_width: float = 0.02
    wheel_mass: float = 0.1
    track: float | None = 0.258
    axle_offset: float = 0.0
    caster_radius: float = 0.018
    caster_offset: float | None = 0.13
    second_caster_offset: float | None = -0.13
    second_caster_radius: float | None = 0.015
    stall_torque: float = 1.2
    no_load_speed: float = 0.5 / 0.036
    color: tuple[float, float, float, float] = (0.85, 0.85, 0.85, 1.0)


@dataclass(kw_only=True)
class LegoNxtTribot(DifferentialDrive):
    """LEGO Mindstorms NXT TriBot (8527 build): 0.6 kg in all, 56 x 26 mm wheels on a 0.112 m track.

    NXT motors (170 rpm, 0.5 N m stall at 9 V): 0.5 m/s top speed. Rear caster wheel modelled as a ball.
    """

    TYPE: ClassVar[str] = "LegoNxtTribot"
    SOURCES: ClassVar[dict[str, str]] = {
        "dimensions": "LEGO Mindstorms NXT 8527 TriBot building instructions: wheels 56 x 26 mm on the NXT "
        "motors (track 0.112 m), brick and motors 0.6 kg; chassis box and caster position estimated from the build",
        "motor": "NXT motor measurements (Philippe Hurbain, philohome.com/nxtmotor): 170 rpm no-load and 50 N cm "
        "stall torque at 9 V",
    }
    mass: float = 0.6 - 2 * 0.02 - 0.001
    chassis_dimensions: tuple[float, float, float] = (0.16, 0.08, 0.1)
    chassis_clearance: float = 0.01
    wheel_radius: float = 0.028
    wheel_width: float = 0.026
    wheel_mass: float = 0.02
    track: float | None = 0.112
    axle_offset: float = 0.04
    caster_radius: float = 0.014
    caster_offset: float | None = None
    stall_torque: float = 0.5
    no_load_speed: float = 170 * math.pi / 30
    color: tuple[float, float, float, float] = (0.9, 0.7, 0.1, 1.0)


READY_ROBOTS: tuple[type[DifferentialDrive], ...] = (BoeBot, Pioneer3DX, IRobotCreate, LegoNxtTribot)
