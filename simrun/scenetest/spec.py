"""Scene test cases: the scenes under ``simrun test``'s paths, their ``[test]`` table and expectations.

A scene's optional ``[test]`` table says how to run it (docs/scene-format.md):

- ``duration``: simulated seconds (default :data:`DEFAULT_DURATION`);
- ``commands``: a commands file (``[[commands]]``, and ``[[expect]]`` of its own) or a ``.py`` controller
  module, relative to the scene's folder;
- ``[test.jitter]``: ``ENTITY = { xy = METRES, yaw = DEGREES }``, pose jitter drawn from each run's seed.

Expectations come from the scene's ``[[expect]]`` tables and the commands file's. A scene without any is
a smoke test: it passes when the simulation stays finite (an implicit ``finite`` expectation).

Each case is checked here before anything runs (the scene loads and binds, commands fit the services,
expectations name bodies, sensors and joints the world has and times within the run), and bundled with
every file it reads (:mod:`simrun.scenetest.bundle`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from simrun.errors import SceneError, UsageError
from simrun.run.commands import Command, check_commands, load_commands
from simrun.run.session import prepare
from simrun.scene.tomlpos import KeyPath, line_of, read_toml
from simrun.scenetest.bundle import Bundle, collect
from simrun.scenetest.expect import Expectation, parse_expectations
from simrun.scenetest.observer import check_against

#: Simulated seconds of a scene whose ``[test]`` table gives no duration.
DEFAULT_DURATION = 5.0
#: Longest duration accepted, simulated seconds.
MAX_DURATION = 7 * 24 * 3600.0
_TEST_KEYS = ("duration", "commands", "jitter")
_SCENE_KEYS = ("world", "entities")


class SpecError(UsageError):
    """No scene to test where the user pointed (a usage error, exit 2)."""


class MissingInputError(SpecError):
    """A path given to test does not exist: exit 1, as a missing input is in every command (docs/cli.md)."""

    exit_code = 1


@dataclass(frozen=True)
class Case:
    """One scene to test.

    Attributes:
        display: The scene's path as the user gave it (POSIX), used in every report.
        doc: The parsed scene document (variations edit a copy).
        bundle: The scene and the files it reads.
        duration: Simulated seconds per run.
        commands: Timed commands (from the ``[test]`` commands file).
        controller: The ``.py`` controller's path in the bundle, or ``None``.
        expectations: The scene's and the commands file's, in that order.
        implicit: No ``[[expect]]`` anywhere: the implicit ``finite`` smoke test.
        jitter: ``[test.jitter]``: entity name to ``{"xy": metres, "yaw": degrees}``.
        lines: Key lines of the scene file.
    """

    display: str
    doc: dict[str, Any]
    bundle: Bundle
    duration: float
    commands: tuple[Command, ...]
    controller: str | None
    expectations: tuple[Expectation, ...]
    implicit: bool
    jitter: dict[str, dict[str, float]] = field(default_factory=dict)
    lines: dict[KeyPath, int] = field(default_factory=dict)

    def line_of(self, *path: str | int) -> int | None:
        """The line of a key path of the scene file."""
        return line_of(self.lines, path)


def discover(paths: list[Path]) -> list[Path]:
    """The scene files named or found (recursively, hidden folders skipped) under ``paths``, sorted per path.

    A ``.toml`` file in a folder is a scene when it has a ``[world]`` table or ``[[entities]]`` (commands
    files and other TOML are skipped); a file named directly must be a scene.

    Raises:
        SpecError: A path that does not exist, a named file that is not a scene, or no scene at all.
    """
    found: list[Path] = []
    for path in paths:
        if path.is_dir():
            for candidate in sorted(path.rglob("*.toml")):
                rel = candidate.relative_to(path)
                if any(part.startswith(".") for part in rel.parts) or not candidate.is_file():
                    continue
                if _is_scene(candidate):
                    found.append(candidate)
        elif path.is_file():
            if not _is_scene(path, named=True):
                raise SpecError(f"{path}: not a scene file (no [world] or [[entities]])")
            found.append(path)
        else:
            raise MissingInputError(f"{path}: no such file or folder")
    unique = list(dict.fromkeys(found))
    if not unique:
        raise SpecError(f"no scene files under {', '.join(map(str, paths))} (.toml with [world] or [[entities]])")
    return unique


def _is_scene(path: Path, named: bool = False) -> bool:
    doc = read_toml(path)[0] if named else _peek(path)
    return doc is not None and any(key in doc for key in _SCENE_KEYS)


def _peek(path: Path) -> dict[str, Any] | None:
    """The document of a TOML file found in a folder, ``None`` when it is not readable TOML (not ours)."""
    try:
        return read_toml(path, "scene")[0]
    except SceneError:
        return None


def load_case(path: Path) -> Case:
    """Read, check and bundle one scene for testing.

    Raises:
        SceneError: The scene, its ``[test]`` table, commands file or expectations are invalid (FILE:LINE).
        SimrunError: Anything else that stops the scene from running (a binding, a missing file).
    """
    from simrun.scene.scene_file import load_scene

    display = path.as_posix()
    doc, lines = read_toml(path)
    table = doc.get("test", {})

    def fail(message: str, *key: str | int) -> SceneError:
        where: KeyPath = ("test", *key)
        return SceneError(message, display, ".".join(map(str, where)), line_of(lines, where))

    if not isinstance(table, dict):
        raise fail("expected a table ([test])")
    for key in table:
        if key not in _TEST_KEYS:
            raise fail(f"unknown key (known: {', '.join(_TEST_KEYS)})", key)
    duration = table.get("duration", DEFAULT_DURATION)
    if isinstance(duration, bool) or not isinstance(duration, int | float) or not math.isfinite(duration):
        raise fail(f"expected a number of seconds, got {duration!r}", "duration")
    if not 0 < duration <= MAX_DURATION:
        raise fail(f"must be in (0, {MAX_DURATION:g}] seconds, got {duration!r}", "duration")
    jitter = _jitter(table.get("jitter", {}), fail)
    expectations = parse_expectations(doc, lines, display)
    commands: list[Command] = []
    controller: Path | None = None
    extra: list[Path] = []
    if "commands" in table:
        name = table["commands"]
        if not isinstance(name, str) or not name:
            raise fail(f"expected a file path relative to the scene, got {name!r}", "commands")
        other = path.parent / name
        extra.append(other)
        if other.suffix == ".py":
            controller = other
        else:
            commands = load_commands(other)
            cdoc, clines = read_toml(other)
            expectations += parse_expectations(cdoc, clines, other.as_posix())
    implicit = not expectations
    if implicit:
        expectations = [
            Expectation("finite", "finite", "the simulation stays finite", "always", 0.0, None, {}, display, None)
        ]

    def preflight() -> Any:
        world = load_scene(path)
        prepare(world)
        check_commands(world, commands)
        check_against(expectations, world, float(duration))
        names = dict(world)
        for entity in jitter:
            if entity not in names:
                raise fail(f"no entity named {entity!r}", "jitter", entity)
        return world

    bundle, _ = collect(path, preflight, tuple(extra))
    rel_controller = None
    if controller is not None:
        root_depth = bundle.scene.count("/")
        base = Path(*path.resolve().parts[: len(path.resolve().parts) - 1 - root_depth])
        rel_controller = controller.resolve().relative_to(base).as_posix()
    return Case(
        display,
        doc,
        bundle,
        float(duration),
        tuple(commands),
        rel_controller,
        tuple(expectations),
        implicit,
        jitter,
        lines,
    )


def _jitter(value: Any, fail: Any) -> dict[str, dict[str, float]]:
    if not isinstance(value, dict):
        raise fail("expected a table of ENTITY = { xy = METRES, yaw = DEGREES }", "jitter")
    out: dict[str, dict[str, float]] = {}
    for entity, spec in value.items():
        if not isinstance(spec, dict) or not spec:
            raise fail("expected { xy = METRES, yaw = DEGREES }", "jitter", entity)
        out[entity] = {}
        for key, number in spec.items():
            if key not in ("xy", "yaw"):
                raise fail("unknown key (known: xy, yaw)", "jitter", entity, key)
            if isinstance(number, bool) or not isinstance(number, int | float) or not math.isfinite(number):
                raise fail(f"expected a finite number, got {number!r}", "jitter", entity, key)
            if not 0 <= number <= (1.0 if key == "xy" else 180.0):
                raise fail(f"must be in [0, {1 if key == 'xy' else 180}], got {number!r}", "jitter", entity, key)
            out[entity][key] = float(number)
    return out
