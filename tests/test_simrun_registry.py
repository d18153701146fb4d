"""One registry of scene types (issue 14 item 3): the docs, the scene reader and the world read the same list."""

import dataclasses
import inspect
import re
from pathlib import Path

import pytest

from simrun import load_scene, save_scene
from simrun.sensors.base import Sensor
from simrun.world.registry.tables import GROUPS, REGISTRY, Controller, names

ROOT = Path(__file__).resolve().parent.parent
DOC = (ROOT / "docs" / "scene-format.md").read_text()
BASE = {"name", "parent", "pose", "free", "kinematic"}
SECTIONS = {"entities": "### Entities", "services": "### Services", "sensors": "### Sensors"}


def _rows(group: str) -> dict[str, str]:
    """``type`` -> its row text, from the group's table in docs/scene-format.md."""
    start = DOC.index(SECTIONS[group])
    rest = DOC[start + len(SECTIONS[group]) :]
    end = min((rest.index(h) for h in ("\n## ", "\n### ") if h in rest), default=len(rest))
    rows = {}
    for line in rest[:end].splitlines():
        match = re.match(r"\| `(\w+)` \|(.*)\|$", line)
        if match:
            rows[match.group(1)] = match.group(2)
    return rows


def _parameters(name: str) -> list[str]:
    """What a scene may set for a type, from its class (not from the registry's or the doc's text)."""
    entry = REGISTRY[name]
    cls = entry.load()
    if entry.group == "entities":
        return [f.name for f in dataclasses.fields(cls) if f.name not in BASE]
    init = cls.__init__
    params = list(inspect.signature(init).parameters.values())[2:]
    if any(p.kind is p.VAR_KEYWORD for p in params):  # IRDistance(**kwargs) passes them to its base
        params = list(inspect.signature(cls.__mro__[1].__init__).parameters.values())[2:]
    wanted = [p.name for p in params if p.kind is not p.VAR_KEYWORD]
    if entry.group != "entities":
        wanted.remove("entity" if entry.group == "services" else entry.binds)
    return wanted


@pytest.mark.parametrize("group", GROUPS)
def test_doc_tables_and_registry_list_the_same_types(group):
    assert list(_rows(group)) == list(names(group))


@pytest.mark.parametrize("name", list(REGISTRY))
def test_doc_row_names_every_parameter(name):
    rows = _rows(REGISTRY[name].group)
    row = rows[name]
    like = re.match(r"\s*as (\w+)", row)  # "as DifferentialDrive, defaults from ...": that row's parameters too
    if like:
        row += rows[like.group(1)]
    missing = [p for p in _parameters(name) if f"`{p}`" not in row]
    assert not missing, f"docs/scene-format.md row of {name} lacks {missing}"


def test_registry_targets_are_the_classes_of_their_names():
    for name, entry in REGISTRY.items():
        cls = entry.load()
        assert cls.__name__ == name
        if entry.group == "entities":
            assert name == cls.TYPE


SCENE = """
[[entities]]
type = "Ground"
name = "ground"

[[entities]]
type = "Light"
name = "sun"
pose = {{ position = [0.0, 0.0, 3.0] }}

[[entities]]
type = "BoeBot"
name = "bot"
pose = {{ position = [0.0, 0.0, 0.001] }}

[[entities]]
type = "StereoRig"
name = "rig"
parent = "bot"
resolution = [32, 24]
pose = {{ position = [0.06, 0.0, 0.08] }}

[[entities]]
type = "LynxL6"
name = "arm"
pose = {{ position = [1.0, 0.0, 0.0] }}

[[services]]
type = "DriveService"
entity = "bot"
rate = 100.0
limits = {{ max_linear = 0.2 }}

[[services]]
type = "ArmService"
entity = "arm"

{sensors}
"""
SENSORS = {
    "LaserRangeFinder": 'entity = "bot"\nrays = 9',
    "Bumper": 'entity = "bot"',
    "Encoders": 'entity = "bot"',
    "GPS": 'entity = "bot"',
    "IMU": 'entity = "bot"',
    "IRDistance": 'entity = "bot"',
    "Sonar": 'entity = "bot"',
    "Webcam": 'camera = "bot/rig/left"\nwidth = 32\nheight = 24',
    "StereoCamera": 'rig = "bot/rig"',
}


def test_every_service_and_sensor_type_works_from_a_scene_file(tmp_path):
    """Each registered service and sensor is bound from a scene, is a Controller, ticks, and saves back."""
    from conftest import GL

    assert set(SENSORS) == set(names("sensors"))
    usable = {k: v for k, v in SENSORS.items() if GL or k not in ("Webcam", "StereoCamera")}
    tables = "\n".join(f'[[sensors]]\ntype = "{k}"\nname = "s_{k}"\n{v}\n' for k, v in usable.items())
    path = tmp_path / "all.toml"
    path.write_text(SCENE.format(sensors=tables))
    world = load_scene(path)
    world.check_bindings()
    drive = world.service("DriveService", "bot")
    assert drive.period == pytest.approx(0.01) and drive.limits.max_linear == 0.2
    arm = world.service("ArmService", "arm")
    for controller in [drive, arm, *world.sensors.values()]:
        assert isinstance(controller, Controller), type(controller).__name__
    assert all(isinstance(s, Sensor) for s in world.sensors.values())
    world.run(0.2)
    for name, sensor in world.sensors.items():
        assert sensor.samples >= 1 and sensor.reading is not None, name
    save_scene(world, tmp_path / "again.toml")
    again = load_scene(tmp_path / "again.toml")
    assert again.services == world.services and again.sensor_specs == world.sensor_specs


def test_unknown_types_name_the_registry(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text('[[entities]]\ntype = "Ground"\nname = "g"\n\n[[sensors]]\ntype = "Lidar"\nname = "x"\n')
    with pytest.raises(Exception, match=r"bad.toml:6: sensors\[0\] 'x': type: unknown sensor type 'Lidar'") as info:
        load_scene(path)
    assert ", ".join(names("sensors")) in str(info.value)


def test_every_key_a_doc_row_names_exists():
    """The other way round (issue 37): each bare `key` in a type's row is a key of that type's schema (its `as X`
    type's, the base keys, a service's commands, an arm segment's keys); values are written quoted (`"convex"`)."""
    from simrun.robots.arm_joints import ArmJoint, Segment
    from simrun.serve.catalogue import service_commands
    from simrun.world.registry.key_schema import parameters

    for group in GROUPS:
        for name, row in _rows(group).items():
            keys = set(parameters(group, name)) | BASE
            like = re.match(r"\s*as (\w+)", row)
            if like:
                keys |= set(parameters(group, like.group(1)))
            if group == "services":
                keys |= set(service_commands(REGISTRY[name].load())) | {"state"}
            if group == "sensors":
                keys.add(REGISTRY[name].binds)
            if "segments" in keys:
                keys |= {f.name for f in dataclasses.fields(Segment)} | {f.name for f in dataclasses.fields(ArmJoint)}
            unknown = sorted(set(re.findall(r"`([a-z][a-z0-9_]*)`", row)) - keys)
            assert not unknown, f"docs/scene-format.md row of {name} names {unknown}, not keys of {name}"
