"""Sensors bound to entities, evaluated at their own rate on the simulation clock, with seeded noise.

Each sensor is a world controller: after a physics step, when its next sample time has come, it computes a
reading (a plain dataclass with the simulation time) from model and data. Noise comes from a
``numpy.random.Generator`` seeded per sensor, so runs are deterministic.
"""

from __future__ import annotations

import abc
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np
import numpy.typing as npt

from simrun.errors import EntityError

if TYPE_CHECKING:  # the world imports the registry, which names this module: no import back
    from simrun.world import World

FloatArray = npt.NDArray[np.float64]

#: What a ray sensor ignores: ``robot`` every geom of the robot it is mounted on (the whole tree of bodies
#: under the top-level entity, mounted arms included), ``body`` only the mounting body's geoms, ``none``
#: nothing.
EXCLUDES = ("robot", "body", "none")


#: Most robot surfaces one ray is continued through (``RayCaster.cast``); a ray that meets more sees nothing.
MAX_CONTINUATIONS = 256
#: How far (m) a continued ray starts inside the next robot body when two bodies share the boundary it left.
NUDGE = 1e-6


class RayCaster:
    """Casts rays from one point, ignoring the geoms of the robot the sensor is mounted on.

    Args:
        entity: Full name of the mounting entity (its body).
        exclude: One of :data:`EXCLUDES`.
    """

    def __init__(self, entity: str, exclude: str = "robot") -> None:
        if exclude not in EXCLUDES:
            raise EntityError(f"exclude must be one of {', '.join(EXCLUDES)}, got {exclude!r}")
        self.entity, self.exclude = entity, exclude
        self.body = -1
        self._own = np.zeros(0, dtype=bool)
        self._bound: mujoco.MjModel | None = None  # the model the cached ids are for (held: a freed id is reused)
        self._hit = np.zeros(1, dtype=np.int32)

    def bind(self, model: mujoco.MjModel) -> int:
        """The mounting body's id (and the geoms to ignore) for ``model``."""
        if self._bound is not model:
            body = model.body(self.entity).id
            if self.exclude == "robot":
                root = model.body_rootid[body]
                own = model.body_rootid[model.geom_bodyid] == root
            elif self.exclude == "body":
                own = model.geom_bodyid == body
            else:
                own = np.zeros(model.ngeom, dtype=bool)
            self._own = np.append(own, False)
            self.body, self._bound = body, model
        return self.body

    def cast(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        origin: FloatArray,
        directions: FloatArray,
        geomid: npt.NDArray[np.int32],
        dist: FloatArray,
        cutoff: float,
    ) -> None:
        """Fill ``geomid`` and ``dist`` (-1 where nothing is hit) for unit ``directions`` (n * 3, flat).

        One ``mj_multiRay`` skips the mounting body; a ray that still hits a geom of the robot (a wheel, a
        mounted arm) is continued past it with ``mj_ray`` until it leaves the robot.
        """
        body = self.bind(model)
        n = len(geomid)
        skip = body if self.exclude != "none" else -1
        mujoco.mj_multiRay(model, data, origin, directions, None, 1, skip, geomid, dist, None, n, cutoff)
        if self.exclude != "robot":
            return
        own = self._own.take(geomid)  # the mask ends with False, which a miss (-1) indexes
        if not own.any():
            return
        for k in np.flatnonzero(own):
            direction = directions[3 * k : 3 * k + 3]
            travelled, gid = float(dist[k]), int(geomid[k])
            for _ in range(MAX_CONTINUATIONS):
                if gid < 0 or not self._own[gid] or travelled >= cutoff:
                    break
                start = origin + direction * travelled
                step = mujoco.mj_ray(model, data, start, direction, None, 1, int(model.geom_bodyid[gid]), self._hit)
                gid = int(self._hit[0]) if step >= 0 else -1
                travelled += step if step >= 0 else 0.0
                if gid >= 0 and self._own[gid] and step < NUDGE:
                    # two of the robot's bodies meet where the ray leaves one: from that boundary each one's
                    # surface is 0 away and excluding one finds the other; start inside it instead
                    travelled += NUDGE
            else:
                gid = -1  # still inside the robot after MAX_CONTINUATIONS surfaces: nothing outside is seen
            if gid < 0 or travelled > cutoff:
                geomid[k], dist[k] = -1, -1.0
            else:
                geomid[k], dist[k] = gid, travelled


class Sensor(abc.ABC):
    """Base: sampling at ``rate`` Hz (0: every step) on the simulation clock, the first sample at once.

    Args:
        world: The world.
        entity: Full name of the entity whose body carries the sensor.
        rate: Samples per simulated second; 0 samples after every step.
        noise: Standard deviation of additive Gaussian noise (sensor units).
        seed: Seed of the noise generator.
        body: The body carrying it when not the entity's own: ``ENTITY/link``, a body of the entity's model
            (an MJCF or URDF robot's link); kept as :attr:`mount`.
    """

    def __init__(
        self, world: World, entity: str, rate: float = 0.0, noise: float = 0.0, seed: int = 0, body: str | None = None
    ) -> None:
        world.entity(entity)
        if rate < 0 or noise < 0:
            raise EntityError("sensor rate and noise must be >= 0")
        if body is not None and (not isinstance(body, str) or not body.startswith(f"{entity}/")):
            raise EntityError(f"body {body!r} is not a body of {entity!r}; name one of its links as '{entity}/LINK'")
        #: Full name of the body the sensor is mounted on (the entity's own body unless ``body`` is given).
        self.mount = body if body is not None else entity
        self.world, self.entity, self.rate, self.noise, self.seed = world, entity, rate, noise, seed
        self.rng = np.random.default_rng(seed)
        self.reading: Any = None
        self.samples = 0
        self.period = 1.0 / rate if rate else 0.0
        self.next_time = world.time
        world.controllers.append(self)

    def tick(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Take a sample (the world calls this when the sensor is due)."""
        self.reading = self.sample(model, data)
        self.samples += 1

    def reseed(self, seed: int) -> None:
        """Restart the noise generator from ``seed``."""
        self.seed, self.rng = seed, np.random.default_rng(seed)

    def snapshot(self) -> dict[str, Any]:
        """Sampling clock and noise generator state (for checkpoints)."""
        return {"next_time": self.next_time, "samples": self.samples, "rng": self.rng.bit_generator.state}

    def restore(self, state: dict[str, Any]) -> None:
        """Inverse of :meth:`snapshot` (the last reading is not kept)."""
        self.next_time, self.samples = float(state["next_time"]), int(state["samples"])
        self.world.reschedule()  # next_time may have moved earlier
        self.rng.bit_generator.state = state["rng"]

    def reset(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Back to time 0: no reading, the noise generator restarted."""
        self.reading, self.samples = None, 0
        self.rng = np.random.default_rng(self.seed)

    @abc.abstractmethod
    def sample(self, model: mujoco.MjModel, data: mujoco.MjData) -> Any:
        """One reading (each sensor defines it)."""

    def _noisy(self, values: FloatArray) -> FloatArray:
        if self.noise == 0:
            return values
        noisy: FloatArray = values + self.rng.normal(0.0, self.noise, values.shape)
        return noisy


@dataclass(frozen=True, slots=True)
class LaserScan:
    """A planar scan.

    Attributes:
        time: Simulation time, s.
        angles: (n,) ray angles in the sensor frame, radians (0 ahead, counter-clockwise).
        ranges: (n,) distances, metres; ``max_range`` where nothing was hit.
        points: (n, 3) world positions of the hits (NaN for misses), when requested.
    """

    time: float
    angles: FloatArray
    ranges: FloatArray
    points: FloatArray | None


class LaserRangeFinder(Sensor):
    """A planar laser range finder, rays cast with ``mj_multiRay`` outside the physics step.

    Args:
        world: The world.
        entity: Entity carrying the laser (its body frame; the scan plane is its XY plane).
        height: Mounting height above the body origin, metres (MSRS: 0.3 m above the base).
        fov_deg: Field of view, degrees, centred ahead.
        rays: Number of rays.
        max_range: Metres.
        rate: Hz.
        noise: Range noise standard deviation, metres.
        points: Also return hit points.
        seed: Noise seed.
        exclude: What the rays ignore (:data:`EXCLUDES`): by default every geom of the robot the laser is
            mounted on.
        body: Mount on this body of the entity (``ENTITY/link``) instead of the entity's own body.
    """

    def __init__(
        self,
        world: World,
        entity: str,
        height: float = 0.3,
        fov_deg: float = 180.0,
        rays: int = 181,
        max_range: float = 8.0,
        rate: float = 10.0,
        noise: float = 0.0,
        points: bool = False,
        seed: int = 0,
        exclude: str = "robot",
        body: str | None = None,
    ) -> None:
        if rays < 1 or max_range <= 0 or not 0 < fov_deg <= 360:
            raise EntityError("laser: rays >= 1, max_range > 0, 0 < fov <= 360")
        self.caster = RayCaster(body or entity, exclude)
        super().__init__(world, entity, rate, noise, seed, body)  # registers it: checks first
        self.height, self.max_range, self.points = height, max_range, points
        span = math.radians(fov_deg)
        if fov_deg == 360:
            self.angles = np.linspace(-math.pi, math.pi, rays, endpoint=False)
        else:
            self.angles = np.linspace(-span / 2, span / 2, rays)
        self._local = np.stack([np.cos(self.angles), np.sin(self.angles), np.zeros(rays)], axis=1)
        self._geomid = np.zeros(rays, dtype=np.int32)
        self._dist = np.zeros(rays)

    def sample(self, model: mujoco.MjModel, data: mujoco.MjData) -> LaserScan:
        """Cast all rays from the mounting point in the body's heading plane."""
        body = self.caster.bind(model)
        rotation = data.xmat[body].reshape(3, 3)
        origin = data.xpos[body] + rotation[:, 2] * self.height
        directions = (self._local @ rotation.T).ravel()
        self.caster.cast(model, data, origin, directions, self._geomid, self._dist, self.max_range)
        ranges = np.where(self._geomid >= 0, self._dist, self.max_range)
        if self.noise:
            ranges = np.clip(self._noisy(ranges), 0.0, self.max_range)
        hits = None
        if self.points:
            hits = origin + directions.reshape(-1, 3) * ranges[:, None]
            hits[self._geomid < 0] = np.nan
        return LaserScan(float(data.time), self.angles, ranges, hits)


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
