"""Editing a running world's services and sensors: bind, change settings, remove (see :mod:`simrun.world.edit`).

A service or sensor built again (new settings, or its entity changed) takes the place of the old one among
the world's controllers (checkpoints depend on the order) and is restored from the old one's snapshot: its
clock, its state and its noise stream continue. Tables go through the registry's one route
(:func:`simrun.world.registry.conversion.arguments`), as a scene's ``[[services]]`` and ``[[sensors]]`` do.
"""

from __future__ import annotations

from typing import Any, Literal

from simrun.errors import EntityError, SimrunError
from simrun.world.edit import Edit, EditError, _entity, _merge, edit_fail, trial
from simrun.world.edit_carry import rebuild_sensor, rebuild_service
from simrun.world.registry.conversion import arguments
from simrun.world.registry.tables import REGISTRY, scene_type
from simrun.world.world import World


def _binding(world: World, kind: str, entity: str) -> dict[str, Any]:
    found = next((s for s in world.services if s.get("type") == kind and s.get("entity") == entity), None)
    if found is None:
        bound = ", ".join(f"{s['type']}:{s['entity']}" for s in world.services) or "none"
        raise EditError(f"no {kind} is bound to {entity!r} (services: {bound})", key="entity", reason="missing")
    return found


def change_service(world: World, kind: str, entity: str, settings: dict[str, Any]) -> None:
    """Change a bound service's settings (its ``[[services]]`` keys: ``rate``, ``limits``, ``gain``...).

    The service is built again from the merged binding and restored from its snapshot, in its place.

    Raises:
        EditError: No such binding, a key that cannot change (``type``, ``entity``), a refused value.
    """
    binding = _binding(world, kind, entity)
    if not isinstance(settings, dict) or not settings:
        raise EditError("expected a table of the settings to change", key="settings")
    for key in settings:
        if key in ("type", "entity"):
            raise EditError(f"{key} cannot change; remove the service and add it again", key=key)
    merged = _merge(binding, settings)
    arguments("services", kind, merged, edit_fail("", entity))
    with Edit(world, "settings") as edit:
        index = world.services.index(binding)
        world.services[index] = merged
        rebuild_service(world, kind, entity)
        _check(world)
        edit.done = True


def change_sensor(world: World, name: str, settings: dict[str, Any]) -> None:
    """Change a sensor's settings (``rate``, ``noise``, ``seed``, its own keys).

    The sensor is built again from the merged table and restored from its snapshot (clock, count, noise
    stream; a new ``seed`` restarts the noise stream from it).

    Raises:
        EditError: No such sensor, a key that cannot change (``type``, ``name``, what it binds), a refused value.
    """
    spec = _sensor_spec(world, name)
    if not isinstance(settings, dict) or not settings:
        raise EditError("expected a table of the settings to change", key="settings")
    binds = REGISTRY[spec["type"]].binds
    for key in settings:
        if key in ("type", "name", binds):
            raise EditError(f"{key} cannot change; remove the sensor and add it again", key=key)
    merged = _merge(spec, settings)
    _check_sensor_values(merged)
    with Edit(world, "settings") as edit:
        rebuild_sensor(world, name, merged, keep_noise="seed" not in settings)
        _check(world)
        edit.done = True


def _check_sensor_values(spec: dict[str, Any]) -> None:
    from simrun.scene.scene_file import MAX_SENSOR_RATE

    arguments("sensors", spec["type"], spec, edit_fail("", spec.get("name")))
    rate = spec.get("rate")
    if isinstance(rate, int | float) and rate > MAX_SENSOR_RATE:
        raise EditError(f"must be at most {MAX_SENSOR_RATE:g} Hz, got {rate!r}", key="rate")
    for key in ("rate", "noise"):
        value = spec.get(key)
        if isinstance(value, int | float) and value < 0:
            raise EditError(f"must be >= 0, got {value!r}", key=key)


def _sensor_spec(world: World, name: Any) -> dict[str, Any]:
    found = next((s for s in world.sensor_specs if s.get("name") == name), None)
    if found is None or name not in world.sensors:
        known = ", ".join(world.sensors) or "none"
        raise EditError(f"no sensor named {name!r} (sensors: {known})", key="name", reason="missing")
    return found


def _check(world: World) -> None:
    """``World.check_bindings`` (a trial reading of every sensor), its refusal as an :class:`EditError`."""
    trial(world, "settings")


def _table_type(table: Any, group: Literal["services", "sensors"], key: str) -> str:
    """The registered type name of a ``[[services]]`` or ``[[sensors]]`` table (``group``).

    Raises:
        EditError: Naming ``key`` (not a table) or ``type`` (an unknown type).
    """
    if not isinstance(table, dict):
        raise EditError("expected a table", key=key)
    try:
        return scene_type(group, table.get("type")).name
    except EntityError as exc:
        raise EditError(str(exc), key="type") from None


def add_service(world: World, table: dict[str, Any]) -> None:
    """Bind a service from a ``[[services]]`` table (``{"type": "DriveService", "entity": "bot", ...}``).

    Raises:
        EditError: An unknown type or entity, a binding already there, a refused value, or it does not fit.
    """
    kind = _table_type(table, "services", "service")
    entity = table.get("entity")
    _entity(world, entity, key="entity")
    if any(s.get("type") == kind and s.get("entity") == entity for s in world.services):
        raise EditError(f"a {kind} is already bound to {entity!r}", key="entity", reason="conflict")
    arguments("services", kind, table, edit_fail("", str(entity)))
    with Edit(world, "service") as edit:
        world.services.append(dict(table))
        try:
            world.service(kind, str(entity))
        except SimrunError as exc:
            raise EditError(exc.message or str(exc), key="entity") from None
        edit.done = True


def remove_service(world: World, kind: str, entity: str) -> None:
    """Unbind a service (its object leaves the controllers; the entity's motors keep their last controls)."""
    binding = _binding(world, kind, entity)
    service = world._bound.pop((kind, entity), None)
    world.controllers[:] = [c for c in world.controllers if c is not service]
    world.services.remove(binding)
    world.reschedule()


def add_sensor(world: World, table: dict[str, Any]) -> None:
    """Add a sensor from a ``[[sensors]]`` table (``{"type": "Bumper", "name": "bump", "entity": "bot"}``).

    Raises:
        EditError: An unknown type, a name taken, an unknown entity, a refused value, or it cannot read.
    """
    kind = _table_type(table, "sensors", "sensor")
    name = table.get("name")
    if not isinstance(name, str) or not name:
        raise EditError("a sensor needs a 'name' string", key="name")
    if name in world.sensors:
        raise EditError(f"a sensor named {name!r} already exists", key="name", reason="conflict")
    target = table.get(REGISTRY[kind].binds)
    owner = target.rsplit("/", 1)[0] if isinstance(target, str) and REGISTRY[kind].binds == "camera" else target
    if not (isinstance(target, str) and (target in dict(world) or owner in dict(world))):
        raise EditError(f"no entity named {target!r}", key=REGISTRY[kind].binds, reason="missing")
    _check_sensor_values(table)
    with Edit(world, "sensor") as edit:
        try:
            world.add_sensor(dict(table))
        except (SimrunError, TypeError, ValueError) as exc:
            raise EditError(str(exc), key="sensor", entity=name) from None
        _check(world)
        edit.done = True


def remove_sensor(world: World, name: str) -> None:
    """Remove a sensor."""
    spec = _sensor_spec(world, name)
    sensor = world.sensors.pop(name)
    world.controllers[:] = [c for c in world.controllers if c is not sensor]
    world.sensor_specs.remove(spec)
    world.reschedule()
