"""The planar laser range finder (SICK LMS style): a fan of rays cast every sample."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import mujoco
import numpy as np
import numpy.typing as npt

from simrun.errors import EntityError
from simrun.sensors.base import RayCaster, Sensor, check_exclude
from simrun.sensors.mount import robot_mask, top_of

if TYPE_CHECKING:  # the world imports the registry, which names this module: no import back
    from simrun.world.world import World

FloatArray = npt.NDArray[np.float64]


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
        entity: Entity carrying the laser.
        height: Mounting height above the mounting body's origin along its Z, metres (the scan plane is the
            body's XY plane lifted by it); ``None`` (the default): the top of that body's geometry in the
            compiled model (:func:`simrun.sensors.mount.top_of`: the chassis top of the built-in robots, 0.105 m
            on the Boe-Bot; a torso's top), so the laser sees what stands on the ground around the robot.
        fov_deg: Field of view, degrees, centred ahead.
        rays: Number of rays.
        max_range: Metres.
        rate: Hz.
        noise: Range noise standard deviation, metres.
        points: Also return hit points.
        seed: Noise seed.
        exclude: What the rays ignore (:data:`EXCLUDES`): by default every geom of the robot the laser is
            mounted on.
        body: The body it sits on and follows, by its full name (``NAME/link``); ``None``: the robot's root
            body (:func:`simrun.sensors.mount.root_body`), the body that moves.
    """

    def __init__(
        self,
        world: World,
        entity: str,
        height: float | None = None,
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
        if height is not None and not math.isfinite(height):
            raise EntityError(f"laser: height must be a finite number of metres, got {height!r}")
        check_exclude(exclude)
        super().__init__(world, entity, rate, noise, seed, body)  # registers it: checks first
        self.caster = RayCaster(self.mounting, exclude)
        #: The ``height`` given (``None``: the mounting body's top, see :attr:`height`).
        self.given_height = height
        self.max_range, self.points = max_range, points
        self._lift, self._lift_model = 0.0, None
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
        origin = data.xpos[body] + rotation[:, 2] * self.mount_height(model)
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

    @property
    def height(self) -> float:
        """Height of the scan plane above the mounting body's origin, metres: ``height``, or the body's top.

        Read from the world's model (compiled now if need be).
        """
        return self.mount_height(self.world.model)

    def mount_height(self, model: mujoco.MjModel) -> float:
        """Height of the scan plane above the mounting body's origin in ``model``, metres: ``height``, or the top."""
        if self.given_height is not None:
            return self.given_height
        if self._lift_model is not model:
            body = self.caster.bind(model)
            self._lift, self._lift_model = top_of(model, body, robot_mask(model, self.entity)), model
        return self._lift
