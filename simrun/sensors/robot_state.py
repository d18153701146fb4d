"""Bumper, wheel encoders, GPS and IMU: contacts, joint angles and the body's motion, with seeded noise."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import mujoco
import numpy as np
import numpy.typing as npt

from simrun.sensors.base import Sensor
from simrun.sensors.mount import robot_mask

if TYPE_CHECKING:  # the world imports the registry, which names this module: no import back
    from simrun.world.world import World

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class BumperReading:
    """Contact of the robot's chassis with anything not part of the robot."""

    time: float
    pressed: bool
    touching: tuple[str, ...]


class Bumper(Sensor):
    """Reports contact between a geom of the entity (default its ``chassis``) and anything not of its robot.

    The robot is every body of the bumper's top-level entity (:func:`simrun.sensors.mount.robot_mask`: wheels, a
    mounted arm, a free-base model's legs).

    Args:
        world: The world.
        entity: Full name of the entity carrying the bumper.
        geom: The bumper geom, by its name inside the entity (``ENTITY/geom``).
        rate: Samples per simulated second; 0 samples after every step.
    """

    def __init__(self, world: World, entity: str, geom: str = "chassis", rate: float = 50.0) -> None:
        super().__init__(world, entity, rate)
        self.geom = f"{entity}/{geom}"
        self._gid, self._own = -1, np.zeros(0, dtype=bool)
        self._bound: mujoco.MjModel | None = None

    def sample(self, model: mujoco.MjModel, data: mujoco.MjData) -> BumperReading:
        """Names of the geoms touching the bumper geom (excluding the robot's own)."""
        if self._bound is not model:
            self._gid = model.geom(self.geom).id
            self._own = robot_mask(model, self.entity)[model.geom_bodyid]
            self._bound = model
        touching: tuple[str, ...] = ()
        pairs = data.contact.geom  # (ncon, 2): data.contact holds the ncon active contacts
        if self._gid in pairs.ravel().tolist():  # a list's `in` is cheaper than numpy's for a few contacts
            mine = pairs[(pairs[:, 0] == self._gid) | (pairs[:, 1] == self._gid)]
            others = np.where(mine[:, 0] == self._gid, mine[:, 1], mine[:, 0])
            others = others[~self._own[others]]
            touching = tuple(sorted({model.geom(int(g)).name for g in others}))
        return BumperReading(float(data.time), bool(touching), touching)


@dataclass(frozen=True, slots=True)
class EncoderReading:
    """Wheel angles (radians) and angular velocities (rad/s)."""

    time: float
    angles: tuple[float, ...]
    velocities: tuple[float, ...]


class Encoders(Sensor):
    """Joint encoders of named joints of an entity (default the two drive wheels).

    Args:
        world: The world.
        entity: Full name of the entity.
        joints: The joints read, by their names inside the entity (``ENTITY/joint``).
        rate: Samples per simulated second; 0 samples after every step.
        noise: Standard deviation of the angle noise, rad (the speeds are exact).
        seed: Seed of the noise generator.
    """

    def __init__(
        self,
        world: World,
        entity: str,
        joints: tuple[str, ...] = ("left_wheel", "right_wheel"),
        rate: float = 50.0,
        noise: float = 0.0,
        seed: int = 0,
    ) -> None:
        super().__init__(world, entity, rate, noise, seed)
        self.joints = tuple(f"{entity}/{j}" for j in joints)
        self._qpos: list[int] = []  # qpos and dof addresses of the joints (for the bound model)
        self._qvel: list[int] = []
        self._bound: mujoco.MjModel | None = None  # the model the cached ids are for (held: a freed id is reused)

    def sample(self, model: mujoco.MjModel, data: mujoco.MjData) -> EncoderReading:
        """Angles and velocities of the joints."""
        if self._bound is not model:
            ids = [model.joint(j).id for j in self.joints]
            self._qpos, self._qvel = model.jnt_qposadr[ids].tolist(), model.jnt_dofadr[ids].tolist()
            self._bound = model
        qpos, qvel = data.qpos, data.qvel
        if self.noise:
            angles = tuple(self._noisy(qpos.take(self._qpos)).tolist())
        else:
            angles = tuple([qpos.item(i) for i in self._qpos])
        return EncoderReading(data.time, angles, tuple([qvel.item(i) for i in self._qvel]))


@dataclass(frozen=True, slots=True)
class GPSReading:
    """Position in metres (world frame), and latitude/longitude when an origin was given."""

    time: float
    position: tuple[float, float, float]
    latitude: float | None
    longitude: float | None


class GPS(Sensor):
    """Body position with noise; optional geodetic coordinates around ``origin`` (lat, lon degrees, +X east).

    Args:
        world: The world.
        entity: Full name of the entity carrying it.
        rate: Samples per simulated second; 0 samples after every step.
        noise: Standard deviation of the position noise, metres.
        seed: Seed of the noise generator.
        origin: (latitude, longitude) of the world origin, degrees; ``None``: no geodetic coordinates.
        body: The body whose origin it reports, by its full name; ``None``: the robot's root body
            (:func:`simrun.sensors.mount.root_body`), so a free-base walker's GPS follows its trunk.
    """

    EARTH_RADIUS = 6_378_137.0

    def __init__(
        self,
        world: World,
        entity: str,
        rate: float = 1.0,
        noise: float = 0.0,
        seed: int = 0,
        origin: tuple[float, float] | None = None,
        body: str | None = None,
    ) -> None:
        super().__init__(world, entity, rate, noise, seed, body)
        self.origin = origin

    def sample(self, model: mujoco.MjModel, data: mujoco.MjData) -> GPSReading:
        """Noisy position (and latitude/longitude)."""
        p = self._noisy(data.xpos[self.mounting.bind(model)].copy())
        lat = lon = None
        if self.origin is not None:
            lat0, lon0 = self.origin
            lat = lat0 + math.degrees(p[1] / self.EARTH_RADIUS)
            lon = lon0 + math.degrees(p[0] / (self.EARTH_RADIUS * math.cos(math.radians(lat0))))
        return GPSReading(float(data.time), (float(p[0]), float(p[1]), float(p[2])), lat, lon)


@dataclass(frozen=True, slots=True)
class IMUReading:
    """Body-frame angular velocity (rad/s), linear acceleration (m/s^2, with gravity) and orientation (w, x, y, z)."""

    time: float
    gyro: tuple[float, float, float]
    accelerometer: tuple[float, float, float]
    orientation: tuple[float, float, float, float]


class IMU(Sensor):
    """Gyro, accelerometer and orientation of a body: ``body`` (full name), else the robot's root body."""

    def __init__(
        self, world: World, entity: str, rate: float = 100.0, noise: float = 0.0, seed: int = 0, body: str | None = None
    ) -> None:
        super().__init__(world, entity, rate, noise, seed, body)

    def sample(self, model: mujoco.MjModel, data: mujoco.MjData) -> IMUReading:
        """Readings from the body's spatial velocity and acceleration (mj_rnePostConstraint)."""
        mujoco.mj_rnePostConstraint(model, data)
        body = data.body(self.mounting.bind(model))
        rotation = body.xmat.reshape(3, 3)
        gyro = self._noisy(rotation.T @ body.cvel[:3])
        accel = self._noisy(rotation.T @ body.cacc[3:])  # at the subtree centre of mass; at rest it reads +g up
        q = body.xquat
        return IMUReading(
            float(data.time),
            tuple(gyro.tolist()),
            tuple(accel.tolist()),
            (float(q[0]), float(q[1]), float(q[2]), float(q[3])),
        )
