"""Errors raised by meshtool.

Every error meshtool raises derives from :class:`MeshtoolError`, and each subclass also derives from the
matching built-in exception, so callers may catch either. An error carries *where* (``path`` and ``line``,
or a byte ``offset``) and *how to fix it* (``hint``); ``str(error)`` is one line in the form
``path:line: message (hint)``.
"""

from __future__ import annotations


class MeshtoolError(Exception):
    """Base class of every error meshtool raises on purpose.

    Args:
        message: What is wrong, one sentence, no location.
        path: The file the problem is in, as the user named it (or relative to the asset folder).
        line: 1-based line number in ``path``, when known.
        offset: 0-based byte offset in ``path``, for binary data, when known.
        hint: How to fix it, one short sentence.
        code: A stable identifier for the kind of problem (e.g. ``non-finite``, ``pack-version``) where callers
            such as ``meshtool validate`` need to tell kinds apart; ``None`` otherwise.
    """

    def __init__(
        self,
        message: str,
        *,
        path: str | None = None,
        line: int | None = None,
        offset: int | None = None,
        hint: str | None = None,
        code: str | None = None,
    ) -> None:
        self.message = message
        self.code = code
        self.path = path
        self.line = line if line is None or line >= 1 else None  # 1-based: 0 (a format without lines) is none
        self.offset = offset
        self.hint = hint
        super().__init__(self.one_line())

    @property
    def where(self) -> str:
        """The location as ``path:line``, ``path@byte N`` or ``path`` (empty when unknown)."""
        if self.path is None:
            return ""
        if self.line is not None:
            return f"{self.path}:{self.line}"
        if self.offset is not None:
            return f"{self.path}: byte {self.offset}"
        return self.path

    def one_line(self) -> str:
        """Render the error as a single line: where, what, and the fix."""
        text = f"{self.where}: {self.message}" if self.where else self.message
        if self.hint:
            text += f" ({self.hint})"
        return text.replace("\n", " ")

    def to_dict(self) -> dict[str, object]:
        """A JSON-ready description of the error."""
        return {
            "type": type(self).__name__,
            "message": self.message,
            "path": self.path,
            "line": self.line,
            "offset": self.offset,
            "hint": self.hint,
        }


class ObjParseError(MeshtoolError, ValueError):
    """An OBJ file cannot be read: not OBJ, empty, a bad number, an invalid index."""


class MtlParseError(MeshtoolError, ValueError):
    """An MTL file cannot be read at all (individual bad statements become findings instead)."""


class TextureError(MeshtoolError, ValueError):
    """An image cannot be decoded or converted to PNG."""


class ResolveError(MeshtoolError, FileNotFoundError):
    """A file the user named directly (not a reference inside a file) cannot be read."""


class OutputError(MeshtoolError, OSError):
    """The output cannot be written where it was asked for, or would overwrite something it must not."""


class StrictModeError(MeshtoolError, ValueError):
    """``strict`` was set and the conversion produced warnings."""


class OptionsError(MeshtoolError, ValueError):
    """An option value is out of range or inconsistent."""


class PackFormatError(MeshtoolError, ValueError):
    """An ``.mbin`` file is truncated, corrupted, of an unknown major version, or hostile."""


class FormatError(MeshtoolError, ValueError):
    """A mesh file in a format other than OBJ (STL, PLY, glTF/GLB, COLLADA) cannot be read."""
