"""The editable schema of every registered type, as JSON (:mod:`simrun.world.edit`, ``GET /api/edit``).

Read from the registry's one schema (:func:`simrun.world.registry.key_schema.schema`): keys, types, units, defaults and
descriptions, nothing kept by hand.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

from simrun.world.registry.key_schema import REQUIRED, Key, fixed_keys, schema, table_keys
from simrun.world.registry.tables import GROUPS, Group, names, scene_type


def json_value(value: Any) -> Any:
    """A default or current value as JSON-ready data (tuples to lists, dataclasses to objects, REQUIRED to None)."""
    if value is REQUIRED:
        return None
    if hasattr(value, "to_scene"):
        return value.to_scene()
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: json_value(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, tuple | list):
        return [json_value(v) for v in value]
    if isinstance(value, dict):
        return {str(k): json_value(v) for k, v in value.items()}
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def key_schema(key: Key) -> dict[str, Any]:
    """One key as JSON: ``{"name", "type", "unit", "default", "required", "description"}`` (``fields`` for tables)."""
    out: dict[str, Any] = {
        "name": key.name,
        "type": key.type_text,
        "unit": key.unit,
        "default": json_value(key.default),
        "required": key.required,
        "description": key.description,
    }
    inner = table_keys(key.hint, key.name)
    if inner:
        out["fields"] = [key_schema(k) for k in inner]
    return out


def type_schema(group: Group, kind: str) -> dict[str, Any]:
    """A registered type's schema: ``{"type", "group", "summary", "fixed", "keys": [key_schema...]}``.

    ``fixed`` are the keys besides the parameters (``type``, a sensor's ``name``, what it binds to); an
    entity's keys start with :data:`~simrun.world.registry.key_schema.ENTITY_BASE` (``name``, ``parent``, ``pose``...).
    """
    registered = scene_type(group, kind)
    return {
        "type": kind,
        "group": group,
        "summary": registered.summary,
        "binds": registered.binds if group != "entities" else None,
        "fixed": list(fixed_keys(group, kind)),
        "keys": [key_schema(k) for k in schema(group, kind).values()],
    }


def types_schema() -> dict[str, list[dict[str, Any]]]:
    """Every registered type's :func:`type_schema`, by group (``entities``, ``services``, ``sensors``)."""
    return {group: [type_schema(group, kind) for kind in names(group)] for group in GROUPS}
