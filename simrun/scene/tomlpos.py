"""Line numbers of the keys, tables and array elements of a TOML document (``tomllib`` keeps none).

:func:`key_lines` scans a document that ``tomllib`` has already accepted and maps each key path, as the
parsed document would index it (``("entities", 3, "pose", "position", 1)``), to the 1-based line where its
value starts. Error messages use it to name the line of the value they refuse (:func:`line_of` falls back to
the nearest enclosing key that has a line). The scan understands the whole TOML 1.0 syntax that matters for
positions: table and array-of-table headers (nested ones too), dotted and quoted keys, inline tables,
arrays over several lines, the four kinds of strings and comments. :func:`read_toml` reads a scene, commands
or test file into its document and key lines, every failure a :class:`~simrun.errors.SceneError` with the line.
"""

from __future__ import annotations

import bisect
import tomllib
from pathlib import Path
from typing import Any

from meshtool.files.nesting import DocumentLimitError, bounded
from simrun.errors import SceneError
from simrun.safeio import MAX_FILE_BYTES, FileReadError, read_regular

KeyPath = tuple[str | int, ...]
_BARE = frozenset("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_-")


def key_lines(text: str) -> dict[KeyPath, int]:
    """Key path to line (1-based) for every key, table and array element of a valid TOML ``text``.

    On text that is not valid TOML the scan stops where it loses its way and returns what it found so far.
    """
    scanner = _Scanner(text)
    try:
        return scanner.run()
    except (IndexError, _Stuck, tomllib.TOMLDecodeError):
        return scanner.lines


class _Stuck(Exception):
    """The scan made no progress (the text is not the valid TOML it expects)."""


def line_of(lines: dict[KeyPath, int], path: KeyPath) -> int | None:
    """The line of ``path``, else of its nearest ancestor that has one, else ``None``."""
    for end in range(len(path), 0, -1):
        line = lines.get(path[:end])
        if line is not None:
            return line
    return None


class _Scanner:
    def __init__(self, text: str) -> None:
        self.text, self.i = text, 0
        self.newlines = [k for k, c in enumerate(text) if c == "\n"]
        self.lines: dict[KeyPath, int] = {}
        self.arrays: dict[KeyPath, int] = {}  # arrays of tables: resolved path to the number of elements

    def line(self) -> int:
        return bisect.bisect_right(self.newlines, self.i - 1) + 1 if self.i else 1

    def advanced(self, start: int) -> None:
        if self.i <= start:
            raise _Stuck

    def peek(self, n: int = 1) -> str:
        return self.text[self.i : self.i + n]

    def skip_blank(self, newlines: bool) -> None:
        text = self.text
        while self.i < len(text):
            c = text[self.i]
            if c in " \t\r" or (newlines and c == "\n"):
                self.i += 1
            elif c == "#":
                end = text.find("\n", self.i)
                self.i = len(text) if end < 0 else end
            else:
                return

    def run(self) -> dict[KeyPath, int]:
        table: KeyPath = ()
        while True:
            self.skip_blank(newlines=True)
            if self.i >= len(self.text):
                return self.lines
            line, start = self.line(), self.i
            if self.peek(2) == "[[":
                self.i += 2
                parts = self.key()
                self.skip_blank(newlines=False)
                self.i += 2
                array = self.resolve(parts, array=True)
                index = self.arrays.get(array, 0)
                self.arrays[array] = index + 1
                self.lines.setdefault(array, line)
                table = (*array, index)
                self.lines[table] = line
            elif self.peek() == "[":
                self.i += 1
                parts = self.key()
                self.skip_blank(newlines=False)
                self.i += 1
                table = self.resolve(parts, array=False)
                self.lines.setdefault(table, line)
            else:
                self.pair(table)
            self.advanced(start)

    def resolve(self, parts: list[str], array: bool) -> KeyPath:
        """A header's key path, with the last element of every array of tables it passes through."""
        path: KeyPath = ()
        for k, part in enumerate(parts):
            path = (*path, part)
            if path in self.arrays and not (array and k == len(parts) - 1):
                path = (*path, self.arrays[path] - 1)
        return path

    def pair(self, table: KeyPath) -> None:
        line = self.line()
        parts = self.key()
        path = table
        for part in parts:
            path = (*path, part)
            self.lines.setdefault(path, line)
        self.lines[path] = line
        self.skip_blank(newlines=False)
        self.i += 1  # '='
        self.skip_blank(newlines=False)
        self.value(path)

    def key(self) -> list[str]:
        parts = []
        while True:
            self.skip_blank(newlines=False)
            c = self.peek()
            if c in ('"', "'"):
                start = self.i
                self.string()
                parts.append(tomllib.loads(f"k = {self.text[start : self.i]}")["k"])
            else:
                start = self.i
                while self.i < len(self.text) and self.text[self.i] in _BARE:
                    self.i += 1
                parts.append(self.text[start : self.i])
            self.skip_blank(newlines=False)
            if self.peek() != ".":
                return parts
            self.i += 1

    def string(self) -> None:
        text, quote = self.text, self.text[self.i]
        if self.peek(3) == quote * 3:
            self.i += 3
            while True:
                if quote == '"' and text[self.i] == "\\":
                    self.i += 2
                elif text.startswith(quote * 3, self.i):
                    self.i += 3
                    while self.i < len(text) and text[self.i] == quote:  # up to two quotes before the closing ones
                        self.i += 1
                    return
                else:
                    self.i += 1
        self.i += 1
        while text[self.i] != quote:
            self.i += 2 if quote == '"' and text[self.i] == "\\" else 1
        self.i += 1

    def value(self, path: KeyPath) -> None:
        c = self.peek()
        if c in ('"', "'"):
            self.string()
        elif c == "[":
            self.i += 1
            index = 0
            while True:
                self.skip_blank(newlines=True)
                if self.peek() == "]":
                    self.i += 1
                    return
                self.lines[(*path, index)] = self.line()
                start = self.i
                self.value((*path, index))
                self.advanced(start)
                self.skip_blank(newlines=True)
                if self.peek() == ",":
                    self.i += 1
                index += 1
        elif c == "{":
            self.i += 1
            while True:
                self.skip_blank(newlines=True)
                if self.peek() == "}":
                    self.i += 1
                    return
                start = self.i
                self.pair(path)
                self.advanced(start)
                self.skip_blank(newlines=True)
                if self.peek() == ",":
                    self.i += 1
        else:
            text = self.text
            while self.i < len(text) and text[self.i] not in ",]}\n#":
                self.i += 1


def read_toml(
    path: Path, what: str = "file", limit: int = MAX_FILE_BYTES, name: str | None = None
) -> tuple[dict[str, Any], dict[KeyPath, int]]:
    """A TOML file's document and the lines of its keys (:func:`key_lines`).

    Args:
        path: The file (a regular file: :func:`simrun.safeio.read_regular`).
        what: What it is, for the messages (``scene``, ``commands file``).
        limit: Most bytes read.
        name: How messages name the file (default ``str(path)``).

    Raises:
        SceneError: Unreadable, too large, not UTF-8 (with the line of the bad byte), not TOML (with its line)
            or nested too deep.
    """
    name = str(path) if name is None else name
    try:
        raw = read_regular(path, what, limit)
    except FileReadError as exc:
        raise SceneError(str(exc)) from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        raise SceneError(f"not UTF-8 (byte {exc.start}); save it as UTF-8", name, line=line) from None
    try:
        doc = bounded(lambda: tomllib.loads(text))
    except DocumentLimitError as exc:
        raise SceneError(str(exc), name) from None
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"not valid TOML: {exc}", name, line=toml_error_line(exc)) from None
    return doc, key_lines(text)


def toml_error_line(exc: tomllib.TOMLDecodeError) -> int | None:
    """The line number in a ``tomllib`` error (its message ends ``(at line L, column C)``)."""
    line = getattr(exc, "lineno", None)
    if isinstance(line, int):
        return line
    text = str(exc)
    marker = "(at line "
    if marker in text:
        digits = text.split(marker, 1)[1].split(",", 1)[0].rstrip(")")
        if digits.isdigit():
            return int(digits)
    return None
