"""Line classification and vectorised number parsing for OBJ text.

A block is every line of one statement kind joined together; its numbers are read in one numpy call.
When that is not possible (inline comments, malformed numbers, MSVC ``1.#IND`` spellings), callers fall
back to :func:`slow_numbers`, which reads line by line and names the bad line.
"""

from __future__ import annotations

import io
import math
import re
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from meshtool.errors import ObjParseError
from meshtool.read.obj.decimals import decimal_numbers

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]

OTHER, V, VT, VN, F, SKIP = range(6)
#: For each of ``V``, ``VT``, ``VN``: values, count per line, 1-based line numbers (see :func:`float_blocks`).
FloatBlocks = dict[int, tuple[FloatArray, IntArray, IntArray]]
_LEADING_WS = re.compile(rb"^[ \t\f\v]+", re.MULTILINE)
_COMMENT = re.compile(r"(?:^|\s)#")
_MSVC_SPECIAL = re.compile(r"^[+-]?1\.#(INF|IND|QNAN|SNAN)\d*$", re.IGNORECASE)
# Bytes that never occur in a text OBJ (tab, LF, VT, FF are allowed; CR was converted by the decoder).
_CONTROL = re.compile(rb"[\x00-\x08\x0e-\x1f]")
_NOT_CONTROL = bytes(b for b in range(256) if not (b < 9 or 13 < b < 32))


@dataclass(slots=True)
class Lines:
    """The decoded text as UTF-8 bytes with per-line start/end offsets and statement kinds."""

    raw: bytes
    starts: IntArray
    ends: IntArray  # index of the terminating b"\n"
    kinds: npt.NDArray[np.int8]

    def text(self, i: int) -> str:
        """Line ``i`` (0-based) as text, without its newline."""
        return self.raw[int(self.starts[i]) : int(self.ends[i])].decode("utf-8")


def reject_control_bytes(raw: bytes, path: str) -> None:
    """Refuse decoded text that holds a NUL or another binary control byte anywhere, naming its line.

    The decoder may look for binary data at the start of a file only; this scans all of it (two vectorised
    comparisons, about 0.1 ms per MB), so a NUL after the first 64 KiB is an error with ``path:line``
    instead of text that flows on into names and numbers.

    Raises:
        ObjParseError: At the first control byte.
    """
    if not raw.translate(None, _NOT_CONTROL):  # keeps only control bytes: one C pass, nothing allocated
        return
    match = _CONTROL.search(raw)
    if match is None:  # unreachable: the same bytes as the comparisons
        return
    at = match.start()
    column = at - raw.rfind(b"\n", 0, at)
    raise ObjParseError(
        f"binary byte 0x{raw[at]:02x} in the text (column {column}): not a text OBJ file",
        path=path,
        line=raw.count(b"\n", 0, at) + 1,
        hint="remove the byte or export the file again as text",
    )


def classify(raw: bytes) -> Lines:
    """Split LF-terminated text into lines and classify each by its first bytes (v, vt, vn, f, skip, other)."""
    buf = np.frombuffer(raw, dtype=np.uint8)
    ends = np.flatnonzero(buf == 10).astype(np.int64, copy=False)
    starts = np.empty_like(ends)
    if ends.size:
        starts[0] = 0
        starts[1:] = ends[:-1] + 1
    # every line ends with its newline, so a line's second and third bytes exist or are past the end of
    # the text; clipping to the last byte (a newline) reads them as newline (no padded copy of the text)
    last = max(buf.size - 1, 0)
    c0 = buf[starts] if buf.size else np.zeros(0, dtype=np.uint8)
    if ((c0 == 32) | (c0 == 9) | (c0 == 11) | (c0 == 12)).any():  # indented: strip the indentation, keep lines
        return classify(_LEADING_WS.sub(b"", raw))
    c1 = buf[np.minimum(starts + 1, last)] if buf.size else c0
    c2 = buf[np.minimum(starts + 2, last)] if buf.size else c0

    def space(c: npt.NDArray[np.uint8]) -> BoolArray:
        result: BoolArray = (c == 32) | (c == 9) | (c == 10) | (c == 11) | (c == 12)
        return result

    kinds = np.full(ends.shape, OTHER, dtype=np.int8)
    kinds[(c0 == 10) | (c0 == 35)] = SKIP
    is_v = c0 == 118
    kinds[is_v & space(c1)] = V
    kinds[is_v & (c1 == 116) & space(c2)] = VT
    kinds[is_v & (c1 == 110) & space(c2)] = VN
    kinds[(c0 == 102) & space(c1)] = F
    return Lines(raw, starts, ends, kinds)


# ----------------------------------------------------------------------------------------------------------
# vectorised blocks


def gather(lines: Lines, kind: int) -> tuple[bytes, IntArray]:
    """All lines of one kind joined into one block (each ending in a newline), and their line numbers."""
    selected = lines.kinds == kind
    idx = np.flatnonzero(selected)
    return gather_lines(lines, idx, selected), idx.astype(np.int64, copy=False) + 1


def gather_lines(lines: Lines, idx: IntArray, selected: BoolArray) -> bytes:
    """The lines ``idx`` (0-based, ascending; ``selected`` is their mask) joined into one block."""
    if idx.size == 0:
        return b""
    breaks = np.flatnonzero(np.diff(idx) != 1)
    raw = lines.raw
    if breaks.size >= _JOIN_RUNS:  # interleaved statements (v, vt, vn per vertex): select the bytes in one pass
        mask = np.repeat(selected, lines.ends - lines.starts + 1)
        return np.frombuffer(raw, dtype=np.uint8)[: mask.size][mask].tobytes()
    first = idx[np.concatenate([[0], breaks + 1])]
    last = idx[np.concatenate([breaks, [idx.size - 1]])]
    return b"".join(
        raw[s:e] for s, e in zip(lines.starts[first].tolist(), (lines.ends[last] + 1).tolist(), strict=True)
    )


def float_blocks(lines: Lines) -> FloatBlocks | None:
    """``v``, ``vt`` and ``vn`` lines read together by :func:`decimal_numbers`, or ``None``.

    ``None`` when they are not all plain decimals: each kind is then read by :func:`vector_block`.

    One block and one parse for the three kinds: an exporter that writes ``v``/``vt``/``vn`` interleaved per
    vertex costs one byte selection instead of three.

    Returns:
        For each of ``V``, ``VT``, ``VN``: the values, the count per line and the 1-based line numbers, as
        :func:`vector_block` returns them.
    """
    kinds = lines.kinds
    selected = (kinds == V) | (kinds == VT) | (kinds == VN)
    idx = np.flatnonzero(selected)
    if idx.size == 0:
        return None
    line_kind = kinds[idx]
    n_vt = int(np.count_nonzero(line_kind == VT))
    n_vn = int(np.count_nonzero(line_kind == VN))
    parsed = decimal_numbers(gather_lines(lines, idx, selected), {118: idx.size, 116: n_vt, 110: n_vn})
    if parsed is None:
        return None
    values, counts = parsed
    if n_vt == 0 and n_vn == 0:
        return {V: (values, counts, idx + 1), VT: _EMPTY_BLOCK, VN: _EMPTY_BLOCK}
    value_kind = np.repeat(line_kind, counts)
    out: FloatBlocks = {}
    for kind in (V, VT, VN):
        mine = line_kind == kind
        out[kind] = (values[value_kind == kind], counts[mine], idx[mine].astype(np.int64, copy=False) + 1)
    return out


_EMPTY_BLOCK = (np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64))


#: Runs of consecutive lines up to which :func:`gather` joins slices; beyond, it selects bytes with a mask.
_JOIN_RUNS = 64


def _token_starts(a: npt.NDArray[np.uint8], block: bytes) -> npt.NDArray[np.bool_]:
    """Mask of the bytes that start a whitespace-separated token."""
    if b"\t" in block or b"\v" in block or b"\f" in block:
        ws = (a == 32) | (a == 9) | (a == 10) | (a == 11) | (a == 12)
    else:
        ws = (a == 32) | (a == 10)
    starts: npt.NDArray[np.bool_] = np.empty_like(ws)
    starts[0] = not ws[0]
    np.logical_and(~ws[1:], ws[:-1], out=starts[1:])
    return starts


def _line_starts(a: npt.NDArray[np.uint8]) -> IntArray:
    ends = np.flatnonzero(a == 10)
    line_starts = np.empty_like(ends)
    line_starts[0] = 0
    line_starts[1:] = ends[:-1] + 1
    return line_starts


def per_line(marks: npt.NDArray[np.bool_], line_starts: IntArray) -> IntArray:
    """How many of ``marks`` (one flag per byte) are set on each line (lines begin at ``line_starts``).

    The positions of the set flags are searched for the line starts: memory grows with the flags set (the
    numbers of an OBJ block), never 8 bytes per byte of text as ``np.add.reduceat(..., dtype=int64)``
    did (a 224 MB temporary for a 43 MB file, issue 28).
    """
    where = np.flatnonzero(marks)
    bounds = np.searchsorted(where, line_starts)
    counts: IntArray = np.diff(bounds, append=where.size)
    return counts


def token_counts(block: bytes) -> IntArray:
    """Number of tokens (keyword included) on each line of a block."""
    a = np.frombuffer(block, dtype=np.uint8)
    return per_line(_token_starts(a, block), _line_starts(a))


def tokens(block: bytes) -> tuple[npt.NDArray[np.uint8], IntArray, IntArray, IntArray]:
    """Tokens of a block whose lines each start with their keyword.

    Returns:
        The block as bytes, each token's start offset, the index of each line's first token (its keyword)
        and each line's token count (keyword included).
    """
    a = np.frombuffer(block, dtype=np.uint8)
    tstart = np.flatnonzero(_token_starts(a, block))
    first = np.searchsorted(tstart, _line_starts(a))
    counts = np.diff(np.append(first, tstart.size))
    return a, tstart, first, counts


def numbers(
    block: bytes, keyword: bytes, dtype: type[np.generic], blank_slashes: bool = False
) -> npt.NDArray[np.generic] | None:
    """Every number of a block in order, or ``None`` when the block needs the line-by-line path.

    One ``np.fromstring`` call over the block with its keywords (and, for faces, slashes) blanked: numpy's
    text parser reads Python's float syntax (correctly rounded) and raises on anything else, including two
    numbers glued together (``3-4``) or a token that is not a number, so when it succeeds every
    whitespace-separated token was exactly one number. No Python object is made per number.
    """
    if b"#" in block or b"(" in block or not block.isascii():  # inline comment, nan(...), non-ASCII digits
        return None
    text = _blank(block, keyword, blank_slashes)
    try:
        values: npt.NDArray[np.generic] = np.fromstring(text, dtype=dtype, sep=" ")
    except (ValueError, TypeError):
        return None
    return values


def float_table(block: bytes, keyword: bytes, lines: int) -> FloatArray | None:
    """The block's numbers as a (lines, columns) table when every line holds the same count, else ``None``.

    numpy's ``loadtxt`` (a C tokenizer; Python's float syntax, correctly rounded, anything else an error) reads
    the keyword-blanked block; a line with another count of values, or none, means ``None`` (the caller reads
    the block number by number instead).
    """
    if b"#" in block or b"(" in block or not block.isascii():
        return None
    text = _blank(block, keyword, False, lines)
    if text.isspace():  # every line a bare keyword (loadtxt would warn "input contained no data")
        return None
    try:
        table: FloatArray = np.loadtxt(io.BytesIO(text), dtype=np.float64, ndmin=2)
    except ValueError:
        return None
    if table.shape[0] != lines or table.shape[1] == 0:
        return None  # a line with the keyword alone is blank to loadtxt, which skips it
    return table


_BLANK_TABLES: dict[tuple[bytes, bool], bytes] = {}


def _blank(block: bytes, keyword: bytes, slashes: bool, lines: int | None = None) -> bytes:
    """The block with each line's keyword (and every ``/`` when ``slashes``) replaced by spaces.

    One ``bytes.translate`` pass when the keyword's letters occur once per line (so only in the keywords:
    checked by counting them); a ``replace`` of each line's keyword otherwise.
    """
    if lines is None:
        lines = block.count(b"\n")
    if all(block.count(bytes([c])) == lines for c in set(keyword)):
        return blank_keywords(block, keyword, slashes)
    blank = b" " * len(keyword)
    text = blank + block[len(keyword) :].replace(b"\n" + keyword, b"\n" + blank)
    return text.replace(b"/", b" ") if slashes else text


def blank_keywords(block: bytes, keyword: bytes, slashes: bool) -> bytes:
    """The block with every byte of ``keyword``'s letters (and every ``/`` when ``slashes``) a space.

    One ``bytes.translate`` pass; the caller has checked that the letters occur in the keywords only.
    """
    table = _BLANK_TABLES.get((keyword, slashes))
    if table is None:
        chars = keyword + (b"/" if slashes else b"")
        table = _BLANK_TABLES[(keyword, slashes)] = bytes.maketrans(chars, b" " * len(chars))
    return block.translate(table)


def values_per_line(block: bytes, total: int) -> IntArray:
    """Numbers on each line of a block (tokens after the keyword), given that ``total`` were read from it.

    Where tokens are separated by single spaces, a line holds as many numbers as spaces: counted in one pass,
    and accepted when the counts add up to ``total`` (extra spaces would only add to them, so equal sums mean
    every line is exact). Otherwise (tabs, doubled or trailing spaces) the tokens are counted.
    """
    if b"\t" not in block and b"\v" not in block and b"\f" not in block:
        a = np.frombuffer(block, dtype=np.uint8)
        counts = per_line(np.equal(a, 32), _line_starts(a))
        if int(counts.sum()) == total:
            return counts
    exact: IntArray = token_counts(block) - 1
    return exact


def slow_numbers(lines: Lines, line_numbers: IntArray, keyword: str, path: str) -> tuple[FloatArray, IntArray]:
    """Read a block line by line: values and per-line counts; raises naming the line of a bad number."""
    values: list[float] = []
    counts = np.zeros(line_numbers.size, dtype=np.int64)
    for k, line_no in enumerate(line_numbers.tolist()):
        words = strip_comment(lines.text(line_no - 1)).split()[1:]
        for word in words:
            try:
                values.append(parse_float(word))
            except ValueError:
                raise ObjParseError(
                    f"'{keyword}' statement has a malformed number {word[:30]!r}",
                    path=path,
                    line=line_no,
                    hint="fix or remove the line",
                ) from None
        counts[k] = len(words)
    return np.asarray(values, dtype=np.float64), counts


def strip_comment(line: str) -> str:
    """Drop a trailing ``# comment`` (a ``#`` at the start of a word; ``1.#IND`` is a number)."""
    match = _COMMENT.search(line)
    return line[: match.start()] if match else line


def parse_float(word: str) -> float:
    """``float`` that also reads the MSVC spellings ``1.#IND``, ``-1.#INF``, ``1.#QNAN``.

    Python's own ``float`` is more lenient than OBJ: it reads ``1_0`` as 10 and non-ASCII digits; both are
    refused here (``ValueError``). ``nan`` and ``inf`` are read; callers decide what non-finite values mean.
    """
    if "_" in word or not word.isascii():
        raise ValueError(word)
    try:
        return float(word)
    except ValueError:
        special = _MSVC_SPECIAL.match(word)
        if not special:
            raise
        sign = -1.0 if word.startswith("-") else 1.0
        return sign * math.inf if special.group(1).upper() == "INF" else math.nan


def vector_block(
    lines: Lines, kind: int, keyword: str, path: str, read: FloatBlocks | None = None
) -> tuple[FloatArray, IntArray, IntArray]:
    """Values, per-line value counts and line numbers of all statements of one kind.

    ``read``: what :func:`float_blocks` read, when it could.
    """
    if read is not None:
        return read[kind]
    block, line_numbers = gather(lines, kind)
    if not block:
        return np.zeros(0), np.zeros(0, dtype=np.int64), line_numbers
    fast = decimal_numbers(block, dict.fromkeys(keyword.encode(), line_numbers.size))
    if fast is not None:  # the usual case: plain decimals, read as integers and scaled exactly
        return fast[0], fast[1], line_numbers
    table = float_table(block, keyword.encode(), line_numbers.size)
    if table is not None:  # the usual case: the same number of values on every line
        return table.ravel(), np.full(table.shape[0], table.shape[1], dtype=np.int64), line_numbers
    values = numbers(block, keyword.encode(), np.float64)
    if values is None:
        return (*slow_numbers(lines, line_numbers, keyword, path), line_numbers)
    # numbers() read exactly one number per token, so the counts add up to values.size
    return values.astype(np.float64, copy=False), values_per_line(block, values.size), line_numbers


def columns(values: FloatArray, counts: IntArray, columns: list[int]) -> FloatArray:
    """Pick value ``columns`` of every line (a column past a line's count reads as 0)."""
    offsets = np.cumsum(counts) - counts
    out = np.zeros((counts.size, len(columns)), dtype=np.float64)
    for j, c in enumerate(columns):
        ok = counts > c
        out[ok, j] = values[offsets[ok] + c]
    return out
