"""TOML scene files (docs/scene-format.md): a world, its assets, entities and service bindings in one file.

``load_scene(path)`` validates every key and value against the entity classes and names the file and key
path in errors (``entities[3].pose.position: expected 3 numbers, got 2``); ``save_scene(world, path)``
writes a canonical file, so save, load, save gives identical text.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
import types
import typing
from pathlib import Path
from typing import Any

import tomli_w

from simrun.arm import KukaLBR3, LynxL6
from simrun.drive import BoeBot, DifferentialDrive, IRobotCreate, LegoNxtTribot, Pioneer3DX
from simrun.entity import Entity, Material
from simrun.environment import Camera, Ground, HeightField, Light, Sky
from simrun.errors import EntityError, SceneError
from simrun.mesh_entity import MeshEntity
from simrun.outfile import write_text
from simrun.pose import Pose
from simrun.shapes import Box, Capsule, Cylinder, Sphere
from simrun.urdf_robot import UrdfRobot
from simrun.world import World, WorldOptions

ENTITY_TYPES: dict[str, type[Entity]] = {
    cls.TYPE: cls
    for cls in (
        Box,
        Sphere,
        Capsule,
        Cylinder,
        MeshEntity,
        Ground,
        HeightField,
        Sky,
        Light,
        Camera,
        DifferentialDrive,
        BoeBot,
        Pioneer3DX,
        IRobotCreate,
        LegoNxtTribot,
        KukaLBR3,
        LynxL6,
        UrdfRobot,
    )
}
_TOP = ("world", "assets", "entities", "services", "sensors")
_BASE = ("type", "name", "parent", "pose", "free", "kinematic")


def load_scene(path: str | Path) -> World:
    """Read a scene file into a new :class:`World` (relative paths resolve against the file's folder).

    Raises:
        SceneError: Unreadable TOML, an unknown key, a value of the wrong type, an unknown entity type,
            a duplicate name or unknown parent, a service bound to a missing entity.
    """
    path = Path(path)
    name = str(path)
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise SceneError(f"cannot be read: {exc.strerror}", name) from None
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"not valid TOML: {exc}", name) from None
    _known(doc, _TOP, name, "")
    options = _world_options(doc.get("world", {}), name)
    world = World(options, base_dir=path.parent)
    assets = doc.get("assets", {})
    if not isinstance(assets, dict) or not all(isinstance(v, str) for v in assets.values()):
        raise SceneError("expected a table of asset names to file paths", name, "assets")
    world.assets.update(assets)
    entities = doc.get("entities", [])
    if not isinstance(entities, list):
        raise SceneError("expected an array of tables ([[entities]])", name, "entities")
    for k, table in enumerate(entities):
        key = f"entities[{k}]"
        entity = _entity(table, name, key)
        if isinstance(entity, MeshEntity) and entity.asset not in world.assets and not entity.asset.endswith(".mbin"):
            message = f"asset {entity.asset!r} is not in [assets] and is not an .mbin path"
            raise SceneError(message, name, f"{key}.asset")
        try:
            world.insert(entity)
        except EntityError as exc:
            raise SceneError(str(exc), name, key) from None
    services = doc.get("services", [])
    if not isinstance(services, list):
        raise SceneError("expected an array of tables ([[services]])", name, "services")
    for k, service in enumerate(services):
        key = f"services[{k}]"
        if not isinstance(service, dict) or not isinstance(service.get("type"), str):
            raise SceneError("a service needs a 'type' string", name, key)
        if not isinstance(service.get("entity"), str):
            raise SceneError("a service needs an 'entity' string naming the entity it drives", name, key)
        if service["entity"] not in dict(world):
            raise SceneError(f"no entity named {service['entity']!r}", name, f"{key}.entity")
        world.services.append(dict(service))
    sensors = doc.get("sensors", [])
    if not isinstance(sensors, list):
        raise SceneError("expected an array of tables ([[sensors]])", name, "sensors")
    for k, spec in enumerate(sensors):
        try:
            world.add_sensor(dict(spec) if isinstance(spec, dict) else spec)
        except (EntityError, TypeError, ValueError) as exc:
            raise SceneError(str(exc), name, f"sensors[{k}]") from None
    return world


def scene_text(world: World) -> str:
    """The canonical TOML text of a world (what :func:`save_scene` writes)."""
    doc: dict[str, Any] = {
        "world": {
            "timestep": world.options.timestep,
            "gravity": list(world.options.gravity),
            "integrator": world.options.integrator,
        }
    }
    if world.assets:
        doc["assets"] = dict(sorted(world.assets.items()))
    entities = []
    for _, entity in world:
        table: dict[str, Any] = {"type": entity.TYPE, "name": entity.name}
        if entity.parent:
            table["parent"] = entity.parent
        if entity.free:
            table["free"] = True
        if entity.kinematic:
            table["kinematic"] = True
        if entity.pose != Pose():
            table["pose"] = {"position": list(entity.pose.position), "orientation": list(entity.pose.orientation)}
        fresh = {f.name: f for f in dataclasses.fields(entity)}
        for key, value in entity.parameters().items():
            spec = fresh[key]
            factory = spec.default_factory
            default = factory() if callable(factory) else spec.default
            if value is None or value == default:
                continue
            table[key] = _plain(value)
        entities.append(table)
    if entities:
        doc["entities"] = entities
    if world.services:
        doc["services"] = [dict(s) for s in world.services]
    if world.sensor_specs:
        doc["sensors"] = [dict(s) for s in world.sensor_specs]
    return tomli_w.dumps(doc)


def save_scene(world: World, path: str | Path) -> None:
    """Write the world as a scene file (atomically)."""
    write_text(Path(path), scene_text(world))


def _plain(value: Any) -> Any:
    if isinstance(value, Material):
        return dataclasses.asdict(value)
    if isinstance(value, tuple):
        return [_plain(v) for v in value]
    if isinstance(value, list):
        return [_plain(v) for v in value]
    return value


def _known(table: Any, keys: tuple[str, ...] | list[str], name: str, prefix: str) -> None:
    if not isinstance(table, dict):
        raise SceneError("expected a table", name, prefix or None)
    for key in table:
        if key not in keys:
            where = f"{prefix}.{key}" if prefix else key
            raise SceneError(f"unknown key (known: {', '.join(keys)})", name, where)


def _world_options(table: Any, name: str) -> WorldOptions:
    _known(table, ("timestep", "gravity", "integrator"), name, "world")
    values: dict[str, Any] = {}
    if "timestep" in table:
        values["timestep"] = _number(table["timestep"], name, "world.timestep", positive=True)
    if "gravity" in table:
        values["gravity"] = _vector(table["gravity"], 3, name, "world.gravity")
    if "integrator" in table:
        values["integrator"] = table["integrator"]
    try:
        return WorldOptions(**values)
    except EntityError as exc:
        raise SceneError(str(exc), name, "world") from None


def _entity(table: Any, name: str, key: str) -> Entity:
    if not isinstance(table, dict):
        raise SceneError("expected a table", name, key)
    kind = table.get("type")
    if kind not in ENTITY_TYPES:
        raise SceneError(f"unknown entity type {kind!r} (known: {', '.join(ENTITY_TYPES)})", name, f"{key}.type")
    cls = ENTITY_TYPES[kind]
    hints = typing.get_type_hints(cls)
    fields = [f.name for f in dataclasses.fields(cls)]
    params = [f for f in fields if f not in _BASE]
    _known(table, list(_BASE) + params, name, key)
    if not isinstance(table.get("name"), str):
        raise SceneError("every entity needs a 'name' string", name, f"{key}.name")
    values: dict[str, Any] = {"name": table["name"]}
    if "parent" in table:
        values["parent"] = _typed(table["parent"], str, name, f"{key}.parent")
    for flag in ("free", "kinematic"):
        if flag in table:
            values[flag] = _typed(table[flag], bool, name, f"{key}.{flag}")
    if "pose" in table:
        pose = table["pose"]
        _known(pose, ("position", "orientation"), name, f"{key}.pose")
        position = _vector(pose.get("position", [0, 0, 0]), 3, name, f"{key}.pose.position")
        orientation = _vector(pose.get("orientation", [1, 0, 0, 0]), 4, name, f"{key}.pose.orientation")
        try:
            values["pose"] = Pose(position, orientation)  # type: ignore[arg-type]
        except ValueError as exc:
            raise SceneError(str(exc), name, f"{key}.pose") from None
    for param in params:
        if param in table:
            values[param] = _convert(table[param], hints[param], name, f"{key}.{param}")
    try:
        return cls(**values)
    except (EntityError, ValueError, TypeError) as exc:
        raise SceneError(str(exc), name, key) from None


def _convert(value: Any, hint: Any, name: str, key: str) -> Any:
    """Check a TOML value against a field's type annotation and convert it (lists to tuples...)."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (types.UnionType, typing.Union):
        options = [a for a in args if a is not type(None)]
        return _convert(value, options[0], name, key)
    if hint is Material:
        _known(value, ("restitution", "dynamic_friction", "static_friction"), name, key)
        coefficients = {k: _number(v, name, f"{key}.{k}") for k, v in value.items()}
        try:
            return Material(**coefficients)
        except EntityError as exc:
            raise SceneError(str(exc), name, key) from None
    if origin is tuple:
        numbers = _vector(value, len(args), name, key)
        return tuple(int(v) if a is int else v for v, a in zip(numbers, args, strict=True))
    if origin is list:
        if not isinstance(value, list) or not all(isinstance(row, list) for row in value):
            raise SceneError("expected an array of arrays of numbers", name, key)
        return [[_number(v, name, f"{key}[{r}][{c}]") for c, v in enumerate(row)] for r, row in enumerate(value)]
    if hint is float:
        return _number(value, name, key)
    return _typed(value, hint, name, key)


def _typed(value: Any, kind: type, name: str, key: str) -> Any:
    if not isinstance(value, kind) or (kind is not bool and isinstance(value, bool)):
        raise SceneError(f"expected {kind.__name__}, got {type(value).__name__} {value!r}", name, key)
    return value


def _number(value: Any, name: str, key: str, positive: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise SceneError(f"expected a number, got {value!r}", name, key)
    if positive and value <= 0:
        raise SceneError(f"expected a positive number, got {value!r}", name, key)
    return float(value)


def _vector(value: Any, n: int, name: str, key: str) -> tuple[float, ...]:
    if not isinstance(value, list) or len(value) != n:
        got = f"{len(value)}" if isinstance(value, list) else type(value).__name__
        raise SceneError(f"expected {n} numbers, got {got}", name, key)
    return tuple(_number(v, name, f"{key}[{k}]") for k, v in enumerate(value))
