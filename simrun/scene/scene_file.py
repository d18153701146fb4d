"""TOML scene files (docs/scene-format.md): a world, its assets, entities and service bindings in one file.

``load_scene(path)`` validates every key and value against the entity classes and names the file and key
path in errors (``entities[3].pose.position: expected 3 numbers, got 2``); ``save_scene(world, path)``
writes a canonical file, so save, load, save gives identical text.
"""

from __future__ import annotations

import dataclasses
import math
import os
from pathlib import Path
from typing import Any

import tomli_w

from meshtool.formats import suffix
from simrun.entities.mesh_entity import MeshEntity
from simrun.errors import EntityError, Origin, SceneError, SimrunError, did_you_mean
from simrun.outfile import write_text
from simrun.robots.urdf_robot import UrdfRobot
from simrun.safeio import FileReadError, check_regular
from simrun.scene.state import KEYS, apply_state, state_table
from simrun.scene.tomlpos import KeyPath, line_of, read_toml
from simrun.world.entity import Entity, Material
from simrun.world.pose import Pose
from simrun.world.registry.conversion import (
    MAX_HEIGHT_CELLS,
    MAX_MAGNITUDE,
    Fail,
    arguments,
    convert,
    key_text,
    unknown_message,
)
from simrun.world.registry.key_schema import known_keys
from simrun.world.registry.tables import REGISTRY, names, scene_type
from simrun.world.world import MAX_TIMESTEP, MIN_TIMESTEP, World, WorldOptions

#: Entity types by name (:mod:`simrun.world.registry`, the one list of scene types).
ENTITY_TYPES = names("entities")
_TOP = ("world", "assets", "entities", "services", "sensors", "state", "test", "expect")  # test, expect: simrun test
#: Largest scene file read, bytes.
MAX_SCENE_BYTES = 16 * 1024 * 1024
#: Most entities in one scene file (the world's body limit, :data:`simrun.world.world.MAX_BODIES`, also holds).
MAX_ENTITIES = 10_000
#: Highest sensor sampling rate accepted from a scene, Hz.
MAX_SENSOR_RATE = 10_000.0
# MAX_MAGNITUDE and MAX_HEIGHT_CELLS, the limits of every value, are the registry's (its ``arguments``), named here too.
__all__ = ["ENTITY_TYPES", "MAX_HEIGHT_CELLS", "MAX_MAGNITUDE", "load_scene", "save_scene", "scene_text"]
#: Entity parameters that name a file (relative to the scene's folder), checked at load.
_FILE_FIELDS = ("texture", "image", "urdf", "asset", "visual_mesh")
_GROUPS = ("entities", "services", "sensors")


def load_scene(path: str | Path) -> World:
    """Read a scene file into a new :class:`World` (relative paths resolve against the file's folder).

    Every error names the file, the line and the key, e.g.
    ``scene.toml:14: entities[3] 'box': mass: expected a positive number, got -100``; errors found later,
    when the world is built, carry the same ``FILE:LINE: entities[3] 'box'`` prefix (``World.origins``).

    Raises:
        SceneError: An unreadable or non-UTF-8 file, bad TOML, an unknown key, a value of the wrong type,
            range or a non-finite number, an unknown entity, service or sensor type, a duplicate name or
            unknown parent, a missing file, or a service or sensor bound to a missing entity.
    """
    return _Loader(Path(path)).load()


class _Loader:
    """One scene file being loaded: its parsed document and the line of every key."""

    def __init__(self, path: Path) -> None:
        self.path, self.name = path, str(path)
        self.lines: dict[KeyPath, int] = {}
        self.labels: dict[KeyPath, str] = {}

    def error(self, message: str, where: KeyPath = (), line_at: KeyPath | None = None) -> SceneError:
        """A :class:`SceneError` at a key path (``("entities", 3, "mass")``) with its line (or ``line_at``'s)."""
        line = line_of(self.lines, line_at or where) if (line_at or where) else None
        if len(where) >= 2 and where[0] in _GROUPS and isinstance(where[1], int):
            rest = key_text(where[2:])
            text = f"{rest}: {message}" if rest else message
            key = f"{where[0]}[{where[1]}]"
            return SceneError(text, self.name, key, line, self.labels.get(where[:2]))
        return SceneError(message, self.name, key_text(where) or None, line)

    def fail(self, where: KeyPath) -> Fail:
        """The :class:`~simrun.world.registry.conversion.Fail` of the table at ``where``.

        Its errors name this file and line.
        """

        def fail(message: str, path: KeyPath, line_at: KeyPath | None = None) -> SceneError:
            return self.error(message, (*where, *path), None if line_at is None else (*where, *line_at))

        return fail

    def load(self) -> World:
        doc = self.read()
        _known(doc, _TOP, self, ())
        options = self.world_options(doc.get("world", {}))
        world = World(options, base_dir=self.path.parent)
        self.assets(doc.get("assets", {}), world)
        entities = doc.get("entities", [])
        if not isinstance(entities, list):
            raise self.error("expected an array of tables ([[entities]])", ("entities",))
        if len(entities) > MAX_ENTITIES:
            raise self.error(f"{len(entities)} entities, over the limit of {MAX_ENTITIES}", ("entities", MAX_ENTITIES))
        for k, table in enumerate(entities):
            where: KeyPath = ("entities", k)
            if isinstance(table, dict) and isinstance(table.get("name"), str):
                self.labels[where] = table["name"]
            entity = _entity(table, self, where)
            self.files(entity, world, where)
            full = world.full_name(entity)
            try:
                world.insert(entity)
            except EntityError as exc:
                raise self.error(str(exc).removeprefix(f"{full!r}: "), where) from None
            world.origins[full] = self.origin(where, where, entity.name)
            for key in table:  # build errors that start with a parameter's name point at its line
                world.origins[f"{full}#{key}"] = self.origin(where, (*where, key), entity.name)
        self.services(doc.get("services", []), world)
        self.sensors(doc.get("sensors", []), world)
        if "state" in doc:
            _known(doc["state"], KEYS, self, ("state",))
            try:
                apply_state(world, doc["state"], lambda message, key: self.error(message, ("state", key)))
            except EntityError as exc:
                raise self.error(str(exc), ("state",)) from None
        return world

    def read(self) -> dict[str, Any]:
        doc, self.lines = read_toml(self.path, "scene", MAX_SCENE_BYTES, self.name)
        return doc

    def world_options(self, table: Any) -> WorldOptions:
        _known(table, ("timestep", "gravity", "integrator"), self, ("world",))
        values: dict[str, Any] = {}
        fail = self.fail(("world",))
        if "timestep" in table:
            step = convert(table["timestep"], float, fail, ("timestep",))
            if not MIN_TIMESTEP <= step <= MAX_TIMESTEP:
                message = f"must be in [{MIN_TIMESTEP:g}, {MAX_TIMESTEP:g}] seconds, got {step:g}"
                raise self.error(message, ("world", "timestep"))
            values["timestep"] = step
        if "gravity" in table:
            values["gravity"] = convert(table["gravity"], tuple[float, float, float], fail, ("gravity",))
        if "integrator" in table:
            values["integrator"] = convert(table["integrator"], str, fail, ("integrator",))
        try:
            return WorldOptions(**values)
        except EntityError as exc:
            raise self.error(str(exc), ("world",)) from None

    def assets(self, assets: Any, world: World) -> None:
        if not isinstance(assets, dict):
            raise self.error("expected a table of asset names to .mbin file paths", ("assets",))
        for key, value in assets.items():
            if not isinstance(value, str):
                raise self.error(f"expected a file path string, got {value!r}", ("assets", key))
            self.check_file(world, value, ("assets", key))
        world.assets.update(assets)

    def files(self, entity: Entity, world: World, where: KeyPath) -> None:
        """Refuse, at load, file parameters that name no regular file (missing, a folder, a FIFO...)."""
        if (
            isinstance(entity, MeshEntity)
            and entity.asset not in world.assets
            and not entity.asset.endswith(suffix("mbin"))
        ):
            raise self.error(f"{entity.asset!r} is not in [assets] and is not an .mbin path", (*where, "asset"))
        for key in _FILE_FIELDS:
            value = getattr(entity, key, None)
            if isinstance(value, str) and value and not (key in ("asset", "visual_mesh") and value in world.assets):
                self.check_file(world, value, (*where, key))
        if isinstance(entity, UrdfRobot):
            for package, folder in entity.package_dirs.items():
                if not (world.base_dir / folder).is_dir():
                    raise self.error(f"{folder!r} is not a folder", (*where, "package_dirs", package))

    def check_file(self, world: World, value: str, where: KeyPath) -> None:
        try:
            check_regular(world.base_dir / value, "file")
        except FileReadError as exc:
            reason = str(exc).split(": file ", 1)[-1]
            raise self.error(f"{value!r} {reason}", where) from None

    def services(self, services: Any, world: World) -> None:
        if not isinstance(services, list):
            raise self.error("expected an array of tables ([[services]])", ("services",))
        entities = dict(world)
        for k, service in enumerate(services):
            where: KeyPath = ("services", k)
            if isinstance(service, dict) and isinstance(service.get("type"), str):
                self.labels[where] = service["type"]
            if not isinstance(service, dict):
                raise self.error("expected a table", where)
            kind = service.get("type")
            if not isinstance(kind, str):
                raise self.error("a service needs a 'type' string", where)
            self.labels[where] = kind
            if kind not in names("services"):
                known = ", ".join(names("services"))
                raise self.error(f"unknown service type {kind!r} (known: {known})", (*where, "type"))
            arguments("services", kind, service, self.fail(where))  # checked here, converted when bound
            if not isinstance(service.get("entity"), str):
                raise self.error("a service needs an 'entity' string naming the entity it drives", where)
            if service["entity"] not in entities:
                raise self.error(f"no entity named {service['entity']!r}", (*where, "entity"))
            if any(s["type"] == kind and s["entity"] == service["entity"] for s in world.services):
                raise self.error(f"a {kind} is already bound to {service['entity']!r}", where)
            world.services.append(dict(service))
            world.origins[f"services:{kind}:{service['entity']}"] = self.origin(where, where)

    def sensors(self, sensors: Any, world: World) -> None:
        if not isinstance(sensors, list):
            raise self.error("expected an array of tables ([[sensors]])", ("sensors",))
        entities = dict(world)
        for k, spec in enumerate(sensors):
            where: KeyPath = ("sensors", k)
            if not isinstance(spec, dict):
                raise self.error("expected a table", where)
            if isinstance(spec.get("name"), str):
                self.labels[where] = spec["name"]
            for key, value in spec.items():
                problem = _bad_value(value, 2**63 if key == "seed" else MAX_MAGNITUDE)
                if key == "rate" and isinstance(value, int | float) and value > MAX_SENSOR_RATE:
                    problem = f"must be at most {MAX_SENSOR_RATE:g} Hz, got {value!r}"
                if problem:
                    raise self.error(problem, (*where, key))
            kind = spec.get("type")
            if not isinstance(kind, str) or kind not in names("sensors"):  # a list or table is unhashable
                known = ", ".join(names("sensors"))
                raise self.error(f"unknown sensor type {kind!r} (known: {known})", (*where, "type"))
            target_key = REGISTRY[kind].binds
            keys = known_keys("sensors", kind)
            unknown = next((key for key in spec if key not in keys), None)
            if unknown is not None:
                message = f"sensor {spec.get('name')!r}: unknown key {unknown!r} (known: {', '.join(keys)})"
                raise self.error(message + did_you_mean(unknown, keys), (*where, unknown))
            arguments("sensors", kind, spec, self.fail(where))  # checked at the key's line; World.add_sensor again
            target = spec.get(target_key)
            owner = target.rsplit("/", 1)[0] if isinstance(target, str) and target_key == "camera" else target
            if isinstance(target, str) and target not in entities and owner not in entities:
                raise self.error(f"no entity named {target!r}", (*where, target_key))
            try:
                world.add_sensor(dict(spec))
            except (EntityError, TypeError, ValueError) as exc:
                raise self.error(str(exc), where) from None
            world.origins[f"sensors:{spec['name']}"] = self.origin(where, where)

    def origin(self, where: KeyPath, line_at: KeyPath, label: str | None = None) -> Origin:
        """Where the item at ``where`` (``("entities", 3)``) came from, at the line of ``line_at``."""
        line = line_of(self.lines, line_at) or None
        return Origin(self.name, line, f"{where[0]}[{where[1]}]", label or self.labels.get(where))


def scene_text(world: World, state: str = "initial", folder: str | Path | None = None) -> str:
    """The canonical TOML text of a world (what :func:`save_scene` writes).

    Args:
        world: The world.
        state: ``initial`` (the entities as inserted) or ``current`` (also a ``[state]`` table: the full
            integration state and every service's and sensor's snapshot, so a reloaded world continues).
        folder: The folder the text will be saved in: relative file paths (assets, textures, images,
            URDFs, package folders) are rewritten relative to it; ``None`` keeps them as they are.

    Raises:
        SimrunError: An unknown ``state``, or a sensor constructed directly (not with ``World.add_sensor``),
            whose parameters a scene cannot hold.
    """
    if state not in ("initial", "current"):
        raise SimrunError(f"state must be 'initial' or 'current', got {state!r}")
    move = _mover(world.base_dir, Path(folder) if folder is not None else None)
    options = world.options  # timestep and integrator only where set explicitly: a robot's own stay its own
    doc: dict[str, Any] = {"world": {"gravity": list(options.gravity)}}
    for key in ("timestep", "integrator"):
        if key in options.explicit:
            doc["world"][key] = getattr(options, key)
    if world.assets:
        doc["assets"] = {name: move(file) for name, file in sorted(world.assets.items())}
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
            named_asset = key in ("asset", "visual_mesh") and value in world.assets
            if key in _FILE_FIELDS and isinstance(value, str) and not named_asset:
                value = move(value)
            elif key == "package_dirs" and isinstance(value, dict):
                value = {package: move(path) for package, path in value.items()}
            table[key] = _plain(value)
        entities.append(table)
    if entities:
        doc["entities"] = entities
    services = _services(world)
    if services:
        doc["services"] = services
    _refuse_unsaved_sensors(world)
    if world.sensor_specs:
        doc["sensors"] = [dict(s) for s in world.sensor_specs]
    if state == "current":
        doc["state"] = state_table(world)
    return tomli_w.dumps(doc)


def save_scene(world: World, path: str | Path, state: str = "initial") -> None:
    """Write the world as a scene file (atomically), its relative paths rewritten for the file's folder.

    Args:
        world: The world.
        path: The scene file to write.
        state: ``initial`` or ``current`` (see :func:`scene_text`): with ``current`` a reloaded world
            continues the motion bit for bit (the services and sensors of the scene are bound and restored).
    """
    path = Path(path)
    write_text(path, scene_text(world, state, path.parent))


def _mover(base: Path, folder: Path | None) -> Any:
    """A function rewriting a path relative to ``base`` into one relative to ``folder`` (absolute stay)."""

    def move(value: str) -> str:
        if folder is None or Path(value).is_absolute():
            return value
        target = (base / value).resolve()
        try:
            return Path(os.path.relpath(target, folder.resolve())).as_posix()
        except ValueError:  # another drive (Windows)
            return target.as_posix()

    return move


def _services(world: World) -> list[dict[str, Any]]:
    """The scene's bindings, then services created in code (constructed directly), in creation order."""
    services = [dict(s) for s in world.services]
    bound = {(s.get("type"), s.get("entity")) for s in services}
    classes = {kind: REGISTRY[kind].load() for kind in names("services")}
    for controller in world.controllers:
        for kind, cls in classes.items():
            entity = getattr(controller, "name", None)
            if isinstance(controller, cls) and (kind, entity) not in bound:
                services.append({"type": kind, "entity": entity})
                bound.add((kind, entity))
    return services


def _refuse_unsaved_sensors(world: World) -> None:
    from simrun.sensors.base import Sensor

    named = {id(s) for s in world.sensors.values()}
    for controller in world.controllers:
        if isinstance(controller, Sensor) and id(controller) not in named:
            kind = type(controller).__name__
            raise SimrunError(
                f"a {kind} sensor on {controller.entity!r} was constructed directly, so its parameters are unknown; "
                f"create it with world.add_sensor({{'type': '{kind}', 'name': ..., 'entity': ...}}) to save it"
            )


def _plain(value: Any) -> Any:
    if hasattr(value, "to_scene"):  # a value that writes itself (an arm's segments)
        return value.to_scene()
    if isinstance(value, Material):
        return dataclasses.asdict(value)
    if isinstance(value, tuple):
        return [_plain(v) for v in value]
    if isinstance(value, list):
        return [_plain(v) for v in value]
    return value


def _bad_value(value: Any, limit: float) -> str | None:
    """Why a sensor parameter is refused (a non-finite number or one over ``limit`` anywhere in it), or ``None``."""
    if isinstance(value, float) and not math.isfinite(value):
        return f"expected a finite number, got {value!r}"
    if isinstance(value, int | float) and not isinstance(value, bool) and abs(value) > limit:
        return f"must be at most {limit:g} in magnitude, got {value!r}"
    if isinstance(value, list):
        return next((p for p in (_bad_value(v, limit) for v in value) if p), None)
    if isinstance(value, dict):
        return next((p for p in (_bad_value(v, limit) for v in value.values()) if p), None)
    return None


def _known(table: Any, keys: tuple[str, ...] | list[str], loader: _Loader, where: KeyPath) -> None:
    if not isinstance(table, dict):
        raise loader.error("expected a table", where)
    for key in table:
        if key not in keys:
            raise loader.error(unknown_message(key, keys), (*where, key))


def _entity(table: Any, loader: _Loader, where: KeyPath) -> Entity:
    if not isinstance(table, dict):
        raise loader.error("expected a table", where)
    kind = table.get("type")
    known = ", ".join(ENTITY_TYPES)
    if "type" not in table:  # a misspelt key is named at its own line, with the closest known key
        typo = next((k for k in table if did_you_mean(k, ("type",))), None)
        if typo is not None:
            message = f"unknown key (an entity needs 'type', one of: {known}){did_you_mean(typo, ('type',))}"
            raise loader.error(message, (*where, typo))
        raise loader.error(f"missing key 'type' (one of: {known})", where)
    if not isinstance(kind, str) or kind not in ENTITY_TYPES:  # a list or table is unhashable
        hint = did_you_mean(kind, ENTITY_TYPES) if isinstance(kind, str) else ""
        raise loader.error(f"unknown entity type {kind!r} (known: {known}){hint}", (*where, "type"))
    cls: type[Entity] = scene_type("entities", kind).load()
    _known(table, known_keys("entities", kind), loader, where)
    if not isinstance(table.get("name"), str):
        raise loader.error("every entity needs a 'name' string", (*where, "name"))
    values = arguments("entities", kind, table, loader.fail(where))
    if kind == "Camera":
        _check_camera(values, loader, where)
    try:
        return cls(**values)
    except (EntityError, ValueError, TypeError) as exc:
        raise loader.error(str(exc), where) from None


def _check_camera(values: dict[str, Any], loader: _Loader, where: KeyPath) -> None:
    eye, target = values.get("eye"), values.get("target")
    if (eye is None) != (target is None):
        raise loader.error("give both eye and target (or neither, and a pose)", (*where, "eye" if eye else "target"))
    if eye is not None and target is not None and math.dist(eye, target) < 1e-9:
        message = f"eye and target are the same point {list(eye)}; the camera would look nowhere"
        raise loader.error(message, (*where, "target"))
