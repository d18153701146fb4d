"""Errors raised by simrun: one base class with the location fields meshtool's errors carry.

Every error simrun raises on purpose derives from :class:`SimrunError`, and each subclass also derives from
the matching built-in exception, so callers may catch either. An error carries *where* (``path``, ``line``
and ``key``: the key path inside the file, e.g. ``entities[3].mass``; ``entity``: the entity, service or
command it concerns) and *how to fix it* (``hint``); ``str(error)`` is one line,
``FILE:LINE: KEY 'ENTITY': message (hint)``, with the parts that are not known left out.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any


class SimrunError(Exception):
    """Base class of every error simrun raises on purpose.

    Args:
        message: What is wrong (no location).
        path: The file, as the user named it.
        line: 1-based line of the problem in ``path``.
        key: Key path inside the file (``entities[3]``, ``world.timestep``) or the parameter (``mass``).
        entity: Name of the entity, service, sensor or command the key belongs to.
        hint: How to fix it, one short sentence.

    Attributes:
        exit_code: The command line's exit code for this kind of error (docs/cli.md): 1, an input refused
            or a check failed; :class:`UsageError` and its kinds 2.
    """

    exit_code = 1

    def __init__(
        self,
        message: str = "",
        *,
        path: str | None = None,
        line: int | None = None,
        key: str | None = None,
        entity: str | None = None,
        hint: str | None = None,
    ) -> None:
        self.message, self.path, self.key, self.entity, self.hint = message, path, key, entity, hint
        self.line = line if line is None or line >= 1 else None
        super().__init__(self.one_line())

    @property
    def where(self) -> str:
        """``path:line``, ``path`` or empty."""
        if self.path and self.line:
            return f"{self.path}:{self.line}"
        return self.path or ""

    def one_line(self) -> str:
        """The error as one line: where, which key of which entity, what, and the fix."""
        what = f"{self.key} {self.entity!r}" if self.key and self.entity else self.key
        text = ": ".join(x for x in (self.where, what, self.message) if x)
        if self.hint:
            text += f" ({self.hint})"
        return text.replace("\n", " ")

    def fields(self) -> dict[str, Any]:
        """The location fields (``path``, ``line``, ``key``, ``entity``, ``hint``)."""
        return {"path": self.path, "line": self.line, "key": self.key, "entity": self.entity, "hint": self.hint}

    def to_dict(self) -> dict[str, object]:
        """A JSON-ready description of the error (as :meth:`meshtool.errors.MeshtoolError.to_dict`)."""
        return {"type": type(self).__name__, "message": self.message, **self.fields()}

    def __reduce__(self) -> tuple[Any, ...]:
        """Pickle with the fields (errors travel back from worker processes and Dask)."""
        return (_rebuild, (type(self), self.message, self.fields()))


def _rebuild(cls: type[SimrunError], message: str, fields: dict[str, Any]) -> SimrunError:
    error = cls.__new__(cls)
    SimrunError.__init__(error, message, **fields)
    return error


class UsageError(SimrunError, ValueError):
    """An option value, or a combination of options, the command cannot use (exit 2, as click's own)."""

    exit_code = 2


class EntityError(SimrunError, ValueError):
    """An entity cannot be inserted or built: bad name, duplicate, unknown parent, invalid parameters."""


class PoseError(EntityError):
    """A pose that is no rigid transform: wrong lengths, non-finite numbers, a quaternion that is not unit."""


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
        label: The name of the entity (or service, sensor, command) the key belongs to (``entity``).
    """

    def __init__(
        self,
        message: str = "",
        path: str | None = None,
        key: str | None = None,
        line: int | None = None,
        label: str | None = None,
        **fields: Any,
    ) -> None:
        entity = label if label is not None else fields.get("entity")
        super().__init__(message, path=path, key=key, line=line, entity=entity, hint=fields.get("hint"))

    @property
    def label(self) -> str | None:
        """The entity name (``entity``), as earlier versions called it."""
        return self.entity


class CompileError(SimrunError, RuntimeError):
    """MuJoCo refused the model, or stepping produced warnings where none are allowed."""


@dataclass(frozen=True, slots=True)
class Origin:
    """Where an item of a world came from: its file, line, key path (``entities[3]``) and name.

    :meth:`error` gives an error with those fields, whose one line starts ``FILE:LINE: KEY 'NAME'``
    (:meth:`SimrunError.one_line`, the one place that text is made).
    """

    path: str | None
    line: int | None
    key: str
    label: str | None = None

    def error(self, message: str, hint: str | None = None) -> EntityError:
        """An :class:`EntityError` located here (path, line, key and entity as fields)."""
        return EntityError(message, path=self.path, line=self.line, key=self.key, entity=self.label, hint=hint)


def did_you_mean(word: object, known: Iterable[str]) -> str:
    """The hint for a misspelt name: ``; did you mean 'rays'?``, or ``""`` when no known name is close.

    The one "did you mean" of simrun (scene keys and types, sensor bodies, commands' entities): the known name
    closest to ``word`` by :func:`difflib.get_close_matches` (similarity ratio at least 0.6).

    Args:
        word: The name given (anything; compared as ``str(word)``).
        known: The names it may have meant.
    """
    close = difflib.get_close_matches(str(word), list(known), n=1, cutoff=0.6)
    return f"; did you mean {close[0]!r}?" if close else ""
