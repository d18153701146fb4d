"""Timed service commands: ``[[commands]]`` files of ``simrun play`` and the commands kept in a ``.simlog``.

A command calls a public method of a bound service at a simulated time, e.g. ``DriveService`` of ``boebot``:
``drive_distance(0.9, 0.6)``. Commands are data: :func:`load_commands` refuses, with the file and line,
anything that is not a finite time, a known service type, a public method of it, or arguments that fit
its signature (finite numbers, booleans, strings, or arrays of them). :func:`check_commands` then checks
them against a world's service bindings before the run starts, so no command fails half-way through.
"""

from __future__ import annotations

import inspect
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from simrun.errors import SceneError, SimrunError, did_you_mean
from simrun.safeio import FileReadError, read_regular
from simrun.scene.tomlpos import line_of, read_toml
from simrun.world.registry.tables import REGISTRY, names
from simrun.world.world import World

#: Largest commands file read, bytes.
MAX_COMMANDS_BYTES = 16 * 1024 * 1024
#: Most values in a commands file's arrays (docs/limits.md), counted on its bytes before the TOML is parsed:
#: parsing costs about 10 us a value, and a trajectory of 1M points took 20 s to parse before it was refused.
#: A trajectory of the JointService's 100,000 points (its limit) on 8 joints is 900,000 values.
MAX_COMMAND_VALUES = 1_000_000
#: What is not between a TOML array's values: strings (a comma inside one separates nothing) and comments.
_NOT_VALUES = re.compile(rb'"""[\s\S]*?"""|\'\'\'[\s\S]*?\'\'\'|"(?:[^"\\\n]|\\.)*"|\'[^\'\n]*\'|#[^\n]*')
#: Latest command time accepted, simulated seconds (one week).
MAX_COMMAND_TIME = 7 * 24 * 3600.0
_KEYS = ("t", "service", "entity", "call", "args")
#: Methods every controller has that the world calls, never a command (``tick(model, data)`` from a
#: commands file reached MuJoCo with a float for the model).
LIFECYCLE = ("tick", "reset", "snapshot", "restore", "check_command")


@dataclass(frozen=True, slots=True)
class Command:
    """A service call at a simulated time.

    Attributes:
        t: Simulated time, seconds.
        service: Service type, e.g. ``DriveService``.
        entity: Full name of the entity the service is bound to.
        call: Public method of the service.
        args: Positional arguments.
        where: Where it came from (``FILE:LINE: commands[3]``), for messages; not compared.
        entity_where: Where its ``entity =`` key is (``FILE:LINE: commands[3]``), for messages; not compared.
    """

    t: float
    service: str
    entity: str
    call: str
    args: tuple[Any, ...] = ()
    where: str = field(default="", compare=False)
    entity_where: str = field(default="", compare=False)

    def apply(self, world: World) -> None:
        """Call it on the bound service.

        Raises:
            SimrunError: No such binding or method, or the service refused the arguments.
        """
        target = world.service(self.service, self.entity)
        method = getattr(target, self.call, None)
        if method is None or self.call.startswith("_"):
            raise SimrunError(f"{self._where()}{self.service} has no command {self.call!r}")
        try:
            method(*self.args)
        except SimrunError as exc:
            raise SimrunError(f"{self._where()}{exc}") from None
        except (TypeError, ValueError) as exc:
            raise SimrunError(f"{self._where()}{self.call}{self.args!r} refused: {exc}") from None

    def _where(self) -> str:
        return f"{self.where}: " if self.where else ""


def load_commands(path: Path) -> list[Command]:
    """Read a commands file: ``[[commands]]`` tables with ``t``, ``service``, ``entity``, ``call``, ``args``.

    ``service`` defaults to ``DriveService`` and ``args`` to none. Commands are returned sorted by time
    (stable: equal times keep file order).

    Raises:
        SceneError: Unreadable file, bad TOML, or a bad command, naming the file, line and key.
    """
    name = str(path)
    try:
        raw = read_regular(path, "commands file", MAX_COMMANDS_BYTES)
    except FileReadError as exc:
        raise SceneError(str(exc)) from None
    separators = _NOT_VALUES.sub(b"", raw).count(b",")  # one fewer than the values, per array
    if separators >= MAX_COMMAND_VALUES:
        raise SceneError(
            f"more than {MAX_COMMAND_VALUES} values in its arrays ({separators} commas outside strings and "
            "comments; docs/limits.md): split long trajectories into shorter ones",
            name,
        )
    doc, lines = read_toml(path, "commands file", MAX_COMMANDS_BYTES)
    unknown = [k for k in doc if k not in ("commands", "expect")]  # [[expect]]: read by simrun test
    if unknown:
        raise SceneError("unknown key (known: commands, expect)", name, unknown[0], line_of(lines, (unknown[0],)))
    tables = doc.get("commands", [])
    if not isinstance(tables, list):
        raise SceneError("expected an array of tables ([[commands]])", name, "commands", line_of(lines, ("commands",)))
    commands = []
    for k, table in enumerate(tables):
        first = line_of(lines, ("commands", k))
        where = f"{name}:{first}: commands[{k}]" if first else f"{name}: commands[{k}]"

        def fail(message: str, key: str | None = None, k: int = k) -> SceneError:
            at = line_of(lines, ("commands", k, key)) if key else line_of(lines, ("commands", k))
            return SceneError(f"{key}: {message}" if key else message, name, f"commands[{k}]", at)

        at = line_of(lines, ("commands", k, "entity"))
        commands.append(parse_command(table, fail, where, f"{name}:{at}: commands[{k}]" if at else where))
    return sorted(commands, key=lambda c: c.t)


def parse_command(table: Any, fail: Any, where: str = "", entity_where: str = "") -> Command:
    """One command from a table (a ``[[commands]]`` entry); ``fail(message, key)`` makes the error to raise.

    ``where`` and ``entity_where`` locate the table and its ``entity =`` key for later messages.
    """
    if not isinstance(table, dict):
        raise fail("expected a table with t, entity, call (and service, args)")
    for key in table:
        if key not in _KEYS:
            raise fail(f"unknown key (known: {', '.join(_KEYS)})", key)
    for key in ("t", "entity", "call"):
        if key not in table:
            raise fail(f"missing {key!r}; a command needs t, entity and call", None)
    t = table["t"]
    if isinstance(t, bool) or not isinstance(t, int | float) or not math.isfinite(t):
        raise fail(f"expected a finite number of seconds, got {t!r}", "t")
    if not 0 <= t <= MAX_COMMAND_TIME:
        raise fail(f"must be in [0, {MAX_COMMAND_TIME:g}] seconds, got {t!r}", "t")
    service = table.get("service", "DriveService")
    for key, value in (("service", service), ("entity", table["entity"]), ("call", table["call"])):
        if not isinstance(value, str) or not value:
            raise fail(f"expected a non-empty string, got {value!r}", key)
    if service not in names("services"):
        raise fail(f"unknown service type {service!r} (known: {', '.join(names('services'))})", "service")
    cls = REGISTRY[service].load()
    args = table.get("args", [])
    if not isinstance(args, list):
        raise fail(f"expected an array of arguments, got {args!r}", "args")
    for k, value in enumerate(args):
        problem = _bad_argument(value)
        if problem:
            raise fail(f"argument {k + 1} {problem}", "args")
    call = table["call"]
    method = getattr(cls, call, None)
    if call.startswith("_") or call in LIFECYCLE or not callable(method):
        public = [n for n, m in inspect.getmembers(cls, callable) if not n.startswith("_")]
        public = [n for n in public if n not in LIFECYCLE]
        raise fail(f"{service} has no command {call!r} (commands: {', '.join(public)})", "call")
    try:
        inspect.signature(method).bind(None, *args)
    except TypeError as exc:
        raise fail(f"{call}{inspect.signature(method)} cannot take {len(args)} argument(s): {exc}", "args") from None
    return Command(float(t), service, table["entity"], call, tuple(args), where, entity_where or where)


def _bad_argument(value: Any) -> str | None:
    """Why a command argument is refused, or ``None``."""
    if isinstance(value, bool | str):
        return None
    if isinstance(value, int | float):
        return None if math.isfinite(value) else f"is not a finite number ({value!r})"
    if isinstance(value, list):
        for item in value:
            if isinstance(item, list):
                return "is an array of arrays (arrays hold numbers, booleans or strings)"
            problem = _bad_argument(item)
            if problem:
                return problem
        return None
    return f"has an unsupported type {type(value).__name__} (numbers, booleans, strings or arrays of them)"


def check_commands(world: World, commands: list[Command]) -> None:
    """Refuse commands that cannot run in ``world``, before the run starts.

    A command's service must be bound; a service the world has created (:meth:`World.check_bindings
    <simrun.world.world.World.check_bindings>`, as ``simrun play``, ``check`` and ``test`` do) with a
    ``check_command(call, args)`` method (the ``JointService``: targets outside a joint's range, trajectories
    too long or too fast for the timestep) refuses the command's arguments here, so the error is one line
    naming the command's file and line before the first step, not half-way through the run.

    Raises:
        SimrunError: A command names a service type and entity with no ``[[services]]`` binding, or its
            service refused its arguments.
    """
    bound = {(s.get("type"), s.get("entity")) for s in world.services}
    entities = [name for name, _ in world]
    for command in commands:
        if command.entity not in entities:  # named at its entity = line, with the closest entity name
            hint = did_you_mean(command.entity, entities)
            where = f"{command.entity_where}: " if command.entity_where else ""
            raise SimrunError(
                f"{where}entity: no entity {command.entity!r} in the scene (entities: {', '.join(entities)}){hint}"
            )
        if (command.service, command.entity) not in bound:
            raise SimrunError(
                f"{command._where()}no {command.service} is bound to {command.entity!r} in the scene; "
                "add it under [[services]]"
            )
        # only a service the world has already created (World.check_bindings): creating one here would start
        # its control earlier than its first command does in a run that does not check (resim)
        cls = REGISTRY[command.service].load()
        live = next(
            (c for c in world.controllers if isinstance(c, cls) and getattr(c, "name", None) == command.entity), None
        )
        check = getattr(live, "check_command", None)
        if callable(check):
            try:
                check(command.call, command.args)
            except SimrunError as exc:
                raise SimrunError(f"{command._where()}{exc}") from None
