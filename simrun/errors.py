"""Errors raised by simrun: one base class, each also a matching built-in."""

from __future__ import annotations


class SimrunError(Exception):
    """Base class of every error simrun raises on purpose.

    Attributes:
        exit_code: The command line's exit code for this kind of error (docs/cli.md): 1, an input refused
            or a check failed; :class:`UsageError` and its kinds 2.
    """

    exit_code = 1


class UsageError(SimrunError, ValueError):
    """An option value, or a combination of options, the command cannot use (exit 2, as click's own)."""

    exit_code = 2


class EntityError(SimrunError, ValueError):
    """An entity cannot be inserted or built: bad name, duplicate, unknown parent, invalid parameters."""


class SceneError(SimrunError, ValueError):
    """A scene, commands or recording file is invalid; the message names the file, line and key path.

    The text is ``FILE:LINE: KEY 'NAME': message``, for example
    ``scene.toml:14: entities[3] 'box': mass: expected a positive number, got -100``; parts that are not
    known are left out (``FILE: message`` for a file that cannot be read).

    Args:
        message: What is wrong (and, where it helps, how to fix it).
        path: The file.
        key: Key path inside it, e.g. ``entities[3]`` or ``world.timestep``.
        line: 1-based line of the key in the file.
        label: The name of the entity (or service, sensor, command) the key belongs to.
    """

    def __init__(
        self,
        message: str,
        path: str | None = None,
        key: str | None = None,
        line: int | None = None,
        label: str | None = None,
    ) -> None:
        self.path, self.key, self.message, self.line, self.label = path, key, message, line, label
        where = f"{path}:{line}" if path and line else path
        what = f"{key} {label!r}" if key and label else key
        super().__init__(": ".join(x for x in (where, what, message) if x))


class CompileError(SimrunError, RuntimeError):
    """MuJoCo refused the model, or stepping produced warnings where none are allowed."""
