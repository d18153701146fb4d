"""PLY data: the binary (either byte order) and ASCII bodies, read into each element's :class:`Rows`.

Every element count is checked against the data actually present before anything is allocated for it, and
every list length against its row; errors name the byte offset (binary) or line (ASCII) where they occur.
"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from meshtool.errors import FormatError
from meshtool.findings import Finding, warning
from meshtool.read.ply_header import ENCODINGS, Element, Header
from meshtool.read.source_mesh import FloatArray, IntArray

__all__ = ["READ", "AnyArray", "Rows", "ascii_body", "binary_body", "number"]

READ = ("vertex", "face", "tristrips")  # the elements read; others are checked and skipped
_STRUCT = {"i1": "b", "u1": "B", "i2": "h", "u2": "H", "i4": "i", "u4": "I"}
_NUMBER = re.compile(rb"[+-]?(?:(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?|nan|inf|infinity)", re.IGNORECASE)
_SPACE = np.zeros(256, dtype=bool)
_SPACE[list(b" \t\r\n\v\f")] = True
_NUMBER_BYTE = _SPACE.copy()
_NUMBER_BYTE[list(b"0123456789+-.eEnNaAiIfFtTyY")] = True
_BINARY_HINT = "the file is cut short or corrupt, or its header names the wrong byte order"
_ASCII_HINT = "the file is cut short or corrupt, or its header's counts are wrong"

AnyArray = npt.NDArray[Any]


@dataclass(slots=True)
class Rows:
    """One element's data: scalar columns, lists (all values, and each row's length), row locations.

    Locations are line numbers in an ASCII file and byte offsets in a binary one. ``firsts`` (binary only):
    the byte offset of each row's first value of a list, and ``item_sizes`` the size of one value.
    """

    where: IntArray
    scalars: dict[str, AnyArray] = field(default_factory=dict)
    lists: dict[str, tuple[AnyArray, IntArray]] = field(default_factory=dict)
    firsts: dict[str, IntArray] = field(default_factory=dict)
    item_sizes: dict[str, int] = field(default_factory=dict)

    def locate(self, name: str, k: int) -> tuple[int, int]:
        """The row of value ``k`` of list ``name``, and the value's line (ASCII) or byte offset (binary)."""
        lengths = self.lists[name][1]
        ends = np.cumsum(lengths)
        row = int(np.searchsorted(ends, k, side="right"))
        if name not in self.firsts:
            return row, int(self.where[row])
        within = k - int(ends[row] - lengths[row])
        return row, int(self.firsts[name][row]) + within * self.item_sizes[name]


# ----------------------------------------------------------------------------------------------------------
# binary data


def binary_body(data: bytes, header: Header, path: str, findings: list[Finding]) -> dict[str, Rows]:
    """Every element's rows from binary data (rows of elements not in :data:`READ` are only walked over)."""
    order = ENCODINGS[header.encoding]
    pos = header.body
    out: dict[str, Rows] = {}
    for element in header.elements:
        out[element.name], pos = _binary_element(data, pos, element, order, path, element.name in READ)
    if pos < len(data):
        findings.append(
            warning(
                "ply-trailing-data",
                f"{len(data) - pos:,} bytes after the data the header declares (from byte {pos}): ignored",
                path,
            )
        )
    return out


def _binary_element(data: bytes, pos: int, element: Element, order: str, path: str, needed: bool) -> tuple[Rows, int]:
    """One element's rows from byte ``pos`` (only walked over when not ``needed``), and the offset after them."""
    props = element.properties
    count = element.count
    remaining = len(data) - pos
    smallest = sum(np.dtype(p.count_kind or p.kind).itemsize for p in props)
    if count * smallest > remaining:
        raise FormatError(
            f"PLY data too short: the header declares {count:,} {element.name!r} rows of at least {smallest} bytes "
            f"({count * smallest:,} bytes) but {remaining:,} bytes remain",
            path=path,
            offset=pos,
            hint=_BINARY_HINT,
        )
    if all(p.count_kind is None for p in props):
        dtype = np.dtype([(p.name, order + p.kind) for p in props])
        table = np.frombuffer(data, dtype, count, pos)
        rows = Rows(pos + np.arange(count, dtype=np.int64) * dtype.itemsize)
        rows.scalars = {p.name: table[p.name] for p in props}
        return rows, pos + count * dtype.itemsize
    layout = _Layout(element, order)
    where, lengths, after = _walk(data, pos, element, layout, path)
    rows = Rows(where)
    if not needed:
        return rows, after
    uniform = count > 0 and all(bool((n == n[0]).all()) for n in lengths.values())
    uniform_rows = _uniform_table(data, pos, element, order, lengths) if uniform else None
    offset = np.zeros(count, dtype=np.int64)  # offset of the current property in each row
    for k, p in enumerate(props):
        size = layout.sizes[k]
        if p.count_kind is None:
            column = uniform_rows[f"s{k}"] if uniform_rows is not None else _at(data, order + p.kind, where + offset)
            rows.scalars[p.name] = column
            offset += size
            continue
        n = lengths[k]
        first = where + offset + layout.count_sizes[k]
        if uniform_rows is not None:  # the usual case: every list as long (triangles)
            values = uniform_rows[f"v{k}"].reshape(-1) if n[0] else np.zeros(0, dtype=order + p.kind)
        else:
            within = np.arange(int(n.sum()), dtype=np.int64) - np.repeat(np.cumsum(n) - n, n)
            values = _at(data, order + p.kind, np.repeat(first, n) + within * size)
        rows.lists[p.name] = (values, n)
        rows.firsts[p.name] = first
        rows.item_sizes[p.name] = size
        offset += n * size + layout.count_sizes[k]
    return rows, after


def _uniform_table(data: bytes, pos: int, element: Element, order: str, lengths: dict[int, IntArray]) -> AnyArray:
    """The rows of an element whose lists are all as long in every row, as one structured array."""
    fields: list[tuple[Any, ...]] = []
    for k, p in enumerate(element.properties):
        if p.count_kind is None:
            fields.append((f"s{k}", order + p.kind))
            continue
        fields.append((f"c{k}", order + p.count_kind))
        if lengths[k][0]:
            fields.append((f"v{k}", order + p.kind, (int(lengths[k][0]),)))
    table: AnyArray = np.frombuffer(data, np.dtype(fields), element.count, pos)
    return table


class _Layout:
    """Sizes of an element's properties (a list's value size, and its length's size and struct format)."""

    def __init__(self, element: Element, order: str) -> None:
        self.sizes = [np.dtype(p.kind).itemsize for p in element.properties]
        self.count_sizes = [np.dtype(p.count_kind).itemsize if p.count_kind else 0 for p in element.properties]
        self.formats = [order + _STRUCT[p.count_kind] if p.count_kind else "" for p in element.properties]


def _walk(
    data: bytes, pos: int, element: Element, layout: _Layout, path: str
) -> tuple[IntArray, dict[int, IntArray], int]:
    """Row offsets, list lengths (by property number) and the end offset of an element with lists.

    Rows whose lists all have the lengths of the first row's are read in one step; otherwise row by row.
    """
    props = element.properties
    count = element.count
    lists = [k for k, p in enumerate(props) if p.count_kind is not None]
    if count == 0:
        empty = np.zeros(0, dtype=np.int64)
        return empty, {k: empty for k in lists}, pos
    first_lengths, size = _row(data, pos, element, layout, path, 0)
    if count * size <= len(data) - pos:  # the same lengths everywhere?
        starts = pos + np.arange(count, dtype=np.int64) * size
        offset, same = 0, True
        lengths: dict[int, IntArray] = {}
        for k, p in enumerate(props):
            if p.count_kind is None:
                offset += layout.sizes[k]
                continue
            n = _at(data, layout.formats[k][0] + p.count_kind, starts + offset).astype(np.int64)
            same = same and bool((n == first_lengths[k]).all())
            lengths[k] = n
            offset += layout.count_sizes[k] + first_lengths[k] * layout.sizes[k]
        if same:
            return starts, lengths, pos + count * size
    if len(lists) == 1:
        return _walk_one_list(data, pos, element, layout, path, lists[0])
    row_starts = np.zeros(count, dtype=np.int64)
    all_lengths = {k: np.zeros(count, dtype=np.int64) for k in lists}
    for r in range(count):
        row_starts[r] = pos
        row_lengths, size = _row(data, pos, element, layout, path, r)
        for k, length in row_lengths.items():
            all_lengths[k][r] = length
        pos += size
    return row_starts, all_lengths, pos


def _walk_one_list(
    data: bytes, pos: int, element: Element, layout: _Layout, path: str, k: int
) -> tuple[IntArray, dict[int, IntArray], int]:
    """:func:`_walk` for rows with one list (faces of mixed sizes): a tight loop, checked at the end."""
    before = sum(layout.sizes[:k])
    fixed = before + sum(layout.sizes[k + 1 :]) + layout.count_sizes[k]
    size, item = len(data), layout.sizes[k]
    fmt = struct.Struct(layout.formats[k])
    starts: list[int] = []
    lengths: list[int] = []
    if fmt.size == 1 and fmt.format.endswith("B"):  # uchar lengths (most faces): data[i] is the fastest read
        append = starts.append
        try:
            for _ in range(element.count):
                append(pos)
                pos += fixed + data[pos + before] * item
        except IndexError:  # this row's length lies past the end
            pos = starts.pop()
        found = np.asarray(starts, dtype=np.int64)
        if pos <= size and len(starts) == element.count:
            return found, {k: _at(data, "u1", found + before).astype(np.int64)}, pos
    else:
        unpack = fmt.unpack_from
        for _ in range(element.count):
            if pos + fixed > size:
                break
            n = unpack(data, pos + before)[0]
            if n < 0:
                break
            starts.append(pos)
            lengths.append(n)
            pos += fixed + n * item
    if pos > size:  # the last row read runs past the end: say exactly how
        _row(data, starts[-1], element, layout, path, len(starts) - 1)
        raise _binary_short(element, len(starts) - 1, path, starts[-1], size)
    if len(starts) < element.count:  # the next row does not fit, or has a negative length
        _row(data, pos, element, layout, path, len(starts))
        raise _binary_short(element, len(starts), path, pos, size)
    return np.asarray(starts, dtype=np.int64), {k: np.asarray(lengths, dtype=np.int64)}, pos


def _row(data: bytes, pos: int, element: Element, layout: _Layout, path: str, r: int) -> tuple[dict[int, int], int]:
    """The list lengths (by property number) and the size of row ``r`` at byte ``pos``; checked against the data."""
    start = pos
    lengths: dict[int, int] = {}
    size = len(data)
    for k, fmt in enumerate(layout.formats):
        if not fmt:
            pos += layout.sizes[k]
            continue
        if pos + layout.count_sizes[k] > size:
            raise _binary_short(element, r, path, start, size)
        n = struct.unpack_from(fmt, data, pos)[0]
        name = element.properties[k].name
        if n < 0:
            raise FormatError(
                f"{element.name!r} row {r + 1:,}: list {name!r} has a negative length ({n})",
                path=path,
                offset=pos,
                hint=_BINARY_HINT,
            )
        end = pos + layout.count_sizes[k] + n * layout.sizes[k]
        if end > size:
            raise FormatError(
                f"{element.name!r} row {r + 1:,}: list {name!r} of {n:,} values runs past the end of the data "
                f"(to byte {end:,} of {size:,})",
                path=path,
                offset=pos,
                hint=_BINARY_HINT,
            )
        lengths[k] = n
        pos = end
    if pos > size:
        raise _binary_short(element, r, path, start, size)
    return lengths, pos - start


def _binary_short(element: Element, r: int, path: str, offset: int, size: int) -> FormatError:
    return FormatError(
        f"PLY data too short: {element.name!r} row {r + 1:,} of {element.count:,} runs past the end of the data "
        f"({size:,} bytes)",
        path=path,
        offset=offset,
        hint=_BINARY_HINT,
    )


def _at(data: bytes, kind: str, offsets: IntArray) -> AnyArray:
    """Values of type ``kind`` at arbitrary byte ``offsets`` of ``data`` (all checked to be inside it)."""
    dtype = np.dtype(kind)
    if offsets.size == 0:
        return np.zeros(0, dtype=dtype)
    view: AnyArray = np.ndarray((len(data) - dtype.itemsize + 1,), dtype=dtype, buffer=data, strides=(1,))
    return view[offsets]


# ----------------------------------------------------------------------------------------------------------
# ASCII data


def ascii_body(data: bytes, header: Header, path: str, findings: list[Finding]) -> dict[str, Rows]:
    """Every element's rows: one row per (non-blank) line, exactly the values its properties take."""
    body = data[header.body :]
    arr = np.frombuffer(body, dtype=np.uint8)
    newline = 10 if b"\n" in body else 13
    breaks = np.flatnonzero(arr == newline)
    first_line = header.lines + 1

    def line_of(byte: int) -> int:
        return first_line + int(np.searchsorted(breaks, byte))

    allowed = _NUMBER_BYTE[arr]
    if not allowed.all():
        bad = int(np.argmin(allowed))
        raise _not_number(path, line_of(bad), _token_at(body, bad))
    space = _SPACE[arr]
    starts = np.flatnonzero(~space & np.concatenate(([True], space[:-1]))) if arr.size else np.zeros(0, np.int64)
    values = _numbers(body, starts, path, line_of)
    token_line = np.searchsorted(breaks, starts)
    new_row = np.concatenate(([True], token_line[1:] != token_line[:-1])) if starts.size else np.zeros(0, bool)
    row_first = np.flatnonzero(new_row)
    row_size = np.diff(np.append(row_first, starts.size))
    row_line = first_line + token_line[row_first]
    out: dict[str, Rows] = {}
    at = 0
    for element in header.elements:
        if at + element.count > row_first.size:
            last = int(row_line[-1]) if row_line.size else header.lines
            raise FormatError(
                f"PLY data ends at line {last:,} after {row_first.size - at:,} of the {element.count:,} "
                f"{element.name!r} rows the header declares",
                path=path,
                line=last,
                hint=_ASCII_HINT,
            )
        span = slice(at, at + element.count)
        out[element.name] = _ascii_element(element, values, row_first[span], row_size[span], row_line[span], path)
        at += element.count
    if at < row_first.size:
        findings.append(
            warning(
                "ply-trailing-data",
                f"{row_first.size - at:,} line(s) of data after the rows the header declares (from line "
                f"{int(row_line[at])}): ignored",
                path,
            )
        )
    elif arr.size and not space[-1] and any(e.count for e in header.elements):
        findings.append(
            warning(
                "ply-unterminated",
                f"the last line ({line_of(arr.size - 1)}) has no line end: if the file was cut short, its last value "
                "may be incomplete",
                path,
            )
        )
    return out


def _numbers(body: bytes, starts: IntArray, path: str, line_of: Any) -> FloatArray:
    """Every whitespace-separated value of ``body`` (whose tokens start at ``starts``) as float64."""
    if starts.size == 0:
        return np.zeros(0, dtype=np.float64)
    try:
        values: FloatArray = np.fromstring(body, dtype=np.float64, sep=" ")
        if values.size == starts.size:
            return values
    except ValueError:
        pass
    out = np.empty(starts.size, dtype=np.float64)  # the slow path says which value is wrong
    for k, word in enumerate(body.split()):
        if not _NUMBER.fullmatch(word):
            raise _not_number(path, line_of(int(starts[k])), word.decode("latin-1"))
        out[k] = float(word)
    return out


def _token_at(body: bytes, at: int) -> str:
    start = at
    while start > 0 and at - start < 40 and body[start - 1 : start] not in (b" ", b"\t", b"\r", b"\n"):
        start -= 1
    end = at + 1
    while end < len(body) and end - at < 40 and body[end : end + 1] not in (b" ", b"\t", b"\r", b"\n"):
        end += 1
    return body[start:end].decode("latin-1")


def _not_number(path: str, line: int, word: str) -> FormatError:
    return FormatError(
        f"PLY value {word[:30]!r} is not a number", path=path, line=line, hint="fix or export the file again"
    )


def _ascii_element(
    element: Element, values: FloatArray, first: IntArray, size: IntArray, lines: IntArray, path: str
) -> Rows:
    """One element's rows; ``first``/``size``/``lines``: each row's first value, value count and line."""
    rows = Rows(lines.astype(np.int64))
    cur = first.astype(np.int64)
    end = cur + size
    for p in element.properties:
        short = cur >= end
        if short.any():
            raise _row_size(element, np.flatnonzero(short)[0], size, lines, "more", path)
        v = values[cur]
        if p.count_kind is None:
            rows.scalars[p.name] = v
            cur = cur + 1
            continue
        with np.errstate(invalid="ignore"):
            bad = ~((v >= 0) & (np.floor(v) == v))
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            raise FormatError(
                f"{element.name!r} row {k + 1:,}: list {p.name!r} length {number(v[k])} is not a whole number of "
                "0 or more",
                path=path,
                line=int(lines[k]),
                hint=_ASCII_HINT,
            )
        long = v > end - cur - 1
        if long.any():
            k = int(np.flatnonzero(long)[0])
            raise FormatError(
                f"{element.name!r} row {k + 1:,}: list {p.name!r} of {number(v[k])} values runs past the end of its "
                f"line ({int(size[k])} value{'' if size[k] == 1 else 's'})",
                path=path,
                line=int(lines[k]),
                hint=_ASCII_HINT,
            )
        n = v.astype(np.int64)
        total = int(n.sum())
        item = np.repeat(cur + 1, n) + np.arange(total, dtype=np.int64) - np.repeat(np.cumsum(n) - n, n)
        rows.lists[p.name] = (values[item], n)
        cur = cur + 1 + n
    extra = cur < end
    if extra.any():
        k = int(np.flatnonzero(extra)[0])
        raise _row_size(element, k, size, lines, str(int(cur[k] - first[k])), path)
    return rows


def _row_size(element: Element, k: Any, size: IntArray, lines: IntArray, takes: str, path: str) -> FormatError:
    k = int(k)
    return FormatError(
        f"{element.name!r} row {k + 1:,} has {int(size[k])} values but its properties take {takes}",
        path=path,
        line=int(lines[k]),
        hint=_ASCII_HINT,
    )


def number(value: float) -> str:
    """``value`` for a message: a whole number without decimals, otherwise as ``%g``."""
    return f"{value:.0f}" if np.isfinite(value) and value == np.floor(value) else f"{value:g}"
