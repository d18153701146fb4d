"""Expectations (``[[expect]]`` in a scene or commands file): what must hold during or at the end of a run.

``simrun test`` (:mod:`simrun.scenetest`) checks them; each has an ``id``, a ``message``, a ``kind`` and a
time: ``at = T`` (the first observation at or after T simulated seconds), ``at = "end"``, ``always =
[T0, T1]`` (every observation in the window) or ``sometime = [T0, T1]`` (at least one; ``T1`` may be
``"end"``). Observations are taken at the start, every :data:`simrun.run.play.DISTANCE_PERIOD` seconds of
simulated time (and at every command time), and at the end. Kinds (units: metres, degrees, seconds):

- ``position``: ``body`` within ``within`` m of ``point`` (2 numbers: distance in the ground plane; 3: in space;
  ``"start"``: where the body was when the run started, in space);
- ``region``: ``body`` inside the axis-aligned box ``min``..``max`` (2 or 3 numbers each);
- ``heading``: ``body``'s yaw (its X axis in the ground plane, degrees from +X towards +Y) within ``within``
  degrees of ``yaw``;
- ``sensor``: the reading of ``sensor`` (its ``field``, element ``index``; every element of an array) in
  [``min``, ``max``];
- ``no_contact``: no contact between any geoms of the two entities named in ``between``;
- ``joint``: ``joint``'s position (radians for hinges, metres for slides) in [``min``, ``max``];
- ``finite``: positions, velocities and accelerations stay finite;
- ``no_warnings``: MuJoCo raises no warning during the run;
- ``realtime``: the run's real-time factor (simulated / wall seconds) is at least ``min`` (the one check
  that depends on the machine, not only on the simulation).

Every failure says what was measured, when, and by how much it missed.

How a run is judged against them (:class:`~simrun.scenetest.observer.Observer`, and the preflight
:func:`~simrun.scenetest.observer.check_against`) lives in :mod:`simrun.scenetest.observer`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from simrun.errors import SceneError
from simrun.scene.tomlpos import KeyPath, line_of

KINDS = ("position", "region", "heading", "sensor", "no_contact", "joint", "finite", "no_warnings", "realtime")
_PARAMS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {  # kind: (required, optional)
    "position": (("body", "point", "within"), ()),
    "region": (("body", "min", "max"), ()),
    "heading": (("body", "yaw", "within"), ()),
    "sensor": (("sensor",), ("field", "index", "min", "max")),
    "no_contact": (("between",), ()),
    "joint": (("joint",), ("min", "max")),
    "finite": ((), ()),
    "no_warnings": ((), ()),
    "realtime": (("min",), ()),
}
_COMMON = ("id", "message", "kind", "at", "always", "sometime")
_WHOLE_RUN = ("no_warnings", "realtime")  # no time keys: they judge the whole run
#: Default time of each kind when none is given: the whole run for the first group, else the end.
_ALWAYS_BY_DEFAULT = ("no_contact", "finite")
#: Largest magnitude of a number in an expectation.
MAX_MAGNITUDE = 1e6
#: Most expectations in one file.
MAX_EXPECTATIONS = 1000


@dataclass(frozen=True, slots=True)
class Expectation:
    """One ``[[expect]]`` table, checked.

    Attributes:
        id: Unique in its run (scene and commands file together).
        kind: One of :data:`KINDS`.
        message: What it means, for people.
        mode: ``at``, ``end``, ``always`` or ``sometime``.
        start: Start of the window (``at``: the time), seconds.
        stop: End of the window, seconds (``None``: the end of the run).
        params: The kind's parameters (numbers as floats, points as tuples).
        file: The file it came from (as given).
        line: Its table's line in that file.
    """

    id: str
    kind: str
    message: str
    mode: str
    start: float
    stop: float | None
    params: dict[str, Any] = field(hash=False)
    file: str
    line: int | None

    def where(self) -> str:
        """``FILE:LINE: expect 'ID'`` for messages."""
        return f"{self.file}:{self.line}: expect {self.id!r}" if self.line else f"{self.file}: expect {self.id!r}"


@dataclass(frozen=True, slots=True)
class Outcome:
    """How one expectation fared in one run.

    Attributes:
        id: The expectation's id.
        kind: Its kind.
        message: Its message.
        file: Its file.
        line: Its line.
        passed: Whether it held.
        detail: What was measured, when, and by how much it missed (or the margin it held with).
        time: Simulated time of the observation the detail is about, seconds (``None``: the whole run).
        miss: How far beyond the tolerance, in the kind's unit (``None`` when it passed).
    """

    id: str
    kind: str
    message: str
    file: str
    line: int | None
    passed: bool
    detail: str
    time: float | None
    miss: float | None


def parse_expectations(doc: dict[str, Any], lines: dict[KeyPath, int], path: str) -> list[Expectation]:
    """The ``[[expect]]`` tables of a parsed TOML document (a scene or commands file).

    Args:
        doc: The document (``tomllib``).
        lines: Its key lines (:func:`simrun.scene.tomlpos.key_lines`).
        path: The file, for messages.

    Raises:
        SceneError: A bad table, naming the file, line and key (``scene.toml:40: expect[2] 'home': within: ...``).
    """
    tables = doc.get("expect", [])
    if not isinstance(tables, list):
        raise SceneError("expected an array of tables ([[expect]])", path, "expect", line_of(lines, ("expect",)))
    if len(tables) > MAX_EXPECTATIONS:
        raise SceneError(f"{len(tables)} expectations, over the limit of {MAX_EXPECTATIONS}", path, "expect")
    out: list[Expectation] = []
    for k, table in enumerate(tables):
        out.append(_parse_one(table, k, lines, path))
    seen: dict[str, int] = {}
    for k, e in enumerate(out):
        if e.id in seen:
            raise SceneError(f"duplicate id (also expect[{seen[e.id]}])", path, f"expect[{k}]", e.line, e.id)
        seen[e.id] = k
    return out


def _parse_one(table: Any, k: int, lines: dict[KeyPath, int], path: str) -> Expectation:
    label = table.get("id") if isinstance(table, dict) and isinstance(table.get("id"), str) else None

    def fail(message: str, key: str | None = None) -> SceneError:
        where: KeyPath = ("expect", k, key) if key else ("expect", k)
        text = f"{key}: {message}" if key else message
        return SceneError(text, path, f"expect[{k}]", line_of(lines, where), label)

    if not isinstance(table, dict):
        raise fail("expected a table with id, kind (and message, time, parameters)")
    kind = table.get("kind")
    if not isinstance(kind, str) or kind not in KINDS:
        raise fail(f"expected one of {', '.join(KINDS)}, got {kind!r}", "kind")
    required, optional = _PARAMS[kind]
    known = (*_COMMON, *required, *optional)
    for key in table:
        if key not in known:
            raise fail(f"unknown key for kind {kind!r} (known: {', '.join(known)})", key)
    for key in ("id", *required):
        if key not in table:
            raise fail(f"missing {key!r}; a {kind!r} expectation needs {', '.join(('id', 'kind', *required))}")
    ident = table["id"]
    if not isinstance(ident, str) or not ident or not all(c.isalnum() or c in "_-." for c in ident):
        raise fail(f"expected a non-empty string of letters, digits, '_', '-', '.', got {ident!r}", "id")
    message = table.get("message", "")
    if not isinstance(message, str):
        raise fail(f"expected a string, got {message!r}", "message")
    mode, start, stop = _timing(table, kind, fail)
    params = _params(table, kind, fail)
    line = line_of(lines, ("expect", k))
    return Expectation(ident, kind, message or _describe(kind, params), mode, start, stop, params, path, line)


def _timing(table: dict[str, Any], kind: str, fail: Any) -> tuple[str, float, float | None]:
    given = [key for key in ("at", "always", "sometime") if key in table]
    if kind in _WHOLE_RUN:
        if given:
            raise fail(f"a {kind!r} expectation judges the whole run; remove it", given[0])
        return "always", 0.0, None
    if len(given) > 1:
        raise fail(f"give one of at, always, sometime, not {' and '.join(given)}", given[1])
    if not given:
        return ("always", 0.0, None) if kind in _ALWAYS_BY_DEFAULT else ("end", 0.0, None)
    key = given[0]
    value = table[key]
    if key == "at":
        if value == "end":
            return "end", 0.0, None
        return "at", _time(value, fail, key), None
    if not isinstance(value, list) or len(value) != 2:
        raise fail('expected [start, stop] seconds (stop may be "end")', key)
    start = _time(value[0], fail, key)
    stop = None if value[1] == "end" else _time(value[1], fail, key)
    if stop is not None and stop < start:
        raise fail(f"the window ends ({stop:g} s) before it starts ({start:g} s)", key)
    return key, start, stop


def _time(value: Any, fail: Any, key: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise fail(f'expected a finite number of seconds (or "end"), got {value!r}', key)
    if not 0 <= value <= MAX_MAGNITUDE:
        raise fail(f"must be in [0, {MAX_MAGNITUDE:g}] seconds, got {value!r}", key)
    return float(value)


def _number(value: Any, fail: Any, key: str, positive: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise fail(f"expected a finite number, got {value!r}", key)
    if abs(value) > MAX_MAGNITUDE:
        raise fail(f"magnitude over {MAX_MAGNITUDE:g}, got {value!r}", key)
    if positive and value <= 0:
        raise fail(f"expected a positive number, got {value!r}", key)
    return float(value)


def _vector(value: Any, fail: Any, key: str) -> tuple[float, ...]:
    if not isinstance(value, list) or len(value) not in (2, 3):
        raise fail(f"expected 2 numbers (x, y) or 3 (x, y, z), got {value!r}", key)
    return tuple(_number(v, fail, key) for v in value)


def _name(value: Any, fail: Any, key: str) -> str:
    if not isinstance(value, str) or not value:
        raise fail(f"expected a non-empty name, got {value!r}", key)
    return value


def _params(table: dict[str, Any], kind: str, fail: Any) -> dict[str, Any]:
    p: dict[str, Any] = {}
    if "body" in table:
        p["body"] = _name(table["body"], fail, "body")
    if kind == "position":
        point = table["point"]
        p["point"] = point if point == "start" else _vector(point, fail, "point")
        p["within"] = _number(table["within"], fail, "within", True)
    elif kind == "region":
        low, high = _vector(table["min"], fail, "min"), _vector(table["max"], fail, "max")
        if len(low) != len(high) or any(a > b for a, b in zip(low, high, strict=False)):
            raise fail("min and max need the same number of values, each min <= its max", "max")
        p["min"], p["max"] = low, high
    elif kind == "heading":
        p["yaw"], p["within"] = _number(table["yaw"], fail, "yaw"), _number(table["within"], fail, "within", True)
        if p["within"] >= 180:
            raise fail("a tolerance of 180 degrees or more accepts every heading", "within")
    elif kind in ("sensor", "joint"):
        p[kind] = _name(table[kind], fail, kind)
        if "min" not in table and "max" not in table:
            raise fail(f"a {kind!r} expectation needs min, max or both")
        p["min"] = _number(table["min"], fail, "min") if "min" in table else -math.inf
        p["max"] = _number(table["max"], fail, "max") if "max" in table else math.inf
        if p["min"] > p["max"]:
            raise fail(f"min {p['min']:g} is above max {p['max']:g}", "min")
        if kind == "sensor":
            p["field"] = _name(table["field"], fail, "field") if "field" in table else None
            index = table.get("index")
            if index is not None and (isinstance(index, bool) or not isinstance(index, int) or index < 0):
                raise fail(f"expected an array index >= 0, got {index!r}", "index")
            p["index"] = index
    elif kind == "no_contact":
        pair = table["between"]
        if not isinstance(pair, list) or len(pair) != 2 or not all(isinstance(n, str) and n for n in pair):
            raise fail(f"expected two entity names, got {pair!r}", "between")
        if pair[0] == pair[1]:
            raise fail("name two different entities", "between")
        p["between"] = tuple(pair)
    elif kind == "realtime":
        p["min"] = _number(table["min"], fail, "min", True)
    return p


def _describe(kind: str, p: dict[str, Any]) -> str:
    """A default message."""
    texts: dict[str, Callable[[], str]] = {
        "position": lambda: (
            f"{p.get('body')} within {p.get('within'):g} m of "
            + ("its start" if p.get("point") == "start" else _fmt_vec(p.get("point", ())))
        ),
        "region": lambda: f"{p.get('body')} inside {_fmt_vec(p.get('min', ()))}..{_fmt_vec(p.get('max', ()))}",
        "heading": lambda: f"{p.get('body')} heading {p.get('yaw'):g} +- {p.get('within'):g} degrees",
        "sensor": lambda: f"sensor {p.get('sensor')} in [{p.get('min'):g}, {p.get('max'):g}]",
        "no_contact": lambda: f"no contact between {' and '.join(p.get('between', ()))}",
        "joint": lambda: f"joint {p.get('joint')} in [{p.get('min'):g}, {p.get('max'):g}]",
        "finite": lambda: "the simulation stays finite",
        "no_warnings": lambda: "MuJoCo raises no warning",
        "realtime": lambda: f"real-time factor at least {p.get('min'):g}",
    }
    return texts[kind]()


def _fmt_vec(values: Any) -> str:
    return "(" + ", ".join(f"{v:g}" for v in values) + ")"
