"""The registry's schema (issue 37 item 2): one route from a scene table to constructor arguments.

Every key of every entity, service and sensor type has its type, unit, default and description read from the
class (:func:`simrun.world.registry.key_schema.schema`); :func:`~simrun.world.registry.conversion.arguments` turns
a TOML table into
the constructor's arguments for all three groups, so a key works in a scene file exactly as in Python; and
docs/scene-format.md is checked against the schema: its generated ``## Keys`` section is the schema's, and
every default or unit a prose row states next to a key is the schema's.
"""

import dataclasses
import json
import math
import re
import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from simrun import World, load_scene
from simrun.errors import EntityError, SceneError
from simrun.world.registry.conversion import arguments, python_fail
from simrun.world.registry.key_schema import KEY_TABLES, REQUIRED, keys_markdown, known_keys, schema
from simrun.world.registry.tables import GROUPS, REGISTRY, names

ROOT = Path(__file__).resolve().parent.parent
DOC = (ROOT / "docs" / "scene-format.md").read_text()
BEGIN, END = "<!-- keys:begin -->", "<!-- keys:end -->"
SECTIONS = {"entities": "### Entities", "services": "### Services", "sensors": "### Sensors"}
ALL = [(t.group, name) for name, t in REGISTRY.items()]


def test_the_doc_key_tables_are_the_schema():
    """docs/scene-format.md's ``## Keys`` tables are :func:`keys_markdown` (regenerate them with it)."""
    assert BEGIN in DOC and END in DOC
    section = DOC[DOC.index(BEGIN) + len(BEGIN) : DOC.index(END)].strip("\n") + "\n"
    expected = keys_markdown()
    if section != expected:
        ours, theirs = section.splitlines(), expected.splitlines()
        first = next(
            (k for k, (a, b) in enumerate(zip(ours, theirs, strict=False)) if a != b), min(len(ours), len(theirs))
        )
        pytest.fail(
            "docs/scene-format.md's key tables differ from the schema at table line "
            f"{first + 1}:\n  doc:    {ours[first] if first < len(ours) else '(end)'}\n"
            f"  schema: {theirs[first] if first < len(theirs) else '(end)'}\n"
            'regenerate: .venv/bin/python -c "from simrun.world.registry.key_schema import keys_markdown; '
            "print(keys_markdown(), end='')\" and paste it between the keys markers"
        )
    for group in GROUPS:
        assert f"### {KEY_TABLES[group]}" in section
        for name in names(group):
            assert f"| `{name}` |" in section, name


def _rows(group: str) -> dict[str, str]:
    start = DOC.index(SECTIONS[group])
    rest = DOC[start + len(SECTIONS[group]) :]
    end = min((rest.index(h) for h in ("\n## ", "\n### ") if h in rest), default=len(rest))
    return dict(re.findall(r"^\| `(\w+)` \|(.*)\|$", rest[:end], flags=re.M))


#: A unit word written right after a key in a prose row, as the schema names it.
PROSE_UNITS = {"Hz": "Hz", "degrees": "deg", "metres": "m", "rad/s": "rad/s", "kg": "kg", "seconds": "s"}
_STATED = re.compile(r"`(\w+)`(?: (Hz|degrees|metres|rad/s|kg|seconds)\b)?(?: \(([^()]*)\)| (\[[^\]]*\]))?")


def _stated_value(text: str) -> tuple[object, str] | None:
    """A default as a prose row writes it (``0.10``, ``8 m``, ``false``, ``"chassis"``, ``[640, 480]``), or ``None``."""
    text = re.split(r"[;:]", text, maxsplit=1)[0].strip().strip("`")
    unit = ""
    found = re.fullmatch(r"(-?[\d.]+) (m|N m|rad/s|Hz|kg)", text)
    if found:
        text, unit = found.group(1), found.group(2)
    turns = re.fullmatch(r"([\d.]+) pi", text)  # `bandwidth` rad/s (8 pi: 4 Hz)
    if turns:
        return float(turns.group(1)) * math.pi, unit
    try:
        return json.loads(text), unit
    except ValueError:
        return None


def _same(stated: object, default: object) -> bool:
    if isinstance(stated, list) and isinstance(default, tuple | list):
        return len(stated) == len(default) and all(_same(a, b) for a, b in zip(stated, default, strict=True))
    if isinstance(stated, bool) or isinstance(default, bool):
        return stated is default
    if isinstance(stated, int | float) and isinstance(default, int | float):
        return math.isclose(stated, default, rel_tol=1e-9)
    return stated == default


def test_the_doc_rows_state_the_schema_defaults_and_units():
    """Where a prose row writes a key with a unit (`rate` Hz) or a default (`rays` (181), `offset` [0, 0, 0.05]),
    both are the schema's: the row of a type says that type's default."""
    checked, wrong = 0, []
    for group in GROUPS:
        for kind, row in _rows(group).items():
            keys = schema(group, kind)
            for key, unit_word, paren, bracket in _STATED.findall(row):
                if key not in keys:
                    continue
                spec = keys[key]
                if unit_word:
                    checked += 1
                    if PROSE_UNITS[unit_word] != spec.unit:
                        wrong.append(f"{kind}.{key}: the doc says {unit_word}, the schema {spec.unit or 'no unit'}")
                stated = _stated_value(paren or bracket)
                if stated is None or spec.default in (None, REQUIRED):
                    continue
                value, unit = stated
                checked += 1
                if not _same(value, spec.default) or (unit and unit != spec.unit):
                    wrong.append(
                        f"{kind}.{key}: the doc says {paren or bracket}, the schema {spec.default_text} {spec.unit}"
                    )
    assert not wrong, "docs/scene-format.md contradicts the schema:\n" + "\n".join(wrong)
    assert checked >= 40, checked  # the rows do state defaults: a parser that finds none checks nothing


#: Units of keys, from the physics and docs/conventions.md (not from the code under test).
UNITS = {
    "mass": "kg",
    "density": "kg/m^3",
    "radius": "m",
    "length": "m",
    "wheel_radius": "m",
    "wheel_width": "m",
    "track": "m",
    "baseline": "m",
    "base_radius": "m",
    "stall_torque": "N m",
    "no_load_speed": "rad/s",
    "fovy": "deg",
    "fov": "deg",
    "fov_deg": "deg",
    "cone_deg": "deg",
    "rate": "Hz",
    "bandwidth": "rad/s",
    "max_range": "m",
    "min_range": "m",
    "height": "m",
    "origin": "deg",
    "limits.max_linear": "m/s",
    "limits.command_timeout": "s",
    "pose.position": "m",
}
#: Where one key name means another quantity: a camera's image size.
UNITS_OF = {("Webcam", "width"): "px", ("Webcam", "height"): "px", ("Camera", "resolution"): "px"}


@pytest.mark.parametrize(("group", "kind"), ALL)
def test_every_key_has_a_description_and_the_units_of_physics(group, kind):
    from simrun.world.registry.key_schema import table_keys

    keys = [row for key in schema(group, kind).values() for row in (key, *table_keys(key.hint, key.name))]
    assert keys or kind == "StereoCamera" or group != "entities"
    for key in keys:
        assert key.description, f"{kind}.{key.name} has no description in its class's docstring"
        expected = UNITS_OF.get((kind, key.name), UNITS.get(key.name))
        if expected is not None:
            assert key.unit == expected, f"{kind}.{key.name}: {key.unit!r}"
        if key.hint in (bool, str):
            assert key.unit == "", f"{kind}.{key.name}: a {key.hint.__name__} has no unit"


def _world_with_bot() -> World:
    from simrun.entities.environment import Camera
    from simrun.robots.catalogue import BoeBot
    from simrun.sensors.cameras import StereoRig

    world = World()
    world.insert(BoeBot(name="bot"))
    world.insert(StereoRig(name="rig", parent="bot"))
    world.insert(Camera(name="cam"))
    return world


TARGETS = {"Webcam": "cam", "StereoCamera": "bot/rig"}


@pytest.mark.parametrize("kind", names("sensors"))
def test_sensor_defaults_are_what_a_sensor_built_without_keys_has(kind):
    """Ground truth: the attributes of a sensor constructed with no parameters (``IRDistance``'s ``max_range``
    0.8 is set by ``kwargs.setdefault`` in its constructor, not in a signature)."""
    world = _world_with_bot()
    sensor = world.add_sensor({"type": kind, "name": "s", REGISTRY[kind].binds: TARGETS.get(kind, "bot")})
    compared = 0
    for name, key in schema("sensors", kind).items():
        if not hasattr(sensor, name) or key.default is None or name in ("offset", "joints", "geom"):
            continue  # unset (resolved when bound: a laser's height) or stored resolved (full joint names)
        value = getattr(sensor, name)
        compared += 1
        if isinstance(value, np.ndarray):
            assert np.allclose(value, key.default), (kind, name)
        else:
            assert value == key.default, (kind, name, value, key.default)
    assert compared >= 1, f"{kind}: no parameter is kept under its name"
    assert sensor.period == pytest.approx(1 / schema("sensors", kind)["rate"].default)
    if kind in ("IRDistance", "Sonar"):
        assert sensor.max_range == schema("sensors", kind)["max_range"].default != 1.0  # not the base's 1.0


def _sample(key):
    """A TOML-writable value for a key: its default, or a typical value where the default is unset."""
    from simrun.world.registry.key_schema import _optional

    if key.default not in (None, REQUIRED, ()) and not isinstance(key.default, dict):
        return key.default
    hint = _optional(key.hint)
    samples = {float: 0.25, int: 3, str: "x", bool: True}
    if hint in samples:
        return samples[hint]
    args = getattr(hint, "__args__", ())
    if getattr(hint, "__origin__", None) is tuple and args[-1] is Ellipsis:
        return ("left", "right") if args[0] is str else ((0.1, 1.0), (0.5, 0.2))
    if getattr(hint, "__origin__", None) is tuple:
        return tuple(0.5 + k for k in range(len(args))) if args[0] is float else tuple(4 + k for k in range(len(args)))
    if getattr(hint, "__origin__", None) is list:
        return [[0.0, 0.5], [0.5, 1.0]]
    if getattr(hint, "__origin__", None) is dict:
        return {"pkg": "folder"}
    if dataclasses.is_dataclass(hint):
        return hint()
    if hasattr(hint, "from_scene"):  # an arm's segments
        return hint.from_scene([{"name": "a", "length": 0.2}, {"name": "b", "length": 0.1, "radius": 0.02}], "s")
    pytest.fail(f"{key.name}: no sample for {hint}")


def _to_toml(value):
    if hasattr(value, "to_scene"):
        return value.to_scene()
    if dataclasses.is_dataclass(value):
        return {f.name: _to_toml(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, tuple | list):
        return [_to_toml(v) for v in value]
    if isinstance(value, dict):
        return {k: _to_toml(v) for k, v in value.items()}
    return value


@pytest.mark.parametrize(("group", "kind"), ALL)
def test_every_key_works_in_toml_exactly_as_in_python(group, kind):
    """Each key, written to TOML text and read back, gives the constructor the value Python would pass
    (``wheels = ["left", "right"]`` included); entities built both ways are equal."""
    python = {name: _sample(key) for name, key in schema(group, kind).items() if name != "name"}
    named = {"name": "e"} if group == "entities" else {}
    text = tomli_w.dumps({"t": {"type": kind, **named, **{k: _to_toml(v) for k, v in python.items() if v is not None}}})
    table = tomllib.loads(text)["t"]
    converted = arguments(group, kind, table, python_fail(kind))
    for name, value in python.items():
        if value is None:
            continue
        assert converted[name] == value, (kind, name, converted[name], value)
        assert type(converted[name]) is type(value) or isinstance(value, tuple), (kind, name)
    if group == "entities":
        cls = REGISTRY[kind].load()
        assert cls(**converted) == cls(name="e", **python)


def test_wheels_from_toml_and_python_make_the_same_robot():
    from simrun.robots.mjcf_robot import MjcfRobot

    table = tomllib.loads('type = "MjcfRobot"\nname = "bot"\nfile = "cylbot.xml"\nwheels = ["left", "right"]\n')
    converted = arguments("entities", "MjcfRobot", table, python_fail())
    assert converted["wheels"] == ("left", "right")
    assert MjcfRobot(**converted) == MjcfRobot(name="bot", file="cylbot.xml", wheels=("left", "right"))


SCENE = (
    '[[entities]]\ntype = "BoeBot"\nname = "bot"\n\n'
    '[[sensors]]\ntype = "LaserRangeFinder"\nname = "l"\nentity = "bot"\n'
)


@pytest.mark.parametrize(
    ("line", "python", "message"),
    [
        ("rays = 2.5", {"rays": 2.5}, "rays: expected int, got float 2.5"),
        ('points = "yes"', {"points": "yes"}, "points: expected bool, got str 'yes'"),
        ("max_range = -1e9", {"max_range": -1e9}, "max_range: must be at most 1e+06 in magnitude, got -1000000000.0"),
        ("exclude = 3", {"exclude": 3}, "exclude: expected str, got int 3"),
    ],
)
def test_a_wrong_sensor_value_is_named_alike_in_toml_and_python(tmp_path, line, python, message):
    """A sensor value of the wrong type is refused before the constructor sees it: at its line in a scene, with
    the same words from ``World.add_sensor``."""
    path = tmp_path / "s.toml"
    path.write_text(SCENE + line + "\n")
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert info.value.line == 9 and str(info.value) == f"{path}:9: sensors[0] 'l': {message}"
    world = _world_with_bot()
    with pytest.raises(EntityError) as python_info:
        world.add_sensor({"type": "LaserRangeFinder", "name": "l", "entity": "bot", **python})
    assert str(python_info.value) == f"sensor 'l': {message}"


def test_range_cone_response_pairs_come_from_a_scene(tmp_path):
    """``response`` (pairs of numbers) was refused by the old reader's types; read from TOML it shapes the reading."""
    path = tmp_path / "s.toml"
    path.write_text(
        '[[entities]]\ntype = "BoeBot"\nname = "bot"\n\n[[entities]]\ntype = "Box"\nname = "wall"\n'
        "pose = { position = [0.5, 0.0, 0.05] }\n\n"
        '[[sensors]]\ntype = "IRDistance"\nname = "ir"\nentity = "bot"\nresponse = [[0.1, 3.0], [0.8, 0.4]]\n'
    )
    world = load_scene(path)
    sensor = world.sensors["ir"]
    assert sensor.response == ((0.1, 3.0), (0.8, 0.4))
    world.run(0.1)
    reading = sensor.reading
    assert 0.1 < reading.distance < 0.8  # the box's face, ahead of the chassis
    assert reading.value == pytest.approx(np.interp(reading.distance, [0.1, 0.8], [3.0, 0.4]))


def test_a_service_binding_in_python_goes_the_same_route(tmp_path):
    """A ``[[services]]`` binding given in Python is checked by the same function: unknown key, known keys and
    the closest one; tables become the dataclass (``limits``)."""
    from simrun.robots.catalogue import BoeBot

    world = World()
    world.insert(BoeBot(name="bot"))
    world.services.append({"type": "DriveService", "entity": "bot", "rates": 10.0})
    with pytest.raises(EntityError, match=r"service DriveService of 'bot': rates: unknown key \(known: type, entity, "
                       r"limits, .*rate\); did you mean 'rate'\?"):  # fmt: skip
        world.service("DriveService", "bot")
    world.services[-1] = {"type": "DriveService", "entity": "bot", "rate": 20, "limits": {"max_linear": 0.2}}
    drive = world.service("DriveService", "bot")
    assert drive.period == pytest.approx(0.05) and drive.limits.max_linear == 0.2


def test_known_keys_are_what_errors_list():
    assert known_keys("sensors", "Webcam")[:3] == ("type", "name", "camera")
    assert known_keys("services", "JointService")[:2] == ("type", "entity")
    assert known_keys("entities", "Box")[:6] == ("type", "name", "parent", "pose", "free", "kinematic")


def test_a_missing_required_key_is_named_with_its_meaning(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text('[[entities]]\ntype = "MjcfRobot"\nname = "bot"\nwheels = ["left", "right"]\n')
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert (
        str(info.value)
        == f"{path}:1: entities[0] 'bot': missing key 'file' (Path of the MJCF `.xml` (relative to the world folder))"
    )
