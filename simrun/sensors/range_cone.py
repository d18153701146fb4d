"""Range cones: infrared distance and sonar sensors, the nearest hit in a cone of rays."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

from simrun.errors import EntityError
from simrun.sensors.base import RayCaster, Sensor, check_exclude

if TYPE_CHECKING:  # the world imports the registry, which names this module: no import back
    from simrun.world.world import World


@dataclass(frozen=True, slots=True)
class RangeReading:
    """Distance to the nearest object in the cone, metres (``max_range`` when nothing is seen)."""

    time: float
    distance: float
    value: float


class RangeCone(Sensor):
    """A cone of rays (IR distance sensor, sonar) returning the nearest hit, through a response curve.

    Args:
        world: The world.
        entity: Entity carrying the sensor.
        offset: Mounting point in the body frame, metres.
        direction: Viewing direction in the body frame.
        cone_deg: Full cone angle, degrees (0: a single ray).
        rays: Rays across the cone (per axis).
        min_range: Shorter distances read as ``min_range``, metres.
        max_range: Nothing within it reads ``max_range``, metres.
        response: (distance, value) pairs; ``value`` is interpolated from the distance (default: the
            distance itself).
        rate: Hz.
        noise: Distance noise, metres.
        seed: Noise seed.
        exclude: What the rays ignore (:data:`simrun.sensors.base.EXCLUDES`): by default every geom of the robot
            the sensor is mounted on.
        body: The body it sits on and follows, by its full name (``NAME/link``, a link of an MJCF or URDF
            robot); ``None``: the robot's root body (:func:`simrun.sensors.mount.root_body`). ``offset`` and
            ``direction`` are in that body's frame, and the cone turns with it.
    """

    def __init__(
        self,
        world: World,
        entity: str,
        offset: tuple[float, float, float] = (0.0, 0.0, 0.05),
        direction: tuple[float, float, float] = (1.0, 0.0, 0.0),
        cone_deg: float = 0.0,
        rays: int = 1,
        min_range: float = 0.0,
        max_range: float = 1.0,
        response: tuple[tuple[float, float], ...] | None = None,
        rate: float = 20.0,
        noise: float = 0.0,
        seed: int = 0,
        exclude: str = "robot",
        body: str | None = None,
    ) -> None:
        if max_range <= min_range or rays < 1 or cone_deg < 0:
            raise EntityError("range cone: 0 <= min_range < max_range, rays >= 1, cone >= 0")
        check_exclude(exclude)
        super().__init__(world, entity, rate, noise, seed, body)  # registers it: checks first
        self.caster = RayCaster(self.mounting, exclude)
        self.offset = np.asarray(offset, dtype=float)
        self.min_range, self.max_range, self.response = min_range, max_range, response
        forward = np.asarray(direction, dtype=float) / np.linalg.norm(direction)
        helper = np.array([0.0, 0.0, 1.0]) if abs(forward[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
        side = np.cross(helper, forward)
        side /= np.linalg.norm(side)
        up = np.cross(forward, side)
        half = math.radians(cone_deg) / 2
        offsets = np.linspace(-half, half, rays) if rays > 1 else np.zeros(1)
        dirs = [
            forward * math.cos(math.hypot(a, b))
            + (side * a + up * b) * (math.sin(math.hypot(a, b)) / (math.hypot(a, b) or 1.0))
            for a in offsets
            for b in offsets
        ]
        self._local = np.asarray(dirs)
        self._geomid = np.zeros(len(dirs), dtype=np.int32)
        self._dist = np.zeros(len(dirs))

    def sample(self, model: mujoco.MjModel, data: mujoco.MjData) -> RangeReading:
        """Nearest hit in the cone."""
        body = self.caster.bind(model)
        rotation = data.xmat[body].reshape(3, 3)
        origin = data.xpos[body] + rotation @ self.offset
        directions = (self._local @ rotation.T).ravel()
        self.caster.cast(model, data, origin, directions, self._geomid, self._dist, self.max_range)
        hit = self._dist[self._geomid >= 0]
        distance = float(hit.min()) if hit.size else self.max_range
        distance = float(
            np.clip(distance + (self.rng.normal(0, self.noise) if self.noise else 0.0), self.min_range, self.max_range)
        )
        value = distance
        if self.response:
            xs, ys = zip(*self.response, strict=True)
            value = float(np.interp(distance, xs, ys))
        return RangeReading(float(data.time), distance, value)


class IRDistance(RangeCone):
    """A Sharp-style IR distance sensor: a narrow beam, 0.1 to 0.8 m."""

    def __init__(self, world: World, entity: str, **kwargs: Any) -> None:
        kwargs.setdefault("cone_deg", 2.0)
        kwargs.setdefault("rays", 3)
        kwargs.setdefault("min_range", 0.1)
        kwargs.setdefault("max_range", 0.8)
        super().__init__(world, entity, **kwargs)


class Sonar(RangeCone):
    """An ultrasonic range finder: a 30 degree cone, 0.02 to 4 m."""

    def __init__(self, world: World, entity: str, **kwargs: Any) -> None:
        kwargs.setdefault("cone_deg", 30.0)
        kwargs.setdefault("rays", 7)
        kwargs.setdefault("min_range", 0.02)
        kwargs.setdefault("max_range", 4.0)
        super().__init__(world, entity, **kwargs)
