"""The registry's schema: every key of every scene type, with its type, unit, default and one-line description.

:func:`schema` reads them from the class (its dataclass fields or constructor signature, and its docstring),
never kept by hand; :func:`keys_markdown` writes docs/scene-format.md's key tables (tests/test_registry_schema.py
checks them and the prose rows against the schema). The types themselves are in
:mod:`simrun.world.registry.tables`.
"""

from __future__ import annotations

import ast
import dataclasses
import functools
import inspect
import re
import sys
import textwrap
import types
import typing
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from simrun.world.registry.tables import GROUPS, Group, names, scene_type

#: The keys every entity has (the :class:`~simrun.world.entity.Entity` base), in the order errors list them.
ENTITY_BASE: tuple[str, ...] = ("name", "parent", "pose", "free", "kinematic")


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
