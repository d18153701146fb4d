"""Seeds and variations of ``simrun test``: what each run changes in its scene, drawn reproducibly.

``--seeds 0:100`` (half-open), ``--seeds 7`` or ``--seeds 1,5,9`` list the seeds. A run's seed decides:

1. sensor noise: sensor *k* (in ``[[sensors]]`` order) draws from a generator seeded with ``seed + k``,
   as ``simrun play --seed``;
2. the pose jitter of the scene's ``[test.jitter]`` table (``ENTITY = { xy = M, yaw = DEG }``: x and y
   offsets uniform in [-M, M] metres, yaw uniform in [-DEG, DEG] degrees, added to the scene's pose);
3. the draws of every ``--vary`` distribution.

Every draw comes from its own generator, ``numpy.random.default_rng([seed, crc32(purpose)])``, so adding
a ``--vary`` key never changes the jitter or another key's draws. Nothing else is random: without noise,
jitter or distributions, every seed runs the same simulation.

``--vary KEY=SPEC``: ``START:STOP:COUNT`` is a grid (``COUNT`` evenly spaced values, both ends included;
every grid value is a separate variation, crossed with the other grids and every seed); ``uniform(A,B)``,
``normal(MEAN,SD)`` and ``choice(V1,V2,...)`` draw one value per run from the seed; a plain number sets
the value. KEY is ``NAME.PARAMETER``: ``NAME`` an entity or a ``[[sensors]]`` name; ``PARAMETER`` a number
parameter of it (``mass``, ``wheel_friction``, ``stall_torque``, ``no_load_speed``, ``noise``, ``rate``...),
``x``/``y``/``z`` (its pose position, metres), ``yaw`` (its pose, degrees about +Z, replacing the
orientation), ``friction`` (its contact material's friction) or ``material.restitution``.
"""

from __future__ import annotations

import copy
import dataclasses
import itertools
import math
import re
import zlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from simrun.errors import UsageError

#: Most runs one invocation may plan: the ceiling of ``--max-runs``, of ``--seeds`` and of a grid's COUNT.
MAX_RUNS = 1_000_000
#: Default of ``simrun test --max-runs``: most runs of one scene (seeds x the values of every grid).
DEFAULT_MAX_RUNS = 10_000
#: Largest seed accepted (seeds are non-negative).
MAX_SEED = 2**31 - 1
_DIST = re.compile(r"^(uniform|normal|choice)\((.*)\)$")


#: Looks up the class of an entity type name (``None`` when unknown).
EntityClass = Callable[[str], Any]


class VaryError(UsageError):
    """A ``--seeds`` or ``--vary`` value that cannot be used (a usage error)."""


@dataclass(frozen=True, slots=True)
class Axis:
    """One ``--vary`` key.

    Attributes:
        key: ``NAME.PARAMETER``.
        kind: ``grid``, ``uniform``, ``normal``, ``choice`` or ``value``.
        values: The grid values, the distribution's parameters, the choices, or the one value.
    """

    key: str
    kind: str
    values: tuple[float, ...]


def parse_seeds(text: str) -> list[int]:
    """``A:B`` (A to B-1), ``N`` or ``N1,N2,...`` as a list of seeds.

    Raises:
        VaryError: Not of these forms, negative, over :data:`MAX_SEED`, or empty.
    """
    try:
        if ":" in text:
            start, stop = (int(p) for p in text.split(":"))
            seeds = list(range(start, stop)) if stop - start <= MAX_RUNS else []
            if stop - start > MAX_RUNS:
                raise VaryError(f"--seeds {text}: more than {MAX_RUNS} seeds")
        else:
            seeds = [int(p) for p in text.split(",")]
    except ValueError:
        raise VaryError(f"--seeds {text!r}: expected START:STOP, N or N1,N2,... (integers)") from None
    if not seeds:
        raise VaryError(f"--seeds {text}: no seeds (STOP must be above START)")
    if any(not 0 <= s <= MAX_SEED for s in seeds):
        raise VaryError(f"--seeds {text}: seeds must be in [0, {MAX_SEED}]")
    if len(set(seeds)) != len(seeds):
        raise VaryError(f"--seeds {text}: a seed is listed twice")
    return seeds


def parse_vary(text: str) -> Axis:
    """One ``KEY=SPEC`` (see the module's description).

    Raises:
        VaryError: A malformed key or spec, a non-finite number, a grid of no values, a negative SD.
    """
    key, sep, spec = text.partition("=")
    key, spec = key.strip(), spec.strip().replace(" ", "")
    if not sep or not re.fullmatch(r"[A-Za-z0-9_][A-Za-z0-9_.-]*\.[A-Za-z_][A-Za-z0-9_.]*", key):
        raise VaryError(
            f"--vary {text!r}: expected NAME.PARAMETER=SPEC, e.g. box.mass=1:5:5 or boebot.x=normal(1,0.01)"
        )
    match = _DIST.match(spec)
    if match:
        kind = match.group(1)
        values = _numbers(match.group(2).split(","), text)
        if kind in ("uniform", "normal") and len(values) != 2:
            raise VaryError(f"--vary {text!r}: {kind} takes 2 numbers")
        if kind == "uniform" and values[0] > values[1]:
            raise VaryError(f"--vary {text!r}: uniform(A,B) needs A <= B")
        if kind == "normal" and values[1] < 0:
            raise VaryError(f"--vary {text!r}: the standard deviation must be >= 0")
        return Axis(key, kind, values)
    parts = spec.split(":")
    if len(parts) == 3:
        start, stop = _numbers(parts[:2], text)
        try:
            count = int(parts[2])
        except ValueError:
            raise VaryError(f"--vary {text!r}: COUNT must be an integer") from None
        if not 1 <= count <= MAX_RUNS:
            raise VaryError(f"--vary {text!r}: COUNT must be in [1, {MAX_RUNS}]")
        grid = np.linspace(start, stop, count) if count > 1 else np.array([start])
        return Axis(key, "grid", tuple(_round(float(v), 12) for v in grid))
    if len(parts) == 1:
        return Axis(key, "value", _numbers(parts, text))
    raise VaryError(
        f"--vary {text!r}: expected START:STOP:COUNT, uniform(A,B), normal(MEAN,SD), choice(...) or a number"
    )


def _numbers(parts: list[str], text: str) -> tuple[float, ...]:
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        raise VaryError(f"--vary {text!r}: {', '.join(parts)} are not all numbers") from None
    if not values or not all(math.isfinite(v) for v in values):
        raise VaryError(f"--vary {text!r}: numbers must be finite")
    return values


def _round(value: float, digits: int) -> float:
    return float(f"{value:.{digits}g}")


def run_count(seeds: int, axes: list[Axis]) -> int:
    """Runs of one scene: ``seeds`` times the number of values of every grid (nothing is expanded)."""
    count = seeds
    for axis in axes:
        if axis.kind == "grid":
            count *= len(axis.values)
    return count


def check_run_count(seeds: list[int], axes: list[Axis], limit: int) -> None:
    """Refuse a run matrix (seeds x grid values, for one scene) over ``limit`` before anything is planned.

    Raises:
        VaryError: Over the limit; the message names each factor and ``--max-runs``.
    """
    count = run_count(len(seeds), axes)
    if count <= limit:
        return
    factors = [f"{len(seeds)} seed(s)"] + [f"{len(a.values)} values of {a.key}" for a in axes if a.kind == "grid"]
    raise VaryError(
        f"{' x '.join(factors)} = {count} runs per scene, more than --max-runs {limit} "
        f"(use fewer seeds or grid values, or raise --max-runs, at most {MAX_RUNS})"
    )


def variations(axes: list[Axis]) -> list[dict[str, float]]:
    """The fixed values of each variation: the cross product of the grids (one empty variation without).

    Raises:
        VaryError: More than :data:`MAX_RUNS` variations (counted before any is made).
    """
    if run_count(1, axes) > MAX_RUNS:
        raise VaryError(f"--vary: {run_count(1, axes)} grid variations, more than {MAX_RUNS}")
    keys = [a.key for a in axes if a.kind in ("grid", "value")]
    grids = [a.values for a in axes if a.kind in ("grid", "value")]
    out = [dict(zip(keys, combo, strict=True)) for combo in itertools.product(*grids)]
    return out or [{}]


def _rng(seed: int, purpose: str) -> np.random.Generator:
    return np.random.default_rng([seed, zlib.crc32(purpose.encode("utf-8"))])


def draw(axes: list[Axis], seed: int) -> dict[str, float]:
    """The values the distributions of ``axes`` give for ``seed`` (9 significant digits, used as written)."""
    out: dict[str, float] = {}
    for axis in axes:
        rng = _rng(seed, f"vary:{axis.key}")
        if axis.kind == "uniform":
            out[axis.key] = _round(float(rng.uniform(axis.values[0], axis.values[1])), 9)
        elif axis.kind == "normal":
            out[axis.key] = _round(float(rng.normal(axis.values[0], axis.values[1])), 9)
        elif axis.kind == "choice":
            out[axis.key] = axis.values[int(rng.integers(len(axis.values)))]
    return out


def jitter(table: dict[str, dict[str, float]], seed: int) -> dict[str, float]:
    """Pose offsets of ``[test.jitter]`` for ``seed``: ``{"ENTITY.x": dx, "ENTITY.y": dy, "ENTITY.yaw": dyaw}``."""
    out: dict[str, float] = {}
    for name in sorted(table):
        rng = _rng(seed, f"jitter:{name}")
        xy, yaw = table[name].get("xy", 0.0), table[name].get("yaw", 0.0)
        dx, dy, dyaw = (float(v) for v in rng.uniform(-1.0, 1.0, 3))
        if xy:
            out[f"{name}.x"], out[f"{name}.y"] = _round(dx * xy, 9), _round(dy * xy, 9)
        if yaw:
            out[f"{name}.yaw"] = _round(dyaw * yaw, 9)
    return out


def check_key(doc: dict[str, Any], key: str, entity_types: EntityClass) -> None:
    """Refuse a ``--vary`` key that names nothing variable in the scene document ``doc``.

    Raises:
        VaryError: An unknown name or a parameter that is not a number of it, with the known ones.
    """
    _target(doc, key, entity_types)


def _target(doc: dict[str, Any], key: str, types: EntityClass) -> tuple[str, int, list[str]]:
    name, _, rest = key.partition(".")
    parts = rest.split(".")
    entities = doc.get("entities", [])
    for k, table in enumerate(entities):
        if isinstance(table, dict) and table.get("name") == name:
            cls = types(str(table.get("type")))
            if parts[0] in ("x", "y", "z", "yaw") and len(parts) == 1:
                return "entities", k, parts
            fields = {f.name: f for f in dataclasses.fields(cls)} if cls is not None else {}
            material = parts == ["friction"] or (len(parts) == 2 and parts[0] == "material" and parts[1] in _MATERIAL)
            if material and "material" in fields:
                return "entities", k, parts
            if len(parts) == 1 and parts[0] in fields and str(fields[parts[0]].type) in _NUMBER_TYPES:
                return "entities", k, parts
            numbers = sorted(n for n, f in fields.items() if str(f.type) in _NUMBER_TYPES)
            extra = ["x", "y", "z", "yaw", *(["friction", "material.restitution"] if "material" in fields else [])]
            raise VaryError(
                f"--vary {key}: {name!r} ({table.get('type')}) has no number parameter {rest!r} "
                f"(variable: {', '.join(extra + numbers)})"
            )
    for k, table in enumerate(doc.get("sensors", [])):
        if isinstance(table, dict) and table.get("name") == name:
            numbers = sorted({"noise", "rate"} | {n for n, v in table.items() if _is_number(v)})
            if len(parts) == 1 and parts[0] in numbers and parts[0] != "seed":
                return "sensors", k, parts
            shown = ", ".join(n for n in numbers if n != "seed")
            raise VaryError(f"--vary {key}: sensor {name!r} has no number parameter {rest!r} (variable: {shown})")
    names = [t.get("name") for t in (*entities, *doc.get("sensors", [])) if isinstance(t, dict)]
    raise VaryError(f"--vary {key}: no entity or sensor named {name!r} (names: {', '.join(map(str, names))})")


_NUMBER_TYPES = ("float", "float | None", "int", "int | None")


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


_MATERIAL = ("dynamic_friction", "static_friction", "restitution")


def apply(doc: dict[str, Any], values: dict[str, float], offsets: dict[str, float], types: EntityClass) -> Any:
    """A copy of the scene document with ``values`` set and pose ``offsets`` added (see the module).

    Raises:
        VaryError: A key that names nothing variable.
    """
    out = copy.deepcopy(doc)
    for key, value in values.items():
        group, k, parts = _target(out, key, types)
        table = out[group][k]
        if group == "sensors":
            table[parts[0]] = value
        elif parts[0] in ("x", "y", "z"):
            position = _pose(table)["position"]
            position["xyz".index(parts[0])] = value
        elif parts[0] == "yaw":
            _pose(table)["orientation"] = _yaw_quat(value)
        elif parts[0] == "friction":
            material = table.setdefault("material", {})
            material["dynamic_friction"] = material["static_friction"] = value
        elif parts[0] == "material":
            table.setdefault("material", {})[parts[1]] = value
        else:
            table[parts[0]] = value
    for key, offset in offsets.items():
        group, k, parts = _target(out, key, types)
        pose = _pose(out[group][k])
        if parts[0] == "yaw":
            pose["orientation"] = _quat_mul(_yaw_quat(offset), [float(q) for q in pose["orientation"]])
        else:
            i = "xyz".index(parts[0])
            pose["position"][i] = _round(float(pose["position"][i]) + offset, 12)
    return out


def _pose(table: dict[str, Any]) -> dict[str, Any]:
    pose: dict[str, Any] = table.setdefault("pose", {})
    pose["position"] = [float(v) for v in pose.get("position", [0.0, 0.0, 0.0])]
    pose.setdefault("orientation", [1.0, 0.0, 0.0, 0.0])
    return pose


def _yaw_quat(degrees: float) -> list[float]:
    half = math.radians(degrees) / 2
    return [math.cos(half), 0.0, 0.0, math.sin(half)]


def _quat_mul(a: list[float], b: list[float]) -> list[float]:
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return [
        w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
        w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
        w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
        w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
    ]
