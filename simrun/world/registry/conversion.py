"""The one route from a table to a scene type's constructor arguments (:func:`arguments`).

For entities, services and sensors alike, whether the table comes from a scene file (errors at its file and
line, through the caller's :class:`Fail`) or from Python (``World.add_sensor``, a service binding:
:func:`python_fail`): unknown keys are named with the known ones and the closest, values are checked against
their key's type (:func:`convert`; units and bounds: :data:`MAX_MAGNITUDE`). The keys come from
:mod:`simrun.world.registry.key_schema`.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import types
import typing
from collections.abc import Iterable
from typing import Any, Protocol

from simrun.errors import EntityError, did_you_mean
from simrun.world.registry.key_schema import _optional, known_keys, schema
from simrun.world.registry.tables import Group

KeyPath = tuple[str | int, ...]
"""A key path inside a table: ``("pose", "position", 1)``."""

#: Largest magnitude of any number in a scene table (metres, kg, seconds...); larger values are typing mistakes.
MAX_MAGNITUDE = 1e6
#: Keys whose whole numbers may be larger than :data:`MAX_MAGNITUDE`: a noise ``seed`` is any 64-bit integer.
LARGE_INTEGERS: dict[str, int] = {"seed": 2**63}
#: Most cells of a height field given as numbers.
MAX_HEIGHT_CELLS = 1024 * 1024


class Fail(Protocol):
    """How :func:`arguments` reports a refused value: the error to raise for ``message`` at ``path``.

    ``path`` is relative to the table (``("pose", "position", 1)``; ``()``: the table itself); ``line_at``, when
    given, is the key whose line the error should name instead of ``path``'s.
    """

    def __call__(self, message: str, path: KeyPath, line_at: KeyPath | None = None) -> Exception:
        """The error to raise (not raised here)."""
        ...


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
