"""The planar laser range finder (SICK LMS style): a fan of rays cast every sample."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import mujoco
import numpy as np
import numpy.typing as npt

from simrun.errors import EntityError
from simrun.sensors.base import RayCaster, Sensor

if TYPE_CHECKING:  # the world imports the registry, which names this module: no import back
    from simrun.world.world import World

FloatArray = npt.NDArray[np.float64]

#: What a ray sensor ignores: ``robot`` every geom of the robot it is mounted on (the whole tree of bodies
#: under the top-level entity, mounted arms included), ``body`` only the mounting body's geoms, ``none``
#: nothing.


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
