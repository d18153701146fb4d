"""simrun.world.edit_bindings: services and sensors changed on a running world; refusals name their field.

Ground truth: the world's own bindings, controllers and sensor objects after each call (a refused call leaves
the same MjModel and MjData objects, tables and controllers), and the scene's declared maxima.
"""

from __future__ import annotations

import pytest
from test_edit_apply import _two_robots

from simrun.scene.scene_file import MAX_SENSOR_RATE
from simrun.world.edit import EditError
from simrun.world.edit_bindings import add_sensor, change_sensor, change_service


def test_a_change_of_one_robots_service_leaves_the_other_binding_alone():
    world = _two_robots()
    first = world.service("DriveService", "boebot")
    change_service(world, "DriveService", "bot2", {"rate": 25.0})
    assert world.services[0] == {"type": "DriveService", "entity": "boebot"}
    assert world.services[1] == {"type": "DriveService", "entity": "bot2", "rate": 25.0}
    assert world.service("DriveService", "boebot") is first and first.period == pytest.approx(0.02)
    assert world.service("DriveService", "bot2").period == pytest.approx(0.04)


def test_a_webcam_added_on_a_named_camera_reads():
    world = _two_robots()
    add_sensor(world, {"type": "Webcam", "name": "eye", "camera": "view", "width": 32, "height": 24})
    world.run(0.6)
    assert world.sensors["eye"].reading is not None and list(world.sensors)[-1] == "eye"


def test_a_sensor_at_the_highest_rate_is_accepted():
    world = _two_robots()
    change_sensor(world, "laser", {"rate": float(MAX_SENSOR_RATE)})
    assert world.sensors["laser"].period == pytest.approx(1.0 / MAX_SENSOR_RATE)


@pytest.mark.parametrize(
    ("call", "args", "key", "reason", "message"),
    [
        ("service", ("DriveService", "bot3", {"rate": 5.0}), "entity", "missing",
         "no DriveService is bound to 'bot3' (services: DriveService:boebot, DriveService:bot2)"),
        ("service", ("JointService", "bot2", {"rate": 5.0}), "entity", "missing", "no JointService is bound to 'bot2'"),
        ("service", ("DriveService", "bot2", {}), "settings", "invalid", "expected a table of the settings to change"),
        ("service", ("DriveService", "bot2", [1]), "settings", "invalid", "expected a table of the settings to change"),
        ("service", ("DriveService", "bot2", {"type": "X"}), "type", "invalid",
         "type cannot change; remove the service and add it again"),
        ("service", ("DriveService", "bot2", {"entity": "bot3"}), "entity", "invalid",
         "entity cannot change; remove the service and add it again"),
        ("service", ("DriveService", "bot2", {"rate": "fast"}), "rate", "invalid",
         " 'bot2': expected a finite number, got 'fast'"),
        ("sensor", ("nothing", {"rate": 5.0}), "name", "missing",
         "no sensor named 'nothing' (sensors: laser, view_cam"),
        ("sensor", ("laser", {}), "settings", "invalid", "expected a table of the settings to change"),
        ("sensor", ("laser", {"rate": MAX_SENSOR_RATE * 2.0}), "rate", "invalid",
         f"must be at most {MAX_SENSOR_RATE:g} Hz, got {MAX_SENSOR_RATE * 2.0!r}"),
        ("sensor", ("laser", {"rate": -1.0}), "rate", "invalid", "must be >= 0, got -1.0"),
        ("sensor", ("laser", {"noise": -0.5}), "noise", "invalid", "must be >= 0, got -0.5"),
        ("sensor", ("laser", {"max_range": "far"}), "max_range", "invalid",
         " 'laser': expected a finite number, got 'far'"),
        ("sensor", ("laser", [1]), "settings", "invalid", "expected a table of the settings to change"),
        ("sensor", ("laser", {"type": "Webcam"}), "type", "invalid",
         "type cannot change; remove the sensor and add it again"),
        ("sensor", ("laser", {"name": "l2"}), "name", "invalid", "name cannot change"),
        ("sensor", ("laser", {"entity": "box"}), "entity", "invalid", "entity cannot change"),
        ("sensor", ("view_cam", {"camera": "sky"}), "camera", "invalid", "camera cannot change"),
        ("add_sensor", ({"type": "Webcam", "name": "eye", "camera": "nobody/cam"},), "camera", "missing",
         "no entity named 'nobody/cam'"),
        ("add_sensor", ({"type": "Webcam", "name": "eye", "camera": "bot2/nothing"},), "settings", "invalid",
         "a binding does not fit the edited world: sensor 'eye': cannot read"),
        ("add_sensor", ({"type": "Bumper", "name": "b", "entity": "bot2", "rate": MAX_SENSOR_RATE * 4.0},), "rate",
         "invalid", "must be at most"),
        ("add_sensor", ({"type": "LaserRangeFinder", "name": "b", "entity": "bot2", "noise": -1.0},), "noise",
         "invalid",
         "must be >= 0"),
    ],
)  # fmt: skip
def test_a_refused_change_names_its_field_and_changes_nothing(call, args, key, reason, message):
    world = _two_robots()
    model, data, controllers = world.model, world.data, list(world.controllers)
    services, sensors = [dict(s) for s in world.services], [dict(s) for s in world.sensor_specs]
    with pytest.raises(EditError) as refused:
        {"service": change_service, "sensor": change_sensor, "add_sensor": add_sensor}[call](world, *args)
    text = str(refused.value)
    assert (refused.value.key, refused.value.reason) == (key, reason), text
    assert text.startswith(f"{key}{message}" if message.startswith(" ") else f"{key}: {message}"), text
    assert "\n" not in text
    assert world.model is model and world.data is data and world.controllers == controllers
    assert world.services == services and world.sensor_specs == sensors
