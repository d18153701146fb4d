"""PLY header: ``ply``, ``format``, ``element``, ``property [list]``, ``comment``, ``obj_info``, ``end_header``.

:func:`parse_header` checks the header line by line (anything else is an error naming the line) and returns
its encoding, its elements with their properties (PLY type names turned into numpy type codes), the byte
offset and line where the data starts, and the ``comment TextureFile NAME`` texture if there is one.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from meshtool.errors import FormatError

__all__ = ["ENCODINGS", "Element", "Header", "Property", "head", "parse_header"]

_TEXTURE = re.compile(r"^comment\s+TextureFile\s+(.+?)\s*$", re.IGNORECASE)
_INDEX_LISTS = ("vertex_indices", "vertex_index")
ENCODINGS = {"ascii": "", "binary_little_endian": "<", "binary_big_endian": ">"}
#: PLY type names -> numpy type codes (without byte order).
_TYPES = {
    "char": "i1",
    "int8": "i1",
    "uchar": "u1",
    "uint8": "u1",
    "short": "i2",
    "int16": "i2",
    "ushort": "u2",
    "uint16": "u2",
    "int": "i4",
    "int32": "i4",
    "uint": "u4",
    "uint32": "u4",
    "float": "f4",
    "float32": "f4",
    "double": "f8",
    "float64": "f8",
}
#: Longest element count accepted in the header, in digits (larger counts cannot be backed by any file).
_COUNT_DIGITS = 19


# ----------------------------------------------------------------------------------------------------------
# header


@dataclass(slots=True)
class Property:
    """One ``property`` line of an element: a scalar, or a list (``count_kind`` set)."""

    name: str
    kind: str  # numpy type code without byte order ("f4")
    count_kind: str | None  # the list length's type code; None for a scalar property
    line: int


@dataclass(slots=True)
class Element:
    """One ``element`` line: its name, row count, line and properties."""

    name: str
    count: int
    line: int
    properties: list[Property] = field(default_factory=list)

    def has(self, *names: str) -> bool:
        """Whether the element has scalar properties of all these ``names``."""
        scalars = {p.name for p in self.properties if p.count_kind is None}
        return all(n in scalars for n in names)

    def index_list(self) -> str | None:
        """The name of the element's vertex index list (``vertex_indices`` or ``vertex_index``), or None."""
        lists = {p.name for p in self.properties if p.count_kind is not None}
        return next((n for n in _INDEX_LISTS if n in lists), None)


@dataclass(slots=True)
class Header:
    """The parsed header: encoding, elements, where the data starts, and the ``TextureFile`` (name, line)."""

    encoding: str
    elements: list[Element]
    body: int  # byte offset of the first data byte
    lines: int  # number of header lines (the data starts on the next line)
    texture: tuple[str, int] | None


def parse_header(data: bytes, path: str) -> Header:
    """The header of PLY file ``data``, checked line by line.

    Raises:
        FormatError: Not a PLY file, or a malformed header (naming the line).
    """
    first = re.match(rb"ply[ \t]*(\r\n|\n|\r)", data)
    if first is None:
        raise FormatError("not a PLY file: it does not start with a 'ply' line", path=path, hint="pass a PLY file")
    end = _end_header(data, path)
    raw_lines = data[:end].splitlines()
    body = end + len(b"end_header")
    while body < len(data) and data[body] in b" \t":
        body += 1
    if data.startswith(b"\r\n", body):
        body += 2
    elif body < len(data) and data[body] in b"\r\n":
        body += 1
    elif body < len(data):
        raise FormatError(
            "malformed 'end_header' line", path=path, line=len(raw_lines) + 1, hint="the header is damaged"
        )
    encoding: str | None = None
    elements: list[Element] = []
    texture: tuple[str, int] | None = None
    for number, raw in enumerate(raw_lines[1:], 2):
        words = raw.split()
        if not words:
            continue
        key = words[0]
        if key in (b"comment", b"obj_info"):
            text = raw.decode("utf-8", "replace")
            match = _TEXTURE.match(text.strip())
            if match and texture is None:
                texture = (match.group(1).strip(), number)
            continue
        if not raw.isascii() or any(b < 32 and b != 9 for b in raw.rstrip(b"\r\n")):
            raise head(path, number, f"non-ASCII or control bytes in the header line {_show(raw)}")
        text_words = [w.decode("ascii") for w in words]
        if key == b"format":
            if encoding is not None:
                raise head(path, number, "a second 'format' line")
            if len(text_words) != 3 or text_words[1] not in ENCODINGS:
                raise head(
                    path,
                    number,
                    f"unknown format {' '.join(text_words[1:])[:40]!r} (expected ascii, binary_little_endian or "
                    "binary_big_endian, then the version 1.0)",
                )
            encoding = text_words[1]
        elif key == b"element":
            elements.append(_element(text_words, number, elements, path))
        elif key == b"property":
            if not elements:
                raise head(path, number, "'property' before any 'element'")
            elements[-1].properties.append(_property(text_words, number, elements[-1], path))
        else:
            raise head(path, number, f"unknown header keyword {text_words[0][:20]!r}")
    if encoding is None:
        raise head(path, 2, "no 'format' line")
    for element in elements:
        if element.count and not element.properties:
            raise head(path, element.line, f"element {element.name!r} has {element.count:,} rows but no properties")
    return Header(encoding, elements, body, len(raw_lines) + 1, texture)


def _end_header(data: bytes, path: str) -> int:
    """Byte offset of the ``end_header`` that starts a line."""
    start = 0
    while True:
        end = data.find(b"end_header", start)
        if end < 0:
            raise FormatError("PLY header has no 'end_header' line", path=path, offset=0, hint="the file is damaged")
        if data[end - 1 : end] in (b"\n", b"\r"):
            return end
        start = end + 1


def _element(words: list[str], line: int, elements: list[Element], path: str) -> Element:
    if len(words) != 3:
        raise head(path, line, "'element' needs a name and a count")
    name, count = words[1], words[2]
    if not count.isdigit() or len(count) > _COUNT_DIGITS:
        raise head(path, line, f"element {name!r} count {count[:30]!r} is not a whole number of 0 or more")
    if any(e.name == name for e in elements):
        raise head(path, line, f"a second element {name!r}")
    return Element(name, int(count), line)


def _property(words: list[str], line: int, element: Element, path: str) -> Property:
    if len(words) >= 2 and words[1] == "list":
        if len(words) != 5:
            raise head(path, line, "'property list' needs a count type, a value type and a name")
        count_kind, kind, name = _TYPES.get(words[2]), _TYPES.get(words[3]), words[4]
        if count_kind is None or count_kind[0] == "f":
            raise head(path, line, f"list count type {words[2][:20]!r} is not an integer type")
    else:
        if len(words) != 3:
            raise head(path, line, "'property' needs a type and a name")
        count_kind, kind, name = None, _TYPES.get(words[1]), words[2]
    if kind is None:
        raise head(path, line, f"unknown property type {words[-2][:20]!r}")
    if any(p.name == name for p in element.properties):
        raise head(path, line, f"element {element.name!r} has a second property {name!r}")
    return Property(name, kind, count_kind, line)


def head(path: str, line: int, what: str) -> FormatError:
    """The error for a malformed header: ``what`` is wrong, at ``line``."""
    return FormatError(f"malformed PLY header: {what}", path=path, line=line, hint="the header is damaged")


def _show(raw: bytes) -> str:
    return repr(raw.decode("latin-1")[:40])
