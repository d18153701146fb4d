"""The laser's batched cast (``mj_multiRay``) against MuJoCo's own ``mj_ray``, ray by ray (issue 41 item 4)."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from simrun import Box, Ground, Pose, World
from simrun.robots.catalogue import BoeBot
from simrun.sensors.laser import LaserRangeFinder

MAX_RANGE = 1.5
HEIGHT = 0.05


def _world() -> World:
    """A Boe-Bot with three boxes around it: within 1.5 m some rays hit a box, the rest see nothing (misses)."""
    world = World()
    world.insert(Ground(name="ground"))
    world.insert(BoeBot(name="bot", pose=Pose((0.0, 0.0, 0.001), (math.cos(0.2), 0.0, 0.0, math.sin(0.2)))))
    for k, (x, y) in enumerate([(0.8, 0.0), (0.0, -1.1), (-0.6, 0.7)]):
        world.insert(Box(name=f"box{k}", dimensions=(0.3, 0.4, 0.3), pose=Pose((x, y, 0.15))))
    world.compile()
    world.step(50)
    return world


def _truth(world: World, laser: LaserRangeFinder) -> tuple[np.ndarray, np.ndarray]:
    """Ranges and geom ids from one ``mj_ray`` per ray (the mounting body skipped), directions computed here."""
    model, data = world.model, world.data
    body = model.body("bot").id
    rotation = data.xmat[body].reshape(3, 3)
    origin = data.xpos[body] + rotation[:, 2] * HEIGHT
    ranges, ids = np.empty(len(laser.angles)), np.empty(len(laser.angles), dtype=np.int32)
    hit = np.zeros(1, dtype=np.int32)
    for k, angle in enumerate(laser.angles):
        direction = rotation @ np.array([math.cos(angle), math.sin(angle), 0.0])
        dist = mujoco.mj_ray(model, data, origin, direction, None, 1, body, hit)
        ids[k] = hit[0] if 0 <= dist <= MAX_RANGE else -1
        ranges[k] = dist if ids[k] >= 0 else MAX_RANGE
    return ranges, ids


def test_the_batched_cast_equals_mj_ray_for_every_ray_bit_for_bit() -> None:
    world = _world()
    laser = LaserRangeFinder(world, "bot", height=HEIGHT, fov_deg=360, rays=360, max_range=MAX_RANGE, exclude="body")
    model, data = world.model, world.data
    body = laser.caster.bind(model)
    rotation = data.xmat[body].reshape(3, 3)
    origin = data.xpos[body] + rotation[:, 2] * HEIGHT
    directions = (laser._local @ rotation.T).ravel()
    geomid, dist = np.zeros(360, dtype=np.int32), np.zeros(360)
    laser.caster.cast(model, data, origin, directions, geomid, dist, MAX_RANGE)
    hit = np.zeros(1, dtype=np.int32)
    for k in range(360):
        expected = mujoco.mj_ray(model, data, origin, directions[3 * k : 3 * k + 3], None, 1, body, hit)
        expected_id = int(hit[0]) if 0 <= expected <= MAX_RANGE else -1
        assert int(geomid[k]) == expected_id, k
        if expected_id >= 0:
            assert dist[k].tobytes() == np.float64(expected).tobytes(), k


@pytest.mark.parametrize("exclude", ["body", "robot"])
def test_the_scan_equals_one_mj_ray_per_ray_with_hits_and_misses(exclude: str) -> None:
    world = _world()
    laser = LaserRangeFinder(world, "bot", height=HEIGHT, fov_deg=360, rays=360, max_range=MAX_RANGE, exclude=exclude)
    truth, ids = _truth(world, laser)  # the state the laser samples: its tick comes before the step's physics
    world.step()
    scan = laser.reading
    assert 0 < int((ids < 0).sum()) < 360  # both hits and misses
    model = world.model
    robot = {model.body(n).id for n in range(model.nbody) if model.body(n).name.startswith("bot")}
    # "robot" continues through the robot's own geoms (its wheels): compare the rays whose first hit is not one
    seen = np.array([exclude == "body" or i < 0 or int(model.geom_bodyid[i]) not in robot for i in ids])
    assert seen.sum() > 300
    np.testing.assert_array_equal((scan.ranges == MAX_RANGE)[seen], (ids < 0)[seen])
    np.testing.assert_allclose(scan.ranges[seen], truth[seen], rtol=0, atol=1e-12)


def test_the_noise_stream_is_the_seeded_generator_on_the_exact_ranges() -> None:
    world = _world()
    laser = LaserRangeFinder(
        world, "bot", height=HEIGHT, fov_deg=360, rays=360, max_range=MAX_RANGE, noise=0.02, seed=7, exclude="body"
    )
    truth, _ = _truth(world, laser)
    world.step()
    expected = np.clip(truth + np.random.default_rng(7).normal(0.0, 0.02, 360), 0.0, MAX_RANGE)
    np.testing.assert_allclose(laser.reading.ranges, expected, rtol=0, atol=1e-12)
    assert not np.array_equal(laser.reading.ranges, truth)
