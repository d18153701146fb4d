"""The one registry of scene types: every entity, service and sensor a scene file may name.

:class:`~simrun.world.world.World` (``service``, ``add_sensor``), :mod:`simrun.scene.scene_file` (``[[entities]]``,
``[[services]]``, ``[[sensors]]``), :mod:`simrun.run.commands` and ``docs/scene-format.md``
(tests/test_simrun_registry.py keeps the document in step) read this table and nothing else; whether an entity
is a robot is the robot contract's answer (:func:`simrun.robots.contract.is_robot`), not a registry flag.
Classes are named by ``module:Class`` and imported on first use, so this
module imports no other simrun module and the modules it names may import :mod:`simrun.world.world` freely:
there is no cycle.

Services and sensors are world controllers: both implement :class:`Controller`, the protocol the world's
stepping loop, checkpoints (``.simlog``) and ``save_scene(state="current")`` rely on.

The registry's schema (:func:`schema`) is every key of every type, with its type, unit, default and one-line
description, read from the class (its dataclass fields or constructor signature, and its docstring), never kept
by hand. :func:`arguments` is the one route from a table to the constructor's arguments, for entities, services
and sensors alike, whether the table comes from a scene file (errors at its file and line) or from Python
(``World.add_sensor``, a service binding): unknown keys are named with the known ones and the closest, values
are checked against their key's type. :func:`keys_markdown` writes docs/scene-format.md's key tables
(tests/test_registry_schema.py checks them and the prose rows against the schema).
"""

from __future__ import annotations

import ast
import dataclasses
import functools
import importlib
import inspect
import math
import numbers
import re
import sys
import textwrap
import types
import typing
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any, Literal, Protocol, runtime_checkable

from simrun.errors import EntityError, did_you_mean

Group = Literal["entities", "services", "sensors"]
GROUPS: tuple[Group, ...] = ("entities", "services", "sensors")


@runtime_checkable
class Controller(Protocol):
    """What a service or sensor is to the world: ticked on the simulation clock, checkpointed, reset.

    Attributes:
        next_time: Simulated time of the next tick, seconds (the world advances it by ``period``).
        period: Seconds between ticks; 0 ticks before every step.
    """

    next_time: float
    period: float

    def tick(self, model: Any, data: Any) -> None:
        """Act or sample (``model``/``data``: the world's ``MjModel``/``MjData``); controls hold until the next tick."""

    def reset(self, model: Any, data: Any) -> None:
        """Back to the state after construction (``World.reset``)."""

    def snapshot(self) -> dict[str, Any]:
        """Everything needed to continue bit for bit (JSON-ready): checkpoints and ``save_scene(state="current")``."""

    def restore(self, state: dict[str, Any]) -> None:
        """Inverse of :meth:`snapshot`."""


@dataclass(frozen=True, slots=True)
class SceneType:
    """One scene type.

    Attributes:
        name: The ``type`` value in a scene file (``Box``, ``DriveService``, ``GPS``).
        group: ``entities``, ``services`` or ``sensors``.
        target: ``module:Class``.
        summary: One line for the documentation.
        binds: Services and sensors: the key naming what it is attached to (``entity``, ``camera``, ``rig``).
    """

    name: str
    group: Group
    target: str
    summary: str
    binds: str = "entity"

    def load(self) -> Any:
        """The class (imported now)."""
        module, name = self.target.split(":")
        return getattr(importlib.import_module(module), name)


def _types(group: Group, rows: list[tuple[str, str, str]], **extra: Any) -> list[SceneType]:
    return [SceneType(name, group, target, summary, **extra) for name, target, summary in rows]


_ENTITIES = _types(
    "entities",
    [
        ("Box", "simrun.entities.shapes:Box", "A box of `dimensions` (m)."),
        ("Sphere", "simrun.entities.shapes:Sphere", "A sphere of `radius` (m)."),
        ("Capsule", "simrun.entities.shapes:Capsule", "A capsule of `radius` and cylinder `length` (m) along Z."),
        ("Cylinder", "simrun.entities.shapes:Cylinder", "A cylinder of `radius` and `length` (m) along Z."),
        (
            "MeshEntity",
            "simrun.entities.mesh_entity:MeshEntity",
            "A meshtool `.mbin` asset: visual mesh and collision hulls.",
        ),
        (
            "UrdfRobot",
            "simrun.robots.urdf_robot:UrdfRobot",
            "A robot imported from a URDF file (meshes through meshtool).",
        ),
        ("MjcfRobot", "simrun.robots.mjcf_robot:MjcfRobot", "Any MJCF model, attached through MjSpec under `NAME/`."),
        ("Ground", "simrun.entities.environment:Ground", "An infinite plane, optionally textured."),
        ("HeightField", "simrun.entities.environment:HeightField", "Terrain from a grey-scale image or numbers."),
        ("Sky", "simrun.entities.environment:Sky", "A sky box (colour gradient or image)."),
        ("Light", "simrun.entities.environment:Light", "A directional, spot or point light."),
        ("Camera", "simrun.entities.environment:Camera", "A named camera (`main = true`: the default view)."),
        ("StereoRig", "simrun.sensors.cameras:StereoRig", "Two cameras `NAME/left` and `NAME/right` a baseline apart."),
        ("ArticulatedArm", "simrun.robots.arm:ArticulatedArm", "An arm of segments and joints with position servos."),
        ("KukaLBR3", "simrun.robots.arm:KukaLBR3", "KUKA LBR3: seven revolute joints, published link lengths."),
        ("LynxL6", "simrun.robots.arm:LynxL6", "Lynx 6: five joints and a two-finger gripper."),
    ],
)
_ROBOTS = _types(
    "entities",
    [
        (
            "DifferentialDrive",
            "simrun.robots.diff_drive:DifferentialDrive",
            "A two-wheeled robot of given dimensions and motors.",
        ),
        ("BoeBot", "simrun.robots.catalogue:BoeBot", "Parallax Boe-Bot (published dimensions and servo speed)."),
        ("Pioneer3DX", "simrun.robots.catalogue:Pioneer3DX", "Adept MobileRobots Pioneer 3-DX."),
        ("IRobotCreate", "simrun.robots.catalogue:IRobotCreate", "iRobot Create."),
        ("LegoNxtTribot", "simrun.robots.catalogue:LegoNxtTribot", "LEGO Mindstorms NXT TriBot."),
    ],
)
_SERVICES = _types(
    "services",
    [
        (
            "DriveService",
            "simrun.services.drive_service:DriveService",
            "Wheel speed control, odometry, drive/rotate commands.",
        ),
        ("ArmService", "simrun.robots.arm_service:ArmService", "Joint targets, trajectories and gripper of an arm."),
        (
            "JointService",
            "simrun.services.joint_service:JointService",
            "Targets, trajectories, state of any model's joints.",
        ),
    ],
)
_SENSORS = _types(
    "sensors",
    [
        ("LaserRangeFinder", "simrun.sensors.laser:LaserRangeFinder", "A planar laser scan (SICK LMS style)."),
        ("Bumper", "simrun.sensors.robot_state:Bumper", "Contact of a geom (default `chassis`) with anything else."),
        ("Encoders", "simrun.sensors.robot_state:Encoders", "Angles and speeds of the named joints."),
        ("GPS", "simrun.sensors.robot_state:GPS", "World position (with noise)."),
        ("IMU", "simrun.sensors.robot_state:IMU", "Angular velocity, linear acceleration and orientation."),
        ("IRDistance", "simrun.sensors.range_cone:IRDistance", "A narrow infrared range cone (short range)."),
        ("Sonar", "simrun.sensors.range_cone:Sonar", "A wide sonar range cone."),
    ],
)
_CAMERAS = [
    SceneType(
        "Webcam", "sensors", "simrun.sensors.cameras:Webcam", "RGB (and depth) images of a named camera.", "camera"
    ),
    SceneType("StereoCamera", "sensors", "simrun.sensors.cameras:StereoCamera", "Both images of a `StereoRig`.", "rig"),
]

#: Every scene type by name (names are unique across groups), in documentation order.
REGISTRY: dict[str, SceneType] = {t.name: t for t in (*_ENTITIES, *_ROBOTS, *_SERVICES, *_SENSORS, *_CAMERAS)}


def names(group: Group) -> tuple[str, ...]:
    """The type names of one group, in registry order."""
    return tuple(name for name, t in REGISTRY.items() if t.group == group)


def scene_type(group: Group, name: Any) -> SceneType:
    """The registered type ``name`` of ``group``.

    Raises:
        EntityError: Not a type of that group (the message lists the known ones).
    """
    found = REGISTRY.get(name) if isinstance(name, str) else None
    if found is None or found.group != group:
        singular = {"entities": "entity", "services": "service", "sensors": "sensor"}[group]
        raise EntityError(f"unknown {singular} type {name!r} (known: {', '.join(names(group))})")
    return found


def load(group: Group, name: Any) -> Any:
    """The class of a registered type (see :func:`scene_type`)."""
    return scene_type(group, name).load()


KeyPath = tuple[str | int, ...]
"""A key path inside a table: ``("pose", "position", 1)``."""

#: Largest magnitude of any number in a scene table (metres, kg, seconds...); larger values are typing mistakes.
MAX_MAGNITUDE = 1e6
#: Keys whose whole numbers may be larger than :data:`MAX_MAGNITUDE`: a noise ``seed`` is any 64-bit integer.
LARGE_INTEGERS: dict[str, int] = {"seed": 2**63}
#: Most cells of a height field given as numbers.
MAX_HEIGHT_CELLS = 1024 * 1024
#: The keys every entity has (the :class:`~simrun.world.entity.Entity` base), in the order errors list them.
ENTITY_BASE: tuple[str, ...] = ("name", "parent", "pose", "free", "kinematic")


class Fail(Protocol):
    """How :func:`arguments` reports a refused value: the error to raise for ``message`` at ``path``.

    ``path`` is relative to the table (``("pose", "position", 1)``; ``()``: the table itself); ``line_at``, when
    given, is the key whose line the error should name instead of ``path``'s.
    """

    def __call__(self, message: str, path: KeyPath, line_at: KeyPath | None = None) -> Exception:
        """The error to raise (not raised here)."""
        ...


class _Required:
    """The default of a key that must be given."""

    def __repr__(self) -> str:
        return "REQUIRED"


#: :attr:`Key.default` of a key that must be given (an entity's ``name``, an ``MjcfRobot``'s ``file``).
REQUIRED: Any = _Required()


@dataclass(frozen=True, slots=True)
class Key:
    """One key a scene table of some type may set: what :func:`schema` says about it.

    Attributes:
        name: The key (``wheel_radius``; ``limits.max_linear`` for a field of a table-valued key).
        hint: Its type annotation, resolved (``float | None``, ``tuple[float, float, float]``, a dataclass).
        default: Its value when not given (the constructor's default); :data:`REQUIRED` when it must be given.
        unit: Unit of its numbers (``m``, ``kg``, ``kg/m^3``, ``s``, ``Hz``, ``deg``, ``rad/s``, ``N m``, ``px``...),
            read from its description; ``""``: no unit (a count, a ratio, not a number).
        description: One line, from the ``Attributes:`` or ``Args:`` section of the class's docstring (its
            bases' too), else the class docstring's sentence that names the key.
    """

    name: str
    hint: Any
    default: Any
    unit: str
    description: str

    @property
    def required(self) -> bool:
        """Whether the key must be given."""
        return self.default is REQUIRED

    @property
    def type_text(self) -> str:
        """The value a scene file writes, in words: ``number``, ``3 numbers``, ``array of strings``, ``table``."""
        return _type_text(self.hint)

    @property
    def default_text(self) -> str:
        """The default as a scene file writes it (``0.05``, ``[0.1, 0.1]``, ``"robot"``), ``none``, ``required``."""
        return _value_text(self.default)


def fixed_keys(group: Group, kind: str) -> tuple[str, ...]:
    """The keys of a table that are no constructor parameter: ``type``, a sensor's ``name``, what it binds.

    What a service or sensor binds is its :attr:`SceneType.binds` (``entity``, ``camera``, ``rig``).
    """
    binds = scene_type(group, kind).binds
    return {"entities": ("type",), "services": ("type", binds), "sensors": ("type", "name", binds)}[group]


def known_keys(group: Group, kind: str) -> tuple[str, ...]:
    """Every key a table of type ``kind`` may hold, in the order errors list them (:func:`fixed_keys` first)."""
    return (*fixed_keys(group, kind), *schema(group, kind))


@functools.cache
def schema(group: Group, kind: str) -> Mapping[str, Key]:
    """The keys a ``kind`` table may set besides :func:`fixed_keys`, in order: type, unit, default, description.

    All of it is read from the class (nothing is kept by hand here).

    Entities: the dataclass fields (the base's :data:`ENTITY_BASE` first), defaults from the fields. Services
    and sensors: the constructor's parameters after ``(world, TARGET)``; a constructor taking ``**kwargs``
    passes them to its base's, whose parameters are read instead, with the defaults it sets itself
    (``kwargs.setdefault("max_range", 0.8)``: an :class:`~simrun.sensors.range_cone.IRDistance`'s range).
    Descriptions: :data:`Key.description`; units: the first unit word of it (``metres`` -> ``m``).

    Raises:
        EntityError: ``kind`` is not a type of ``group``.
    """
    cls = scene_type(group, kind).load()
    owner = cls
    if group == "entities":
        hints = typing.get_type_hints(cls)
        fields = {f.name: f for f in dataclasses.fields(cls)}
        order = [*ENTITY_BASE, *(name for name in fields if name not in ENTITY_BASE)]
        defaults = {name: _field_default(fields[name]) for name in order}
    else:
        owner = next(c for c in cls.__mro__ if not _takes_kwargs(c))
        params = list(inspect.signature(owner.__init__).parameters.values())[3:]
        names_there = dict(vars(sys.modules[owner.__module__]))
        names_there.setdefault("World", Any)  # imported for type checking only (no import cycle)
        hints = typing.get_type_hints(owner.__init__, globalns=names_there)
        order = [p.name for p in params if p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]
        defaults = {p.name: REQUIRED if p.default is p.empty else p.default for p in params if p.name in order}
        defaults.update(_set_defaults(cls, owner))
    documented = _documented(cls)
    return types.MappingProxyType(
        {name: _key(name, hints[name], defaults[name], documented.get(name, "")) for name in order}
    )


def table_keys(hint: Any, prefix: str) -> tuple[Key, ...]:
    """The keys of a table-valued key's dataclass (``limits``: ``limits.max_linear``...), ``()`` for other hints."""
    inner = _optional(hint)
    if not (isinstance(inner, type) and dataclasses.is_dataclass(inner)):
        return ()
    hints, documented = typing.get_type_hints(inner), _documented(inner)
    return tuple(
        _key(f"{prefix}.{f.name}", hints[f.name], _field_default(f), documented.get(f.name, ""))
        for f in dataclasses.fields(inner)
    )


def parameters(group: Group, kind: str) -> tuple[str, ...]:
    """The keys a scene table of type ``kind`` may set besides ``type``, ``name`` and what it binds.

    Entities: the dataclass fields less the base (``name``, ``pose``, ``parent``, ``free``, ``kinematic``); services
    and sensors: the constructor's parameters after ``(world, TARGET)`` (see :func:`schema`).
    """
    return tuple(name for name in schema(group, kind) if group != "entities" or name not in ENTITY_BASE)


def unknown_message(key: object, known: Iterable[str]) -> str:
    """``unknown key (known: type, name, entity, height, ...); did you mean 'rays'?`` (the hint when one is close)."""
    known = list(known)
    return f"unknown key (known: {', '.join(known)}){did_you_mean(key, known)}"


def arguments(group: Group, kind: str, table: dict[str, Any], fail: Fail) -> dict[str, Any]:
    """The constructor's keyword arguments for a scene table of type ``kind``.

    The one route from a table (``[[entities]]``, ``[[services]]``, ``[[sensors]]``, or the same dict given in
    Python to ``World.add_sensor`` or as a service binding) to a constructor.

    Every key is checked against :func:`known_keys` (the first unknown one is refused with the known ones and a
    "did you mean"), every value against its key's type (:func:`convert`): numbers finite and at most
    :data:`MAX_MAGNITUDE` in magnitude, arrays to tuples of the right length, tables to the dataclass the key
    wants; a key without a default (:data:`REQUIRED`: an ``MjcfRobot``'s ``file``) must be there. The
    :func:`fixed_keys` are checked by the caller and left out of the result.

    Args:
        group: ``entities``, ``services`` or ``sensors``.
        kind: The registered type (its ``type`` value).
        table: The table, as ``tomllib`` reads it (Python tuples, ``None`` for an optional key and numpy
            scalars are accepted too).
        fail: Makes the error for a refused key (a scene file's names the file and line; :func:`python_fail`).

    Raises:
        Exception: What ``fail`` returns, for the first unknown key or refused value.
    """
    keys = schema(group, kind)
    known = known_keys(group, kind)
    for key in table:
        if key not in known:
            raise fail(unknown_message(key, known), (key,))
    missing = next((name for name, key in keys.items() if key.required and name not in table), None)
    if missing is not None:
        raise fail(f"missing key {missing!r} ({keys[missing].description.rstrip('.')})", ())
    return {name: convert(table[name], key.hint, fail, (name,)) for name, key in keys.items() if name in table}


def python_fail(subject: str = "") -> Fail:
    """A :class:`Fail` for tables given in Python: an :class:`EntityError` ``SUBJECT: KEY: message``."""

    def fail(message: str, path: KeyPath, line_at: KeyPath | None = None) -> Exception:
        text = f"{key_text(path)}: {message}" if path else message
        return EntityError(f"{subject}: {text}" if subject else text)

    return fail


def service_arguments(binding: dict[str, Any]) -> dict[str, Any]:
    """Keyword arguments of a ``[[services]]`` binding (:func:`arguments`; errors are :class:`EntityError`)."""
    kind = binding["type"]
    return arguments("services", kind, binding, python_fail(f"service {kind} of {binding.get('entity')!r}"))


def key_text(path: KeyPath) -> str:
    """``("pose", "position", 1)`` as ``pose.position[1]``."""
    text = ""
    for part in path:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else str(part))
    return text


def convert(value: Any, hint: Any, fail: Fail, path: KeyPath) -> Any:
    """Check a scene value against a type annotation and convert it (arrays to tuples, tables to dataclasses).

    Args:
        value: The value as ``tomllib`` reads it.
        hint: The annotation (``float``, ``float | None``, ``tuple[float, float, float]``, ``tuple[str, ...]``,
            ``list[list[float]]`` rows, ``dict[str, str]``, a dataclass, a class with ``from_scene``).
        fail: Makes the error (see :class:`Fail`).
        path: Where the value is, relative to the table (errors name it).

    Raises:
        Exception: What ``fail`` returns: a value of the wrong type, length or range, an unknown key of a
            table, a non-finite number, or a type a scene file cannot write.
    """
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (types.UnionType, typing.Union):
        if value is None and type(None) in args:  # Python only: TOML has no null
            return None
        return convert(value, _optional(hint), fail, path)
    if isinstance(hint, type) and hasattr(hint, "from_scene"):  # a value that reads itself (an arm's segments)
        try:
            return hint.from_scene(value, key_text(path))
        except EntityError as exc:  # its message starts with the key path (``segments[1].length: ...``)
            raise fail(str(exc), (), path) from None
    if dataclasses.is_dataclass(hint) and isinstance(hint, type):  # DriveLimits, Material, Pose
        fields = typing.get_type_hints(hint)
        _check_keys(value, list(fields), fail, path)
        converted = {k: convert(v, fields[k], fail, (*path, k)) for k, v in value.items()}
        try:
            return hint(**converted)
        except (EntityError, ValueError, TypeError) as exc:
            raise fail(str(exc), path) from None
    if origin is tuple and len(args) == 2 and args[1] is Ellipsis:  # any length (MjcfRobot's wheels)
        if not isinstance(value, list | tuple):
            raise fail(f"expected an array, got {type(value).__name__} {value!r}", path)
        return tuple(convert(v, args[0], fail, (*path, k)) for k, v in enumerate(value))
    if origin is tuple:
        if not all(a in (int, float) for a in args):
            raise fail("cannot be set in a scene file (create this entity in code)", path)
        numbers = _vector(value, len(args), fail, path)
        for k, (v, a) in enumerate(zip(numbers, args, strict=True)):
            if a is int and not float(v).is_integer():
                raise fail(f"expected a whole number, got {v!r}", (*path, k))
        return tuple(int(v) if a is int else v for v, a in zip(numbers, args, strict=True))
    if origin is list:
        return _grid(value, fail, path)
    if origin is dict:
        if not isinstance(value, dict):
            raise fail(f"expected a table, got {type(value).__name__}", path)
        for key, item in value.items():
            _typed(item, str, fail, (*path, key))
        return dict(value)
    if hint is float:
        return _number(value, fail, path)
    if hint is int:
        number = _typed(value, int, fail, path)
        limit = LARGE_INTEGERS.get(str(path[-1]) if path else "", MAX_MAGNITUDE)
        if abs(number) > limit:
            raise fail(f"must be at most {limit:g} in magnitude, got {number}", path)
        return int(number)
    if not isinstance(hint, type):
        raise fail("cannot be set in a scene file (create this entity in code)", path)
    return _typed(value, hint, fail, path)


def _check_keys(table: Any, keys: list[str], fail: Fail, path: KeyPath) -> None:
    if not isinstance(table, dict):
        raise fail("expected a table", path)
    for key in table:
        if key not in keys:
            raise fail(unknown_message(key, keys), (*path, key))


def _grid(value: Any, fail: Fail, path: KeyPath) -> list[list[float]]:
    """A rectangular array of arrays of numbers (a height field), at least 2 x 2."""
    if not isinstance(value, list) or not value or not all(isinstance(row, list) for row in value):
        raise fail("expected an array of arrays of numbers (rows)", path)
    width = len(value[0])
    for r, row in enumerate(value):
        if len(row) != width:
            raise fail(f"row {r} has {len(row)} numbers, row 0 has {width}; rows must be equally long", (*path, r))
    if len(value) < 2 or width < 2:
        raise fail(f"needs at least 2 x 2 numbers, got {len(value)} x {width}", path)
    if len(value) * width > MAX_HEIGHT_CELLS:
        raise fail(f"{len(value)} x {width} numbers, over the limit of {MAX_HEIGHT_CELLS}", path)
    return [[_number(v, fail, (*path, r, c)) for c, v in enumerate(row)] for r, row in enumerate(value)]


def _typed(value: Any, kind: type, fail: Fail, path: KeyPath) -> Any:
    if kind is int and isinstance(value, numbers.Integral) and not isinstance(value, bool):
        return int(value)  # a numpy integer from Python
    if not isinstance(value, kind) or (kind is not bool and isinstance(value, bool)):
        raise fail(f"expected {kind.__name__}, got {type(value).__name__} {value!r}", path)
    return value


def _number(value: Any, fail: Fail, path: KeyPath) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value):
        raise fail(f"expected a finite number, got {value!r}", path)
    if abs(float(value)) > MAX_MAGNITUDE:
        raise fail(f"must be at most {MAX_MAGNITUDE:g} in magnitude, got {value!r}", path)
    return float(value)


def _vector(value: Any, n: int, fail: Fail, path: KeyPath) -> tuple[float, ...]:
    if not isinstance(value, list | tuple) or len(value) != n:
        got = f"{len(value)}" if isinstance(value, list | tuple) else type(value).__name__
        raise fail(f"expected {n} numbers, got {got}", path)
    return tuple(_number(v, fail, (*path, k)) for k, v in enumerate(value))


# --- reading the schema from the classes -------------------------------------------------------------------------

#: Unit words of descriptions and the unit they name (longest first where one starts another).
_UNITS: tuple[tuple[str, str], ...] = (
    ("power per rad/s", "power per rad/s"),
    ("power per rad", "power per rad"),
    ("kg/m^3", "kg/m^3"),
    ("m/s^2", "m/s^2"),
    ("rad/s^2", "rad/s^2"),
    ("rad/s", "rad/s"),
    ("m/s", "m/s"),
    ("N m", "N m"),
    ("Hz", "Hz"),
    ("degrees", "deg"),
    ("radians", "rad"),
    ("rad", "rad"),
    ("per simulated second", "Hz"),
    ("metres", "m"),
    ("meters", "m"),
    ("seconds", "s"),
    ("kg", "kg"),
    ("pixels", "px"),
)
_UNIT = re.compile(r"(?<![\w/^])(" + "|".join(re.escape(w) for w, _ in _UNITS) + r")(?![\w/^])", re.IGNORECASE)
_SECTION = re.compile(r"^(\s*)(Args|Attributes):\s*$")
_ENTRY = re.compile(r"^(\s*)(\w+)(?: \([^)]*\))?:(?:\s+(.*))?$")
_ROLE = re.compile(r":\w+:`~?([^`]+)`")


def _key(name: str, hint: Any, default: Any, text: str) -> Key:
    description = _ROLE.sub(lambda m: f"`{m.group(1).rsplit('.', 1)[-1]}`", text).replace("``", "`")
    return Key(name, hint, default, _unit(hint, description), description)


def _unit(hint: Any, description: str) -> str:
    """The unit a description names for a key whose values are numbers, else ``""``."""
    if not _has_numbers(hint):
        return ""
    found = _UNIT.search(description)
    if found is None:
        return ""
    word = found.group(1).lower()
    return next(unit for w, unit in _UNITS if w.lower() == word)


def _has_numbers(hint: Any) -> bool:
    if hint in (int, float):
        return True
    if isinstance(hint, type) and (dataclasses.is_dataclass(hint) or hasattr(hint, "from_scene")):
        return False
    return any(_has_numbers(a) for a in typing.get_args(hint) if a is not Ellipsis)


def _optional(hint: Any) -> Any:
    """``X`` of ``X | None``; other hints as they are."""
    if typing.get_origin(hint) in (types.UnionType, typing.Union):
        return next(a for a in typing.get_args(hint) if a is not type(None))
    return hint


def _field_default(spec: dataclasses.Field[Any]) -> Any:
    if spec.default is not dataclasses.MISSING:
        return spec.default
    if spec.default_factory is not dataclasses.MISSING:
        return spec.default_factory()
    return REQUIRED


def _takes_kwargs(cls: type) -> bool:
    return any(p.kind is p.VAR_KEYWORD for p in inspect.signature(cls.__init__).parameters.values())  # type: ignore[misc]


def _set_defaults(cls: type, owner: type) -> dict[str, Any]:
    """The defaults the constructors between ``cls`` and ``owner`` give with ``kwargs.setdefault(KEY, VALUE)``."""
    found: dict[str, Any] = {}
    for klass in cls.__mro__[: cls.__mro__.index(owner)]:
        if "__init__" not in vars(klass):
            continue
        tree = ast.parse(textwrap.dedent(inspect.getsource(klass.__init__)))  # type: ignore[misc]
        for node in ast.walk(tree):
            if (
                isinstance(node, ast.Call)
                and isinstance(node.func, ast.Attribute)
                and node.func.attr == "setdefault"
                and len(node.args) == 2
                and isinstance(node.args[0], ast.Constant)
                and isinstance(node.args[0].value, str)
            ):
                found.setdefault(node.args[0].value, ast.literal_eval(node.args[1]))
    return found


def _documented(cls: type) -> dict[str, str]:
    """Key to its description (one line) from the docstrings of ``cls`` and its bases, the class's own first.

    Read: the ``Attributes:`` and ``Args:`` sections of each class's docstring and of its ``__init__``'s; a key
    none of them lists gets the first sentence of a class docstring that names it (````key````).
    """
    found: dict[str, str] = {}
    texts = []
    for klass in cls.__mro__:
        for doc in (vars(klass).get("__doc__"), getattr(vars(klass).get("__init__"), "__doc__", None)):
            if doc:
                texts.append(inspect.cleandoc(doc))
                for name, text in _entries(doc).items():
                    found.setdefault(name, text)
    for text in texts:
        for sentence in re.split(r"(?<=[.:])\s+(?=[A-Z`(])", " ".join(text.split())):
            for name in re.findall(r"``(\w+)``", sentence):
                found.setdefault(name, sentence)
    return found


def _entries(doc: str) -> dict[str, str]:
    """The entries of a docstring's ``Args:`` and ``Attributes:`` sections, each joined into one line."""
    lines = inspect.cleandoc(doc).splitlines()
    out: dict[str, list[str]] = {}
    k = 0
    while k < len(lines):
        section = _SECTION.match(lines[k])
        k += 1
        if section is None:
            continue
        indent, entry_indent, current = len(section.group(1)), None, None
        while k < len(lines) and (not lines[k].strip() or len(lines[k]) - len(lines[k].lstrip()) > indent):
            line = lines[k]
            k += 1
            if not line.strip():
                continue
            entry = _ENTRY.match(line)
            depth = len(line) - len(line.lstrip())
            if entry and (entry_indent is None or depth == entry_indent):
                entry_indent, current = depth, entry.group(2)
                out[current] = [entry.group(3) or ""]
            elif current is not None:
                out[current].append(line.strip())
    return {name: " ".join(" ".join(parts).split()) for name, parts in out.items()}


def _type_text(hint: Any) -> str:
    hint = _optional(hint)
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if isinstance(hint, type) and hasattr(hint, "from_scene"):
        return "array of tables"
    if isinstance(hint, type) and dataclasses.is_dataclass(hint):
        return "table"
    if origin is tuple and len(args) == 2 and args[1] is Ellipsis:
        inner = _type_text(args[0])
        return f"array of {inner}s" if " " not in inner else f"array of [{inner}]"
    if origin is tuple:
        word = "integers" if all(a is int for a in args) else "numbers"
        return f"{len(args)} {word}"
    if origin is list:
        return "rows of numbers"
    if origin is dict:
        return "table of strings"
    return {float: "number", int: "integer", str: "string", bool: "boolean"}.get(hint, str(hint))


def _value_text(value: Any) -> str:
    if value is REQUIRED:
        return "required"
    if value is None:
        return "none"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{k} = {_value_text(v)}" for k, v in value.items()) + " }" if value else "{}"
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return (
            "{ "
            + ", ".join(f"{f.name} = {_value_text(getattr(value, f.name))}" for f in dataclasses.fields(value))
            + " }"
        )
    if isinstance(value, tuple | list):
        if value and all(hasattr(v, "to_scene") for v in value):
            return f"{len(value)} tables"
        return "[" + ", ".join(_value_text(v) for v in value) + "]"
    return repr(value)


#: The heading of each group's key table in docs/scene-format.md.
KEY_TABLES: dict[Group, str] = {"entities": "Entity keys", "services": "Service keys", "sensors": "Sensor keys"}


def keys_markdown() -> str:
    """The key tables of ``docs/scene-format.md`` (its ``## Keys`` section), made from :func:`schema`.

    One table per group (headed :data:`KEY_TABLES`); a row per key (a table-valued key's fields follow it as
    ``key.field``) with the value a scene writes, its unit, its default and its description. The entities'
    base keys (:data:`ENTITY_BASE`) are listed once, as ``every entity``.
    """
    out = []
    for group in GROUPS:
        out += [
            f"### {KEY_TABLES[group]}",
            "",
            "| type | key | value | unit | default | meaning |",
            "|---|---|---|---|---|---|",
        ]
        kinds = [("every entity", "Box", ENTITY_BASE)] if group == "entities" else []
        kinds += [(f"`{kind}`", kind, parameters(group, kind)) for kind in names(group)]
        for label, kind, wanted in kinds:
            rows = [
                row
                for name in wanted
                for key in [schema(group, kind)[name]]
                for row in (key, *table_keys(key.hint, name))
            ]
            for k, row in enumerate(rows):
                cells = [
                    label if k == 0 else "",
                    f"`{row.name}`",
                    row.type_text,
                    row.unit,
                    row.default_text,
                    row.description,
                ]
                out.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
            if not rows:
                out.append(f"| {label} | - | | | | no keys besides {', '.join(fixed_keys(group, kind))} |")
        out.append("")
    return "\n".join(out).rstrip() + "\n"
