"""Editing a running world: insert, change and remove entities, services and sensors, teleport and push bodies.

Every edit goes from a table (the same table a scene file's ``[[entities]]``, ``[[services]]`` or
``[[sensors]]`` holds) through the registry's one route (:func:`simrun.world.registry.conversion.arguments`), then the
world is built again from its entities into a new ``MjSpec`` and compiled (``spec.compile()``) *beside* the
running model. Only when MuJoCo and simrun accept it is the new model swapped in
(:meth:`~simrun.world.world.World.adopt`), with the state of the running one carried over by name
(:func:`carry_state`): simulation time, every joint's ``qpos``/``qvel``/warm start/applied force, actuators'
``ctrl``/``act``, mocap poses, applied body wrenches, equality activations, and the bodies' derived frames
as the last step left them (:func:`carry_kinematics`). Services and sensors are the
same objects afterwards (their state and their noise generators' streams untouched) unless bound to an entity
that was changed (then built again from their tables and restored from their own snapshots); a service is
bound to the new model at once and restored from its snapshot (met at its next tick, a new model would be a
restart at time 0 to it). A refused edit leaves the
world exactly as it was (the same ``MjModel`` and ``MjData`` objects, byte for byte) and raises
:class:`EditError` naming the field (``entity.mass``, ``pose.position[1]``).

What is fresh after an edit: an inserted entity starts at its pose at rest; an entity given a new ``pose``
(or ``free``) starts there at rest, its children with it; every other body keeps its state bit for bit.

:func:`teleport` moves a free or kinematic body without a recompile.
Services and sensors (add, change, remove) are :mod:`simrun.world.edit_bindings`, pushes
:mod:`simrun.world.edit_push`, saving and loading (the whole world, a selection of entities)
:mod:`simrun.world.edit_save`.
"""

from __future__ import annotations

import dataclasses
import tomllib
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from simrun.errors import EntityError, SimrunError
from simrun.safeio import FileReadError, check_regular
from simrun.world.edit_carry import _bound_to, bind_now, carry_kinematics, carry_state, rebuild_sensor, rebuild_service
from simrun.world.edit_errors import EditError as EditError  # re-exported: simrun.world.edit.EditError
from simrun.world.entity import Entity
from simrun.world.pose import Pose
from simrun.world.registry.conversion import Fail, KeyPath, arguments, convert, key_text
from simrun.world.registry.tables import REGISTRY, scene_type
from simrun.world.world import World

#: Most entities one :func:`insert` may add.
MAX_BATCH = 100
#: Entity keys that name a file (relative to the world's folder, the scene root); ``package_dirs`` names folders.
FILE_KEYS = ("texture", "image", "urdf", "asset", "visual_mesh", "file")
#: Keys of a table an edit cannot change (remove the entity and insert it again instead).
FIXED = ("type", "name", "parent")


def _join(prefix: str, path: KeyPath) -> str:
    rest = key_text(path)
    if not prefix:
        return rest
    return f"{prefix}[{rest}]" if rest.startswith("[") else f"{prefix}.{rest}" if rest else prefix


def edit_fail(prefix: str = "", entity: str | None = None) -> Fail:
    """A :class:`~simrun.world.registry.conversion.Fail`.

    Its errors are :class:`EditError` with the field ``PREFIX.KEY``.
    """

    def fail(message: str, path: KeyPath, line_at: KeyPath | None = None) -> Exception:
        return EditError(message, key=_join(prefix, path) or None, entity=entity)

    return fail


# --- what the world holds -------------------------------------------------------------------------------------


def entity_tables(world: World) -> dict[str, dict[str, Any]]:
    """Every entity's table as a scene file holds it (:func:`simrun.scene.scene_file.scene_text`), by full name."""
    from simrun.scene.scene_file import scene_text

    doc = tomllib.loads(scene_text(world))
    return {full: table for (full, _), table in zip(world, doc.get("entities", []), strict=True)}


def world_pose(world: World, full: str) -> list[float] | None:
    """An entity's body pose now, world frame: ``[x, y, z, qw, qx, qy, qz]`` (m); ``None``: it has no body."""
    if not world.entity(full).HAS_BODY:
        return None
    body = world.data.body(full)
    return [*map(float, body.xpos), *map(float, body.xquat)]


def current_pose(world: World, full: str) -> Pose:
    """An entity's pose now, relative to its parent: a free body's joint, a kinematic body's mocap pose.

    Other entities are welded to their parent: their pose is the one they were given.
    """
    entity = world.entity(full)
    model, data = world.model, world.data
    if entity.HAS_BODY and entity.kinematic:
        mocap = int(model.body(full).mocapid[0])
        return Pose(tuple(map(float, data.mocap_pos[mocap])), tuple(map(float, data.mocap_quat[mocap])))  # type: ignore[arg-type]
    adr = _free_qpos(model, full) if entity.HAS_BODY else None
    if adr is not None:
        q = data.qpos[adr : adr + 7]
        return Pose((float(q[0]), float(q[1]), float(q[2])), (float(q[3]), float(q[4]), float(q[5]), float(q[6])))
    return entity.pose


def _free_qpos(model: mujoco.MjModel, body: str) -> int | None:
    """The ``qpos`` address of a body's free joint (``None``: it has none)."""
    try:
        b = model.body(body)
    except KeyError:
        return None
    for j in range(int(b.jntadr[0]), int(b.jntadr[0]) + int(b.jntnum[0])):
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
            return int(model.jnt_qposadr[j])
    return None


def describe(world: World, full: str) -> dict[str, Any]:
    """One entity: ``{"name", "type", "parent", "values" (its table), "pose" (world), "services", "sensors"}``."""
    entity = world.entity(full)
    table = entity_tables(world)[full]
    return _description(world, full, entity, table)


def _description(world: World, full: str, entity: Entity, table: dict[str, Any]) -> dict[str, Any]:
    return {
        "name": full,
        "type": entity.TYPE,
        "parent": entity.parent,
        "values": {k: v for k, v in table.items() if k not in ("type",)},
        "pose": world_pose(world, full),
        "services": [s["type"] for s in world.services if s.get("entity") == full],
        "sensors": [n for n, s in world.sensors.items() if s.entity == full],
    }


def describe_all(world: World) -> list[dict[str, Any]]:
    """:func:`describe` of every entity, in world order."""
    tables = entity_tables(world)
    return [_description(world, full, entity, tables[full]) for full, entity in world]


# --- the transaction ------------------------------------------------------------------------------------------


class Edit:
    """One edit of a running world: keep what was there, change it, compile beside, swap or roll back.

    Use as ``with Edit(world) as edit: ...; edit.commit(fresh, rebuilt)``; an exception inside (or a
    :meth:`commit` that fails) restores the world exactly as it was: entities, services, sensors, controllers,
    the model and the state (the same objects).

    Args:
        world: The world, compiled here when it is not yet.
        field: The field named by a refusal of the build as a whole (MuJoCo's compile errors).
    """

    def __init__(self, world: World, field: str | None = None) -> None:
        self.world, self.field = world, field
        self.model, self.data = world.model, world.data
        self.entities = dict(world)
        self.options = world.options
        self.services = [dict(s) for s in world.services]
        self.bound = dict(world._bound)
        self.sensors = dict(world.sensors)
        self.specs = [dict(s) for s in world.sensor_specs]
        self.controllers = list(world.controllers)
        self.assets = dict(world.assets)
        #: Every bound service's snapshot now (services restore from it after the model changes, or a rollback).
        self.snapshots = {key: service.snapshot() for key, service in world._bound.items()}
        self.done = False

    def __enter__(self) -> Edit:
        return self

    def __exit__(self, kind: Any, exc: Any, tb: Any) -> None:
        if exc is not None or not self.done:
            self.rollback()

    def rollback(self) -> None:
        """Put everything back as it was when the edit began."""
        w = self.world
        w.options = self.options
        w.set_entities(self.entities)
        w.adopt(None, self.model, self.data)
        w.services[:] = self.services
        w._bound.clear()
        w._bound.update(self.bound)
        w.sensors.clear()
        w.sensors.update(self.sensors)
        w.sensor_specs[:] = self.specs
        w.controllers[:] = self.controllers
        w.assets.clear()
        w.assets.update(self.assets)
        for key, service in self.bound.items():  # bound to the old model again, as they were
            bind_now(service, self.model)
            service.restore(self.snapshots[key])
        w.reschedule()

    def commit(self, fresh: Iterable[str] = (), rebuilt: Iterable[str] = ()) -> None:
        """Compile the edited entities beside the running model, carry the state over, and swap.

        Args:
            fresh: Entities (full names) whose bodies, and their children's, start at their pose at rest.
            rebuilt: Entities whose bound services and sensors are built again (and restored from their
                snapshots); every other service is bound to the new model and restored.

        Raises:
            EditError: simrun or MuJoCo refused the edited world (everything is rolled back).
        """
        w = self.world
        try:
            spec = w.build_spec()
        except SimrunError as exc:
            raise EditError(exc.message or str(exc), key=self.field or exc.key, entity=exc.entity) from None
        try:
            model = spec.compile()
        except ValueError as exc:
            raise EditError(f"MuJoCo refused the edited world: {exc}", key=self.field) from None
        data = mujoco.MjData(model)
        carry_state(self.model, self.data, model, data, set(fresh))
        w.adopt(spec, model, data)
        mujoco.mj_forward(model, data)
        carry_kinematics(self.model, self.data, model, data, set(fresh))
        rebuilt = set(rebuilt)

        # a service meeting a new model takes it for a restart at time 0 (a DriveService zeroes its odometry, a
        # JointService forgets what it holds), which an edit is not: each is bound now and restored; one bound
        # to a changed entity is built again (its robot's parameters may have changed)
        for (kind, entity), service in list(w._bound.items()):
            snapshot = self.snapshots.get((kind, entity), service.snapshot())
            if _bound_to(entity, rebuilt):
                rebuild_service(w, kind, entity, snapshot)
            else:
                bind_now(service, model)
                service.restore(snapshot)
        if rebuilt:
            for name, spec_table in [(s["name"], s) for s in w.sensor_specs]:
                if _bound_to(spec_table.get(REGISTRY[spec_table["type"]].binds), rebuilt):
                    rebuild_sensor(w, name, dict(spec_table))
        trial(w, self.field)
        self.done = True


def trial(world: World, field: str | None = None) -> None:
    """Create every bound service and take one trial reading of every sensor, leaving no trace.

    :meth:`World.check_bindings`, its refusal as an :class:`EditError`. A camera's trial frame makes its
    renderer for the new model (most of a second for a GL context) now, inside the edit, where the server's
    edit budget counts it, rather than at its next sample; the sample then reuses it.

    Raises:
        EditError: A binding that does not fit the edited world.
    """
    try:
        world.check_bindings()
    except SimrunError as exc:
        raise EditError(f"a binding does not fit the edited world: {exc.message or exc}", key=field) from None
    world.reschedule()


# --- entities -------------------------------------------------------------------------------------------------


def make_entity(table: Any, prefix: str = "entity") -> Entity:
    """An entity from a scene table (``{"type": "Box", "name": ..., ...}``), through the registry's one route.

    Raises:
        EditError: Not a table, an unknown type, no name, or a key or value refused (the field named).
    """
    if not isinstance(table, dict):
        raise EditError(f"expected a table of an entity's keys, got {type(table).__name__}", key=prefix or None)
    kind = table.get("type")
    try:
        registered = scene_type("entities", kind)
    except EntityError as exc:
        raise EditError(str(exc), key=_join(prefix, ("type",))) from None
    name = table.get("name")
    if not isinstance(name, str):
        raise EditError("every entity needs a 'name' string", key=_join(prefix, ("name",)))
    values = arguments("entities", registered.name, table, edit_fail(prefix, name))
    try:
        entity: Entity = registered.load()(**values)
    except (EntityError, ValueError, TypeError) as exc:
        text = exc.message if isinstance(exc, SimrunError) and exc.message else str(exc)
        raise EditError(text, key=prefix or None, entity=name) from None
    return entity


def check_files(world: World, entity: Entity, prefix: str = "entity", keys: Iterable[str] | None = None) -> None:
    """Refuse file parameters that leave the world's folder (the scene root) or name no regular file.

    ``keys``: only these (the keys an edit gives; a file the scene itself named is the scene's business).
    """
    root = world.base_dir.resolve()
    wanted = set(FILE_KEYS if keys is None else keys)
    for key in FILE_KEYS:
        value = getattr(entity, key, None) if key in wanted else None
        if not isinstance(value, str) or not value or (key in ("asset", "visual_mesh") and value in world.assets):
            continue
        _inside(root, value, _join(prefix, (key,)), entity.name, folder=False)
    for package, folder in (getattr(entity, "package_dirs", None) or {}).items() if "package_dirs" in wanted else ():
        _inside(root, folder, _join(prefix, ("package_dirs", package)), entity.name, folder=True)


def _inside(root: Path, value: str, field: str, entity: str, folder: bool) -> None:
    target = (root / value).resolve()
    if not target.is_relative_to(root):
        raise EditError(f"{value!r} is outside the scene's folder {str(root)!r}; not read", key=field, entity=entity)
    if folder:
        if not target.is_dir():
            raise EditError(f"{value!r} is not a folder", key=field, entity=entity)
        return
    try:
        check_regular(target, "file")
    except FileReadError as exc:
        raise EditError(f"{value!r} {str(exc).split(': file ', 1)[-1]}", key=field, entity=entity) from None


def _insert_checked(world: World, entity: Entity, prefix: str) -> str:
    """``World.insert`` (its name, parent and kinematic-child rules), its refusal as an :class:`EditError`."""
    try:
        world.insert(entity)
    except EntityError as exc:
        text = str(exc)
        key = "name" if ("already exists" in text or "must match" in text) else "parent"
        if "either kinematic or free" in text:
            key = "kinematic"
        reason = "conflict" if "already exists" in text else "invalid"
        raise EditError(text, key=_join(prefix, (key,)), entity=entity.name, reason=reason) from None
    return world.full_name(entity)


def insert(world: World, tables: dict[str, Any] | list[dict[str, Any]], parent: str | None = None) -> list[str]:
    """Insert entities from their scene tables (one, or a list of at most :data:`MAX_BATCH`), in one recompile.

    Args:
        world: The running world.
        tables: ``{"type": "Box", "name": "crate", "dimensions": [...], "pose": {...}, "free": true}`` (the keys
            of :func:`type_schema`), or a list of them (a later one may name an earlier one as its ``parent``).
        parent: Full name of the entity the tables without a ``parent`` go under (``None``: the world).

    Returns:
        The full names inserted.

    Raises:
        EditError: A refused table (field ``entity.KEY``, or ``entities[K].KEY`` for a list), a name taken, an
            unknown parent, a kinematic child, a file outside the scene's folder, or MuJoCo refused the world.
    """
    single = isinstance(tables, dict)
    items = [tables] if isinstance(tables, dict) else tables
    if not isinstance(items, list):
        raise EditError("expected a table or a list of tables", key="entities")
    if len(items) > MAX_BATCH:
        raise EditError(f"{len(items)} entities in one edit, over the limit of {MAX_BATCH}", key="entities")
    with Edit(world, "entity" if single else "entities") as edit:
        added = []
        for k, table in enumerate(items):
            prefix = "entity" if single else f"entities[{k}]"
            if parent is not None and isinstance(table, dict):
                table = {**table, "parent": f"{parent}/{table['parent']}" if table.get("parent") else parent}
            entity = make_entity(table, prefix)
            check_files(world, entity, prefix)
            added.append(_insert_checked(world, entity, prefix))
        edit.commit(fresh=added)
    return added


def _merge(table: dict[str, Any], changes: dict[str, Any]) -> dict[str, Any]:
    """``table`` with ``changes``: a table-valued key (``pose``, ``material``, ``limits``) merged one level down."""
    out = dict(table)
    for key, value in changes.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = {**out[key], **value}
        else:
            out[key] = value
    return out


def change(world: World, name: str, changes: dict[str, Any]) -> None:
    """Change an entity's keys (``pose``, ``mass``, ``dimensions``, ``color``, ``material``, ``free``...).

    ``changes`` holds the keys to set, as a scene table writes them; a table-valued key may give some of its
    fields (``{"material": {"dynamic_friction": 0.3}}``, ``{"pose": {"position": [1, 0, 0.1]}}``). The entity
    is built again through the registry with its other keys as they were. A new ``pose`` (relative to the
    parent) or ``free`` puts the entity there at rest; otherwise every body keeps its state. Services and
    sensors bound to it are built again and restored (their state and noise streams continue).

    Raises:
        EditError: No such entity (``name``, missing), a key that cannot change (``type``, ``name``,
            ``parent``), a refused value (the key named), or MuJoCo refused the world.
    """
    entity = _entity(world, name)
    if not isinstance(changes, dict) or not changes:
        raise EditError("expected a table of the keys to change", key="changes")
    for key in changes:
        if key in FIXED:
            raise EditError(f"{key} cannot change; remove the entity and insert it again", key=key, entity=name)
    table = _merge(entity_tables(world)[name], changes)
    if entity.parent:
        table["parent"] = entity.parent
    new = make_entity(table, "")
    check_files(world, new, "", keys=changes)
    with Edit(world) as edit:
        before = list(edit.entities)
        index = before.index(name)
        world.set_entities({n: edit.entities[n] for n in before[:index]})
        _insert_checked(world, new, "")
        rest = dict(world)
        rest.update({n: edit.entities[n] for n in before[index + 1 :]})
        world.set_entities(rest)
        moved = "pose" in changes or "free" in changes or "kinematic" in changes
        edit.commit(fresh=[name] if moved else [], rebuilt=[name])


def _entity(world: World, name: Any, key: str = "name") -> Entity:
    """The entity called ``name``, or an EditError (404) naming the request field ``key`` and the known names."""
    if not isinstance(name, str) or name not in dict(world):
        known = ", ".join(n for n, _ in world) or "none"
        raise EditError(f"no entity named {name!r} (entities: {known[:300]})", key=key, reason="missing")
    return world.entity(name)


def remove(world: World, name: str) -> dict[str, list[str]]:
    """Remove an entity, its children, and the services and sensors bound to them.

    Returns:
        ``{"entities": [...], "services": ["TYPE:ENTITY"...], "sensors": [...]}``: what went.

    Raises:
        EditError: No such entity, or what is left does not build (a camera mounted on it...).
    """
    _entity(world, name)
    with Edit(world, "name") as edit:
        gone = [n for n, _ in world if n == name or n.startswith(name + "/")]
        world.remove(name)
        dropped = set(gone)
        services = [s for s in world.services if _bound_to(s.get("entity"), dropped)]
        for binding in services:
            service = world._bound.pop((binding["type"], binding["entity"]), None)
            world.controllers[:] = [c for c in world.controllers if c is not service]
        world.services[:] = [s for s in world.services if not _bound_to(s.get("entity"), dropped)]
        sensors = [s["name"] for s in world.sensor_specs if _bound_to(s.get(REGISTRY[s["type"]].binds), dropped)]
        for sensor_name in sensors:
            sensor = world.sensors.pop(sensor_name)
            world.controllers[:] = [c for c in world.controllers if c is not sensor]
        world.sensor_specs[:] = [s for s in world.sensor_specs if s.get("name") not in sensors]
        edit.commit()
    return {"entities": gone, "services": [f"{s['type']}:{s['entity']}" for s in services], "sensors": sensors}


def set_gravity(world: World, gravity: Any) -> None:
    """Change the world's gravity (m/s^2, 3 numbers), keeping every body's state.

    Raises:
        EditError: Not 3 finite numbers (field ``gravity``).
    """
    values = convert(gravity, tuple[float, float, float], edit_fail(""), ("gravity",))
    with Edit(world, "gravity") as edit:
        options = dataclasses.replace(world.options, gravity=values)
        object.__setattr__(options, "explicit", edit.options.explicit)  # replace() passes the defaults as given
        world.options = options
        edit.commit()


# --- moving ---------------------------------------------------------------------------------------------------


def teleport(
    world: World, name: str, position: Any, orientation: Any = None, keep_velocity: bool = False
) -> dict[str, Any]:
    """Move an entity to a pose relative to its parent (the world for top-level entities).

    A free body's joint or a kinematic body's mocap pose is set at once (no recompile; every other body
    untouched; velocity zeroed unless ``keep_velocity``); any other entity is welded to its parent, so its
    ``pose`` changes (:func:`change`, a recompile). ``orientation`` ``None`` keeps the current one.

    Returns:
        ``{"name", "pose": world pose [x, y, z, qw, qx, qy, qz], "recompiled": bool}``.

    Raises:
        EditError: No such entity, no body, or a pose that is no rigid transform (field ``position`` or
            ``orientation``).
    """
    entity = _entity(world, name)
    if not entity.HAS_BODY:
        raise EditError(f"{name!r} is a {entity.TYPE}, which has no body; change its keys instead", key="name")
    fail = edit_fail("", name)
    where = convert(position, tuple[float, float, float], fail, ("position",))
    now = current_pose(world, name)
    turn = (
        now.orientation
        if orientation is None
        else convert(orientation, tuple[float, float, float, float], fail, ("orientation",))
    )
    try:
        pose = Pose(where, turn)
    except EntityError as exc:
        raise EditError(str(exc), key="orientation", entity=name) from None
    model, data = world.model, world.data
    adr = _free_qpos(model, name)
    if entity.kinematic:
        world.set_pose(name, pose.position, pose.orientation)
    elif adr is not None and not entity.parent:
        data.qpos[adr : adr + 3] = pose.position
        data.qpos[adr + 3 : adr + 7] = pose.orientation
        if not keep_velocity:
            b = model.body(name)
            dof = int(model.jnt_dofadr[int(b.jntadr[0])])
            data.qvel[dof : dof + 6] = 0.0
    else:
        change(world, name, {"pose": {"position": list(pose.position), "orientation": list(pose.orientation)}})
        return {"name": name, "pose": world_pose(world, name), "recompiled": True}
    mujoco.mj_forward(model, data)
    return {"name": name, "pose": world_pose(world, name), "recompiled": False}


def state_bytes(world: World) -> bytes:
    """The world's whole physics state (``mjSTATE_FULLPHYSICS`` plus ``ctrl``), as bytes: what a refusal keeps."""
    model, data = world.model, world.data
    bits = int(mujoco.mjtState.mjSTATE_FULLPHYSICS) | int(mujoco.mjtState.mjSTATE_CTRL)
    values = np.empty(mujoco.mj_stateSize(model, bits))
    mujoco.mj_getState(model, data, values, bits)
    return values.tobytes()
