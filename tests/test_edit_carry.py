"""simrun.world.edit_carry: a rebuilt service or sensor takes its old one's place, state and noise stream.

Ground truth: the objects' own snapshots and readings before and after, and a sensor built fresh from a scene
that names the same seed (its noise generator's state).
"""

from __future__ import annotations

import pytest
from test_edit_apply import SENSORS, _two_robots

from simrun.run.session import prepare
from simrun.scene.scene_file import load_scene
from simrun.world.edit_bindings import change_sensor
from simrun.world.edit_carry import rebuild_service


def test_a_changed_sensor_keeps_its_place_its_clock_its_last_reading_and_its_noise_stream():
    world = _two_robots()
    old = world.sensors["view_cam"]
    state, reading = old.snapshot(), old.reading
    assert reading is not None
    laser_spec = dict(world.sensor_specs[0])
    index = world.controllers.index(old)
    change_sensor(world, "view_cam", {"width": 80})  # the second sensor: the first one's table stays
    new = world.sensors["view_cam"]
    assert new is not old and list(world.sensors) == ["laser", "view_cam"]
    assert [s["name"] for s in world.sensor_specs] == ["laser", "view_cam"]
    assert world.sensor_specs[0] == laser_spec and world.sensor_specs[1]["width"] == 80
    assert world.controllers[index] is new and new.reading is reading
    assert new.snapshot() == state


def test_a_new_seed_restarts_the_noise_stream_as_a_fresh_sensor_of_that_seed_would():
    world = _two_robots()
    change_sensor(world, "laser", {"noise": 0.01, "seed": 7})
    rebuilt = load_scene(SENSORS)  # the same scene, the laser added fresh with that seed
    spec = {**rebuilt.sensor_specs[0], "noise": 0.01, "seed": 7}
    rebuilt.sensor_specs.clear()
    rebuilt.sensors.clear()
    rebuilt.controllers.clear()
    prepare(rebuilt)
    expected = rebuilt.add_sensor(spec).rng.bit_generator.state
    assert world.sensors["laser"].rng.bit_generator.state == expected
    kept = world.sensors["laser"].rng.bit_generator.state
    change_sensor(world, "laser", {"rate": 5.0})  # no seed: the stream goes on where it was
    assert world.sensors["laser"].rng.bit_generator.state == kept


def test_a_rebuilt_service_takes_the_old_ones_place_and_the_state_it_is_given():
    world = _two_robots()
    drive = world.service("DriveService", "bot2")
    given = drive.snapshot()
    drive.drive_distance(0.5)
    world.run(0.1)
    index = world.controllers.index(drive)
    assert drive.snapshot() != given
    new = rebuild_service(world, "DriveService", "bot2", snapshot=given)
    assert new is not drive and world.controllers[index] is new
    assert new.snapshot() == given
    again = rebuild_service(world, "DriveService", "bot2")  # no snapshot: the old one's now
    assert again.snapshot() == new.snapshot() and world.controllers[index] is again


def test_rebuilding_a_service_not_yet_built_builds_it():
    world = load_scene(SENSORS)
    prepare(world)
    world._bound.pop(("DriveService", "boebot"), None)
    world.controllers[:] = [c for c in world.controllers if type(c).__name__ != "DriveService"]
    built = rebuild_service(world, "DriveService", "boebot")
    assert type(built).__name__ == "DriveService" and world.service("DriveService", "boebot") is built
    assert pytest.approx(built.period) == 0.02
