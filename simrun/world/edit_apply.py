"""Edits as data: one JSON-ready record per edit (what a recording of an edited session would hold).

:class:`EditRecord` is ``(t, kind, args)``: the simulated time it was applied at (seconds), the edit's name
(:data:`KINDS`) and its arguments as JSON values; :func:`apply_edit` is the one dispatcher from a record's
kind and arguments to :mod:`simrun.world.edit` (and its ``edit_bindings``, ``edit_push``, ``edit_save``
companions), used by the server's edit routes, so every edit a client makes is such a record. Applying the
same records at the same steps of the same scene gives the same world bit for bit (edits are deterministic:
tests/test_edit_apply.py re-runs a session of five edits).
"""

from __future__ import annotations

import inspect
import json
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from simrun.world import edit, edit_bindings, edit_push, edit_save
from simrun.world.edit import EditError
from simrun.world.registry.tables import Group
from simrun.world.world import World

#: Every edit by name: the library function a record of that kind calls (keyword arguments, JSON values).
KINDS: dict[str, Callable[..., Any]] = {
    "insert": edit.insert,
    "change": edit.change,
    "remove": edit.remove,
    "teleport": edit.teleport,
    "set_gravity": edit.set_gravity,
    "apply_force": edit_push.apply_force,
    "add_service": edit_bindings.add_service,
    "change_service": edit_bindings.change_service,
    "remove_service": edit_bindings.remove_service,
    "add_sensor": edit_bindings.add_sensor,
    "change_sensor": edit_bindings.change_sensor,
    "remove_sensor": edit_bindings.remove_sensor,
    "load_entities": edit_save.load_entities_text,
}


def _parameters(kind: str) -> dict[str, inspect.Parameter]:
    return dict(list(inspect.signature(KINDS[kind]).parameters.items())[1:])  # after the world


def apply_edit(world: World, kind: str, args: dict[str, Any]) -> Any:
    """Apply the edit ``kind`` with keyword ``args`` (JSON values) to ``world`` now; returns its result.

    Raises:
        EditError: An unknown kind (field ``kind``), an unknown or missing argument (its name), or what the
            edit itself refuses (the world is then as it was).
    """
    if kind not in KINDS:
        raise EditError(f"unknown edit {kind!r} (known: {', '.join(KINDS)})", key="kind")
    if not isinstance(args, dict):
        raise EditError("expected an object of the edit's arguments", key="args")
    params = _parameters(kind)
    for name in args:
        if name not in params:
            raise EditError(f"{kind} takes no argument {name!r} (arguments: {', '.join(params)})", key=str(name))
    for name, p in params.items():
        if p.default is inspect.Parameter.empty and name not in args:
            raise EditError(f"{kind} needs {name!r}", key=name)
    return KINDS[kind](world, **args)


@dataclass(frozen=True, slots=True)
class EditRecord:
    """One edit as applied: when, which, with what.

    Attributes:
        t: Simulated time it was applied at, seconds (between two steps).
        kind: A key of :data:`KINDS`.
        args: Its keyword arguments, JSON values.
    """

    t: float
    kind: str
    args: dict[str, Any] = field(default_factory=dict)

    def apply(self, world: World) -> Any:
        """:func:`apply_edit` of this record (the time is the caller's: apply it at ``t``)."""
        return apply_edit(world, self.kind, self.args)

    def to_json(self) -> str:
        """``[t, kind, args]`` as canonical JSON text (NaN refused)."""
        return json.dumps([self.t, self.kind, self.args], sort_keys=True, allow_nan=False, separators=(",", ":"))

    @classmethod
    def from_json(cls, text: str) -> EditRecord:
        """Inverse of :meth:`to_json`.

        Raises:
            EditError: Not ``[t, kind, args]`` with a finite time >= 0, a known kind and an object.
        """
        try:
            value = json.loads(text)
        except ValueError as exc:
            raise EditError(f"not JSON ({exc})", key="edit") from None
        if not (isinstance(value, list) and len(value) == 3):
            raise EditError("expected [t, kind, args]", key="edit")
        t, kind, args = value
        if isinstance(t, bool) or not isinstance(t, int | float) or not math.isfinite(t) or t < 0:
            raise EditError(f"expected a time >= 0, got {t!r}", key="t")
        if kind not in KINDS:
            raise EditError(f"unknown edit {kind!r}", key="kind")
        if not isinstance(args, dict):
            raise EditError("expected an object of arguments", key="args")
        return cls(float(t), kind, args)


def _old_values(current: dict[str, Any], keys: Any, group: Group, kind: str) -> dict[str, Any]:
    """The values ``keys`` have in ``current`` (a table), or their schema defaults when it leaves them out."""
    from simrun.world.edit_schema import json_value
    from simrun.world.registry.key_schema import schema

    known = schema(group, kind)
    out: dict[str, Any] = {}
    for key in keys:
        if key in current:
            out[key] = current[key]
        elif key == "pose":
            out[key] = {"position": [0.0, 0.0, 0.0], "orientation": [1.0, 0.0, 0.0, 0.0]}
        elif key in known:
            out[key] = json_value(known[key].default)
    return out


def inverse(world: World, kind: str, args: dict[str, Any]) -> list[EditRecord] | None:
    """The edits that undo ``kind(args)`` on ``world`` as it is now (call before applying it); ``None``: no undo.

    ``insert`` and ``load_entities`` are undone by removing what they add (the caller fills the names in
    from the result: :func:`undo_of`), ``remove`` by loading the removed entities (and their services and
    sensors) back at their poses now, a change by the old values (an entity given its old ``pose`` starts
    there at rest), a teleport by a teleport to where the entity is now. A push is physics: it has no undo.
    """
    t = float(world.data.time)
    if kind == "change" and isinstance(args.get("changes"), dict) and args.get("name") in dict(world):
        name = args["name"]
        old = edit.entity_tables(world)[name]
        values = _old_values(old, args["changes"], "entities", world.entity(name).TYPE)
        return [EditRecord(t, "change", {"name": name, "changes": values})]
    if kind == "remove" and args.get("name") in dict(world):
        name = args["name"]
        text = edit_save.entities_text(world, [name])
        return [EditRecord(t, "load_entities", {"text": text, "parent": world.entity(name).parent})]
    if kind == "teleport" and args.get("name") in dict(world) and world.entity(args["name"]).HAS_BODY:
        pose = edit.current_pose(world, args["name"])
        back = {"name": args["name"], "position": list(pose.position), "orientation": list(pose.orientation)}
        return [EditRecord(t, "teleport", back)]
    if kind == "set_gravity":
        return [EditRecord(t, "set_gravity", {"gravity": list(world.options.gravity)})]
    if kind in ("change_service", "remove_service"):
        binding = next(
            (s for s in world.services if s.get("type") == args.get("kind") and s.get("entity") == args.get("entity")),
            None,
        )
        if binding is None:
            return None
        if kind == "remove_service":
            return [EditRecord(t, "add_service", {"table": dict(binding)})]
        values = _old_values(binding, args.get("settings") or {}, "services", binding["type"])
        return [EditRecord(t, "change_service", {"kind": args["kind"], "entity": args["entity"], "settings": values})]
    if kind in ("change_sensor", "remove_sensor"):
        spec = next((s for s in world.sensor_specs if s.get("name") == args.get("name")), None)
        if spec is None:
            return None
        if kind == "remove_sensor":
            return [EditRecord(t, "add_sensor", {"table": dict(spec)})]
        values = _old_values(spec, args.get("settings") or {}, "sensors", spec["type"])
        return [EditRecord(t, "change_sensor", {"name": args["name"], "settings": values})]
    if kind in ("add_service", "add_sensor", "insert", "load_entities"):
        return []  # filled in from the result (undo_of)
    return None


def undo_of(
    t: float, kind: str, args: dict[str, Any], result: Any, before: list[EditRecord] | None
) -> list[EditRecord] | None:
    """The undo of an edit applied at ``t``: :func:`inverse`'s, with what an insertion added (its ``result``)."""
    if before is None:
        return None
    if kind == "insert":
        tops = [n for n in result if not any(n.startswith(o + "/") for o in result if o != n)]
        return [EditRecord(t, "remove", {"name": n}) for n in reversed(tops)]
    if kind == "load_entities":
        added = result["entities"]
        tops = [n for n in added if not any(n.startswith(o + "/") for o in added if o != n)]
        return [EditRecord(t, "remove", {"name": n}) for n in reversed(tops)]
    if kind == "add_service":
        table = args["table"]
        return [EditRecord(t, "remove_service", {"kind": table["type"], "entity": table["entity"]})]
    if kind == "add_sensor":
        return [EditRecord(t, "remove_sensor", {"name": args["table"]["name"]})]
    return before
