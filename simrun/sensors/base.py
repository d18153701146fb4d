"""The sensor base class (rates on the simulation clock, seeded noise) and the ray caster range sensors share.

Each sensor is a world controller: after a physics step, when its next sample time has come, it computes a
reading (a plain dataclass with the simulation time) from model and data. Noise comes from a
``numpy.random.Generator`` seeded per sensor, so runs are deterministic.
"""

from __future__ import annotations

import abc
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np
import numpy.typing as npt

from simrun.errors import EntityError
from simrun.sensors.mount import Mount, robot_mask

if TYPE_CHECKING:  # the world imports the registry, which names this module: no import back
    from simrun.world.world import World

FloatArray = npt.NDArray[np.float64]

#: What a ray sensor ignores: ``robot`` every geom of the robot it is mounted on, whatever body it sits on
#: (:func:`simrun.sensors.mount.robot_mask`: every body named ``TOP`` or ``TOP/...`` and the bodies below them,
#: so a free-base model's trunk and legs, wheels and mounted arms), ``body`` only the mounting body's geoms,
#: ``none`` nothing.
EXCLUDES = ("robot", "body", "none")


#: Most robot surfaces one ray is continued through (``RayCaster.cast``); a ray that meets more sees nothing.
MAX_CONTINUATIONS = 256
#: How far (m) a continued ray starts inside the next robot body when two bodies share the boundary it left.
NUDGE = 1e-6


def check_exclude(exclude: str) -> str:
    """``exclude`` when it is one of :data:`EXCLUDES`.

    Raises:
        EntityError: Another value (the message lists them).
    """
    if exclude not in EXCLUDES:
        raise EntityError(f"exclude must be one of {', '.join(EXCLUDES)}, got {exclude!r}")
    return exclude


class RayCaster:
    """Casts rays from one point, ignoring the geoms of the robot the sensor is mounted on.

    Args:
        mount: Where the sensor sits.
        exclude: One of :data:`EXCLUDES`.
    """

    def __init__(self, mount: Mount, exclude: str = "robot") -> None:
        self.mount, self.exclude = mount, check_exclude(exclude)
        self.body = -1
        self._own = np.zeros(0, dtype=bool)
        self._bound: mujoco.MjModel | None = None  # the model the cached ids are for (held: a freed id is reused)
        self._hit = np.zeros(1, dtype=np.int32)

    def bind(self, model: mujoco.MjModel) -> int:
        """The mounting body's id (and the geoms to ignore) for ``model``."""
        if self._bound is not model:
            body = self.mount.bind(model)
            if self.exclude == "robot":
                own = robot_mask(model, self.mount.entity)[model.geom_bodyid]
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
        far = dist > cutoff  # mj_multiRay's cutoff only culls bounding spheres: a geom within it is hit beyond it
        if far.any():
            geomid[far], dist[far] = -1, -1.0
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
        body: The body carrying it, by its full name (``NAME/link``: a link of an MJCF or URDF robot, a
            mounted arm's wrist); ``None``: the robot's root body, the body that moves
            (:func:`simrun.sensors.mount.root_body`). Resolved per compiled model by :attr:`mounting`
            (a :class:`~simrun.sensors.mount.Mount`).
    """

    def __init__(
        self, world: World, entity: str, rate: float = 0.0, noise: float = 0.0, seed: int = 0, body: str | None = None
    ) -> None:
        world.entity(entity)
        if rate < 0 or noise < 0:
            raise EntityError("sensor rate and noise must be >= 0")
        #: The body the sensor sits on (``mounting.bind(model)``: its id).
        self.mounting = Mount(entity, body)
        self.world, self.entity, self.rate, self.noise, self.seed = world, entity, rate, noise, seed
        self.rng = np.random.default_rng(seed)
        self.reading: Any = None
        self.samples = 0
        self.period = 1.0 / rate if rate else 0.0
        self.next_time = world.time
        world.controllers.append(self)

    @property
    def mount(self) -> str:
        """Full name of the body the sensor sits on (``body``, or the root body's once a model is bound)."""
        return self.mounting.name

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
