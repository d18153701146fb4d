"""The catalogue robots: differential drives with published dimensions (Boe-Bot, Pioneer 3-DX, Create, TriBot).

Each names the source of its numbers in ``SOURCES``; the drive itself is :mod:`simrun.robots.diff_drive`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

from simrun.robots.diff_drive import DifferentialDrive


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
