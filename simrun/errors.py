"""Errors raised by simrun: one base class, each also a matching built-in."""

from __future__ import annotations


class SimrunError(Exception):
    """Base class of every error simrun raises on purpose."""


class EntityError(SimrunError, ValueError):
    """An entity cannot be inserted or built: bad name, duplicate, unknown parent, invalid parameters."""


class SceneError(SimrunError, ValueError):
    """A scene file is invalid; the message names the file and the key path.

    Args:
        message: What is wrong.
        path: The scene file.
        key: Key path inside it, e.g. ``entities[3].pose.position``.
    """

    def __init__(self, message: str, path: str | None = None, key: str | None = None) -> None:
        self.path, self.key, self.message = path, key, message
        where = ": ".join(x for x in (path, key) if x)
        super().__init__(f"{where}: {message}" if where else message)


class CompileError(SimrunError, RuntimeError):
    """MuJoCo refused the model, or stepping produced warnings where none are allowed."""
