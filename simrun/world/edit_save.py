"""Saving a running world as a scene file, and copying entities between worlds (Save / Load Entities).

:func:`current_scene_text` is :func:`simrun.scene.scene_file.scene_text` with every entity at its pose *now*:
a free body where its joint has taken it, a kinematic body at its mocap pose (welded entities, children
included, keep the pose relative to their parent they were given). Loaded again, the scene compiles to the
running world's model (bodies, geoms, masses) and its bodies start, at rest, where the running ones are (a
robot's wheels and arm joints at their initial angles). With ``state="current"`` the entities keep the poses
they were given (the running model exactly, ``body_pos`` included) and the ``[state]`` table holds where
everything is now: every position, velocity, joint angle, service and sensor continues bit for bit.

:func:`entities_text` writes a selection (the entities named and everything below them, with the assets
they use and the services and sensors bound to them) as a scene file of its own; :func:`load_entities`
inserts such a file into another running world in one edit (:mod:`simrun.world.edit`), under a parent or at
the top. An entity whose parent was not selected is written without it, its pose still relative to that
parent; loaded under a ``parent``, it keeps that pose relative to the new one. Relative file paths are
rewritten for the folder the text is written in, and for the target world's folder when loaded (a path
leaving that folder is refused).
"""

from __future__ import annotations

import os
import tempfile
import tomllib
from pathlib import Path
from typing import Any

import tomli_w

from simrun.errors import SimrunError
from simrun.outfile import write_text
from simrun.scene.tomlpos import read_toml
from simrun.world.edit import (
    Edit,
    EditError,
    _insert_checked,
    check_files,
    current_pose,
    make_entity,
    trial,
)
from simrun.world.edit_carry import _bound_to
from simrun.world.pose import Pose
from simrun.world.registry.conversion import arguments
from simrun.world.registry.tables import REGISTRY, scene_type
from simrun.world.world import World

#: Largest entities file or text :func:`load_entities` reads, bytes.
MAX_TEXT_BYTES = 4 * 1024 * 1024
#: The keys of an entity table before its pose, in the order :func:`simrun.scene.scene_file.scene_text` writes.
_HEAD = ("type", "name", "parent", "free", "kinematic")


def _posed(table: dict[str, Any], pose: Pose) -> dict[str, Any]:
    """``table`` with ``pose`` in its canonical place (after the base keys; none when it is the identity)."""
    out = {k: table[k] for k in _HEAD if k in table}
    if pose != Pose():
        out["pose"] = {"position": list(pose.position), "orientation": list(pose.orientation)}
    out.update({k: v for k, v in table.items() if k not in _HEAD and k != "pose"})
    return out


def current_scene_text(world: World, state: str = "initial", folder: str | Path | None = None) -> str:
    """The scene text of ``world`` with every entity at its current pose (see the module).

    Args:
        world: The running world.
        state: ``initial`` (entities at their current poses, services, sensors, options) or ``current`` (the
            entities as given and the ``[state]`` table: see the module).
        folder: The folder the text is saved in (relative paths rewritten for it); ``None``: as they are.

    Raises:
        SimrunError: As :func:`simrun.scene.scene_file.scene_text`.
    """
    from simrun.scene.scene_file import scene_text

    doc = tomllib.loads(scene_text(world, state, folder))
    if state == "current":  # the [state] table holds where everything is: the model stays the running one's
        return tomli_w.dumps(doc)
    tables = doc.get("entities", [])
    for k, (full, _) in enumerate(world):
        tables[k] = _posed(tables[k], current_pose(world, full))
    return tomli_w.dumps(doc)


def save_world(world: World, path: str | Path, state: str = "initial") -> Path:
    """Write :func:`current_scene_text` to ``path`` (atomically; relative paths rewritten for its folder)."""
    path = Path(path)
    write_text(path, current_scene_text(world, state, path.parent))
    return path


def _selection(world: World, names: list[str]) -> list[str]:
    """The entities named and every one below them, in world order."""
    known = dict(world)
    for name in names:
        if not isinstance(name, str) or name not in known:
            raise EditError(f"no entity named {name!r}", key="names", reason="missing")
    chosen = set(names)
    return [full for full in known if _bound_to(full, chosen)]


def entities_text(world: World, names: list[str], folder: str | Path | None = None) -> str:
    """A scene text holding the selected entities at their current poses, their assets, services and sensors.

    Names in the text are relative to the selection: an entity whose parent is not selected is at the top
    (``robot/arm`` selected alone is written as ``arm``, its children ``arm/...``).

    Raises:
        EditError: An unknown name (field ``names``), or an empty selection.
    """
    if not isinstance(names, list) or not names:
        raise EditError("name at least one entity to save", key="names")
    chosen = _selection(world, names)
    doc = tomllib.loads(current_scene_text(world, "initial", folder))
    tables = dict(zip([full for full, _ in world], doc.get("entities", []), strict=True))
    roots = {full: world.entity(full).parent for full in chosen if world.entity(full).parent not in chosen}

    def rename(full: str) -> str:
        root = next(r for r in roots if full == r or full.startswith(r + "/"))
        above = roots[root]
        return full[len(above) + 1 :] if above else full

    out: dict[str, Any] = {}
    entities = []
    for full in chosen:
        table = dict(tables[full])
        if full in roots:
            table.pop("parent", None)
        elif "parent" in table:
            table["parent"] = rename(table["parent"])
        entities.append(table)
    used = {str(getattr(world.entity(f), k, "")) for f in chosen for k in ("asset", "visual_mesh")}
    assets = {name: path for name, path in doc.get("assets", {}).items() if name in used}
    if assets:
        out["assets"] = assets
    out["entities"] = entities
    services = [dict(s, entity=rename(s["entity"])) for s in doc.get("services", []) if s.get("entity") in chosen]
    if services:
        out["services"] = services
    sensors = []
    for spec in doc.get("sensors", []):
        binds = REGISTRY[spec["type"]].binds
        target = spec.get(binds)
        owner = next((f for f in chosen if target == f), None) or next(
            (f for f in chosen if isinstance(target, str) and target.startswith(f + "/")), None
        )
        if owner is not None:
            sensors.append(dict(spec, **{binds: rename(owner) + target[len(owner) :]}))
    if sensors:
        out["sensors"] = sensors
    return tomli_w.dumps(out)


def save_entities(world: World, names: list[str], path: str | Path) -> Path:
    """Write :func:`entities_text` to ``path`` (atomically; relative paths rewritten for its folder)."""
    path = Path(path)
    write_text(path, entities_text(world, names, path.parent))
    return path


def load_entities(world: World, path: str | Path, parent: str | None = None) -> dict[str, list[str]]:
    """Insert the entities (and assets, services, sensors) of an entities or scene file into ``world``.

    Relative paths in the file are relative to its folder; ``[world]`` and ``[state]`` are not read.

    Returns:
        ``{"entities": [full names], "services": ["TYPE:ENTITY"], "sensors": [names]}``: what was added.

    Raises:
        SceneError: The file cannot be read or is not TOML (its line named).
        EditError: As :func:`load_entities_text`.
    """
    path = Path(path)
    doc, _ = read_toml(path, "entities file", MAX_TEXT_BYTES)
    return _load(world, doc, parent, path.parent)


def load_entities_text(
    world: World, text: str, parent: str | None = None, folder: str | Path | None = None
) -> dict[str, list[str]]:
    """:func:`load_entities` of a text (relative paths relative to ``folder``; ``None``: the world's folder).

    Raises:
        EditError: Text over :data:`MAX_TEXT_BYTES` or not TOML (field ``text``), an unknown key, a refused
            table (``entities[K].KEY``, ``services[K]``, ``sensors[K]``), a name taken, an asset name taken by
            another file, a path leaving the world's folder, or MuJoCo refused the world (nothing is added).
    """
    if len(text.encode("utf-8", "replace")) > MAX_TEXT_BYTES:
        raise EditError(f"larger than {MAX_TEXT_BYTES} bytes", key="text")
    with tempfile.TemporaryDirectory(prefix="simrun-entities-") as tmp:
        file = Path(tmp) / "entities.toml"
        file.write_text(text, encoding="utf-8")
        try:
            doc, _ = read_toml(file, "entities text", MAX_TEXT_BYTES, name="text")
        except SimrunError as exc:
            raise EditError(str(exc).removeprefix("text: "), key="text") from None
    return _load(world, doc, parent, Path(folder) if folder is not None else world.base_dir)


def _load(world: World, doc: dict[str, Any], parent: str | None, folder: Path) -> dict[str, list[str]]:
    for key in doc:
        if key not in ("world", "assets", "entities", "services", "sensors", "state", "test", "expect"):
            raise EditError("unknown key (known: assets, entities, services, sensors)", key=key)
    if parent is not None and parent not in dict(world):
        raise EditError(f"no entity named {parent!r}", key="parent", reason="missing")
    base = world.base_dir.resolve()

    def move(value: str) -> str:
        if Path(value).is_absolute():
            return value
        return Path(os.path.relpath((folder / value).resolve(), base)).as_posix()

    def renamed(name: str) -> str:
        return f"{parent}/{name}" if parent else name

    tables, services, sensors = (doc.get(k, []) for k in ("entities", "services", "sensors"))
    for key, value in (("entities", tables), ("services", services), ("sensors", sensors)):
        if not isinstance(value, list) or not all(isinstance(t, dict) for t in value):
            raise EditError("expected an array of tables", key=key)
    from simrun.world.edit import MAX_BATCH

    if len(tables) > MAX_BATCH:
        raise EditError(f"{len(tables)} entities in one edit, over the limit of {MAX_BATCH}", key="entities")
    assets = doc.get("assets", {})
    if not isinstance(assets, dict) or not all(isinstance(v, str) for v in assets.values()):
        raise EditError("expected a table of asset names to .mbin file paths", key="assets")
    added: list[str] = []
    with Edit(world, "entities") as edit:
        for name, file in assets.items():
            file = move(file)
            if world.assets.get(name, file) != file:
                message = f"the world's asset {name!r} is {world.assets[name]!r}, not {file!r}; rename one"
                raise EditError(message, key=f"assets.{name}", reason="conflict")
            world.assets[name] = file
        for k, table in enumerate(tables):
            prefix = f"entities[{k}]"
            table = _moved(dict(table), move, set(world.assets))
            table["parent"] = renamed(table["parent"]) if table.get("parent") else parent
            if table["parent"] is None:
                del table["parent"]
            entity = make_entity(table, prefix)
            check_files(world, entity, prefix)
            added.append(_insert_checked(world, entity, prefix))
        edit.commit(fresh=added)
        bound = []
        for k, binding in enumerate(services):
            binding = dict(binding, entity=renamed(str(binding.get("entity"))))
            bound.append(_bind(world, binding, f"services[{k}]"))
        named = []
        for k, spec in enumerate(sensors):
            named.append(_sense(world, spec, renamed, f"sensors[{k}]"))
        trial(world, "sensors")
    return {"entities": added, "services": bound, "sensors": named}


def _moved(table: dict[str, Any], move: Any, assets: set[str]) -> dict[str, Any]:
    """An entity table with its file paths moved (a named asset is no path)."""
    from simrun.world.edit import FILE_KEYS

    for key in FILE_KEYS:
        value = table.get(key)
        if isinstance(value, str) and value and not (key in ("asset", "visual_mesh") and value in assets):
            table[key] = move(value)
    if isinstance(table.get("package_dirs"), dict):
        table["package_dirs"] = {p: move(v) if isinstance(v, str) else v for p, v in table["package_dirs"].items()}
    return table


def _bind(world: World, binding: dict[str, Any], prefix: str) -> str:
    try:
        kind = scene_type("services", binding.get("type")).name
    except SimrunError as exc:
        raise EditError(str(exc), key=f"{prefix}.type") from None
    entity = binding["entity"]
    if entity not in dict(world):
        raise EditError(f"no entity named {entity!r}", key=f"{prefix}.entity")
    if any(s.get("type") == kind and s.get("entity") == entity for s in world.services):
        raise EditError(f"a {kind} is already bound to {entity!r}", key=prefix, reason="conflict")
    from simrun.world.edit import edit_fail

    arguments("services", kind, binding, edit_fail(prefix, entity))
    world.services.append(binding)
    try:
        world.service(kind, entity)
    except SimrunError as exc:
        raise EditError(exc.message or str(exc), key=prefix, entity=entity) from None
    return f"{kind}:{entity}"


def _sense(world: World, spec: dict[str, Any], renamed: Any, prefix: str) -> str:
    try:
        kind = scene_type("sensors", spec.get("type")).name
    except SimrunError as exc:
        raise EditError(str(exc), key=f"{prefix}.type") from None
    binds = REGISTRY[kind].binds
    spec = dict(spec, **{binds: renamed(str(spec.get(binds)))})
    name = spec.get("name")
    if not isinstance(name, str) or name in world.sensors:
        raise EditError(f"a sensor needs a unique 'name', got {name!r}", key=f"{prefix}.name", reason="conflict")
    try:
        world.add_sensor(spec)
    except (SimrunError, TypeError, ValueError) as exc:
        raise EditError(str(exc), key=prefix, entity=name) from None
    return name
