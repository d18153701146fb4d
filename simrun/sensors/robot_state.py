"""Bumper, wheel encoders, GPS and IMU: contacts, joint angles and the body's motion, with seeded noise."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import mujoco
import numpy as np
import numpy.typing as npt

from simrun.sensors.base import Sensor

if TYPE_CHECKING:  # the world imports the registry, which names this module: no import back
    from simrun.world.world import World

FloatArray = npt.NDArray[np.float64]

#: What a ray sensor ignores: ``robot`` every geom of the robot it is mounted on (the whole tree of bodies
#: under the top-level entity, mounted arms included), ``body`` only the mounting body's geoms, ``none``
#: nothing.


@dataclass(frozen=True, slots=True)
class BumperReading:
    """Contact of the robot's chassis with anything not part of the robot."""

    time: float
    pressed: bool
    touching: tuple[str, ...]


class Bumper(Sensor):
    """Reports contact between a geom of the entity (default its ``chassis``) and anything not of its robot.

    The robot is the whole tree of bodies under the bumper's top-level entity (wheels, a mounted arm).
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
            root = model.body_rootid[model.geom_bodyid[self._gid]]
            self._own = model.body_rootid[model.geom_bodyid] == root
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
    """Joint encoders of named joints of an entity (default the two drive wheels)."""

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
    """Body position with noise; optional geodetic coordinates around ``origin`` (lat, lon degrees, +X east)."""

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
        self._body = -1
        self._bound: mujoco.MjModel | None = None

    def sample(self, model: mujoco.MjModel, data: mujoco.MjData) -> GPSReading:
        """Noisy position (and latitude/longitude)."""
        if self._bound is not model:
            self._body, self._bound = model.body(self.mount).id, model
        p = self._noisy(data.xpos[self._body].copy())
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
    """Gyro, accelerometer and orientation of an entity's body."""

    def __init__(
        self, world: World, entity: str, rate: float = 100.0, noise: float = 0.0, seed: int = 0, body: str | None = None
    ) -> None:
        super().__init__(world, entity, rate, noise, seed, body)

    def sample(self, model: mujoco.MjModel, data: mujoco.MjData) -> IMUReading:
        """Readings from the body's spatial velocity and acceleration (mj_rnePostConstraint)."""
        mujoco.mj_rnePostConstraint(model, data)
        body = data.body(self.mount)
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
