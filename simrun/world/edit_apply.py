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
