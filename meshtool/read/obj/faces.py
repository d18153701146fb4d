"""Face statements: corner parsing (vectorised, with a line-by-line fallback) and index resolution.

Limits: a face may have at most :data:`MAX_FACE_CORNERS` corners, and an index is ``[+-]?digits`` (ASCII)
of at most :data:`MAX_INDEX` in magnitude; anything else is an error naming the line.
"""

from __future__ import annotations

import re
from typing import Any

import numpy as np
import numpy.typing as npt

from meshtool.errors import ObjParseError
from meshtool.findings import Finding, info, warning
from meshtool.read.obj.decimals import tokens_per_line
from meshtool.read.obj.lines import (
    F,
    IntArray,
    Lines,
    blank_keywords,
    gather,
    numbers,
    strip_comment,
    tokens,
    values_per_line,
)

#: Most corners one ``f`` statement may have (a polygon is triangulated in one piece; larger ones are refused).
MAX_FACE_CORNERS = 65_536
#: Largest index magnitude (no file can define more elements than this and still be read).
MAX_INDEX = 2**31 - 1
# What an OBJ index is. Python's int() also reads "1_0" (as 10), " 1" and non-ASCII digits.
_INDEX = re.compile(r"[+-]?[0-9]+")


def read_faces(
    lines: Lines, path: str, findings: list[Finding]
) -> tuple[IntArray, IntArray, IntArray, IntArray, IntArray]:
    """Polygons: sizes, line numbers and raw (1-based or negative) corner indices; 0 marks 'absent'."""
    block, line_numbers = gather(lines, F)
    empty = np.zeros(0, dtype=np.int64)
    if not block:
        return empty, empty, empty, empty, empty
    parsed = _fast_faces(block, line_numbers.size)
    if parsed is None:
        parsed = _slow_faces(lines, line_numbers, path)
    sizes, cv, cvt, cvn = parsed
    huge = np.flatnonzero(sizes > MAX_FACE_CORNERS)
    if huge.size:
        raise ObjParseError(
            f"face has {int(sizes[huge[0]])} corners, more than the limit of {MAX_FACE_CORNERS}",
            path=path,
            line=int(line_numbers[huge[0]]),
            hint="split the polygon into smaller faces (or triangulate it) in the exporter",
            code="limit-face-corners",
        )
    small = sizes < 3
    if small.any():
        bad = np.flatnonzero(small)
        findings.append(
            warning(
                "face-too-small",
                f"{bad.size} 'f' statement(s) with fewer than 3 corners skipped",
                path,
                int(line_numbers[bad[0]]),
            )
        )
        keep = np.repeat(~small, sizes)
        sizes, line_numbers = sizes[~small], line_numbers[~small]
        cv, cvt, cvn = cv[keep], cvt[keep], cvn[keep]
    return sizes, line_numbers, cv, cvt, cvn


def _fast_faces(block: bytes, n_lines: int) -> tuple[IntArray, IntArray, IntArray, IntArray] | None:
    if b"/" not in block:  # plain "f a b c ...": every token after the keyword is one vertex index
        values = numbers(block, b"f", np.int64)
        if values is None:
            return None
        sizes = values_per_line(block, values.size)  # one number per token: the sizes add up to values.size
        cv = values.astype(np.int64, copy=False)
        if (cv == 0).any() or _out_of_range(cv):
            return None  # an explicit index 0 or a huge one: the line-by-line path reports its line
        zeros = np.zeros_like(cv)
        return sizes, cv, zeros, zeros
    uniform = _uniform_faces(block, n_lines)
    if uniform is not None:
        return uniform
    a, tstart, first, counts = tokens(block)
    sizes = counts - 1
    is_kw = np.zeros(tstart.size, dtype=bool)
    is_kw[first] = True
    slashes = np.flatnonzero(a == 47)
    n_tok = tstart.size
    tok_of = np.searchsorted(tstart, slashes, side="right") - 1
    n_slash = np.bincount(tok_of, minlength=n_tok)
    doubled = slashes[:-1][np.diff(slashes) == 1]
    n_double = np.bincount(np.searchsorted(tstart, doubled, side="right") - 1, minlength=n_tok)
    n_slash, n_double = n_slash[~is_kw], n_double[~is_kw]
    if ((n_slash > 2) | (n_double > 1) | ((n_double == 1) & (n_slash != 2))).any():
        return None
    per_corner = 1 + n_slash - n_double
    values = numbers(block, b"f", np.int64, blank_slashes=True)
    if values is None or values.size != int(per_corner.sum()) or _out_of_range(values):
        return None
    offsets = np.cumsum(per_corner) - per_corner
    last = max(values.size - 1, 0)
    cv = values[offsets]
    has_vt = (n_slash >= 1) & (n_double == 0)
    has_vn = n_slash == 2
    cvt = np.where(has_vt, values[np.minimum(offsets + 1, last)], 0)
    cvn = np.where(has_vn, values[np.minimum(offsets + per_corner - 1, last)], 0)
    if (cv == 0).any() or (has_vt & (cvt == 0)).any() or (has_vn & (cvn == 0)).any():
        return None  # an explicit index 0: the line-by-line path reports its line
    return sizes, cv.astype(np.int64, copy=False), cvt.astype(np.int64, copy=False), cvn.astype(np.int64, copy=False)


def _uniform_faces(block: bytes, n_lines: int) -> tuple[IntArray, IntArray, IntArray, IntArray] | None:
    """Faces whose every corner is written the same way (all ``v/vt/vn``, all ``v//vn`` or all ``v/vt``).

    The usual exporter output, checked from the positions of the slashes alone: with ``k`` slashes per corner
    the ``i``-th run of ``k`` slashes lies inside the ``i``-th corner, never at its ends, and the slashes of a
    corner are all adjacent (``v//vn``) or none are. Then every field between them is one whitespace-free run,
    which numpy's integer parser reads as exactly one number or refuses, so the block's integers are the
    corners' fields in order. ``None`` for any other block (mixed forms, a tab, an empty field, comments).
    """
    if b"\t" in block or b"\v" in block or b"\f" in block or block.count(b"f") != n_lines:
        return None
    a = np.frombuffer(block, dtype=np.uint8)
    ws = (a <= 32) | (a == 102)  # every "f" is a keyword (counted): blank
    edges = np.flatnonzero(ws[1:] != ws[:-1]) + 1
    tstart, tend = edges[0::2], edges[1::2]
    slashes = np.flatnonzero(a == 47)
    n = tstart.size
    if n == 0 or slashes.size not in (n, 2 * n):
        return None
    per = slashes.size // n
    first = slashes[0::per]
    last = slashes[per - 1 :: per]
    if not bool(((first > tstart) & (last < tend - 1)).all()):
        return None
    if per == 2:
        gap = last - first
        doubled = bool((gap == 1).all())
        if not doubled and not bool((gap > 1).all()):
            return None
    else:
        doubled = False
    fields = 2 if per == 1 or doubled else 3
    if b"#" in block or b"(" in block or not block.isascii():
        return None
    try:
        values = np.fromstring(blank_keywords(block, b"f", True), dtype=np.int64, sep=" ")  # "f" counted
    except (ValueError, TypeError):
        return None
    if values.size != fields * n or _out_of_range(values):
        return None
    table = values.reshape(n, fields)
    cv = table[:, 0].copy()
    zeros = np.zeros(n, dtype=np.int64)
    cvt = table[:, 1].copy() if not doubled else zeros
    cvn = table[:, fields - 1].copy() if per == 2 else zeros
    if (cv == 0).any() or (not doubled and (cvt == 0).any()) or (per == 2 and (cvn == 0).any()):
        return None  # an explicit index 0: the line-by-line path reports its line
    return tokens_per_line(a, tstart, tend), cv, cvt, cvn


def _out_of_range(values: npt.NDArray[Any]) -> bool:
    """Whether an index is beyond :data:`MAX_INDEX` (numpy saturates overflowing text at the int64 limits)."""
    return bool(((values > MAX_INDEX) | (values < -MAX_INDEX)).any())


def _index(part: str) -> int:
    """One OBJ index (``0`` for an empty field); ``ValueError`` for anything but ``[+-]?digits``."""
    if not part:
        return 0
    if not _INDEX.fullmatch(part):
        raise ValueError(part)
    return int(part)


def _slow_faces(lines: Lines, line_numbers: IntArray, path: str) -> tuple[IntArray, IntArray, IntArray, IntArray]:
    sizes = np.zeros(line_numbers.size, dtype=np.int64)
    corners: list[tuple[int, int, int]] = []
    for k, line_no in enumerate(line_numbers.tolist()):
        words = strip_comment(lines.text(line_no - 1)).split()[1:]
        for word in words:
            parts = word.split("/")
            try:
                if len(parts) > 3 or not parts[0]:
                    raise ValueError(word)
                parts += [""] * (3 - len(parts))
                corner = (_index(parts[0]), _index(parts[1]), _index(parts[2]))
            except ValueError:
                raise ObjParseError(
                    f"malformed face corner {word[:30]!r} (expected v, v/vt, v//vn or v/vt/vn)",
                    path=path,
                    line=line_no,
                    hint="fix or remove the line",
                ) from None
            if any(abs(i) > MAX_INDEX for i in corner):
                raise ObjParseError(
                    f"face index in {word[:30]!r} is beyond the largest possible index {MAX_INDEX}",
                    path=path,
                    line=line_no,
                    hint="the file is corrupt; fix or remove the line",
                )
            if corner[0] == 0 or any(p and i == 0 for p, i in zip(parts[1:], corner[1:], strict=True)):
                _zero_index(path, line_no)
            corners.append(corner)
        sizes[k] = len(words)
    arr = np.asarray(corners, dtype=np.int64).reshape(-1, 3)
    return sizes, arr[:, 0], arr[:, 1], arr[:, 2]


def _zero_index(path: str, line: int) -> None:
    raise ObjParseError(
        "face index 0 is invalid (OBJ indices start at 1; negative ones count back from the last)",
        path=path,
        line=line,
        hint="re-export the mesh; the exporter wrote 0-based indices",
    )


# ----------------------------------------------------------------------------------------------------------
# index resolution


def _absolute(raw: IntArray, corner_lines: IntArray, element_lines: IntArray) -> tuple[IntArray, IntArray]:
    """0-based indices from raw OBJ indices, and the number of elements defined before each corner."""
    if element_lines.size == 0 or element_lines[-1] < corner_lines[0]:  # all defined before the first face
        before = np.full(raw.shape, element_lines.size, dtype=np.int64)
    else:
        before = np.searchsorted(element_lines, corner_lines).astype(np.int64, copy=False)
    if (raw > 0).all():
        return raw - 1, before
    return np.where(raw > 0, raw - 1, before + raw), before


def resolve_vertex_index(
    raw: IntArray, corner_lines: IntArray, vertex_lines: IntArray, path: str, findings: list[Finding]
) -> IntArray:
    """0-based vertex indices; raises on 0, past-the-end or before-the-start indices; notes forward references."""
    if raw.size == 0:
        return raw
    zero = np.flatnonzero(raw == 0)
    if zero.size:
        _zero_index(path, int(corner_lines[zero[0]]))
    idx, before = _absolute(raw, corner_lines, vertex_lines)
    total = vertex_lines.size
    bad = np.flatnonzero((idx < 0) | (idx >= total))
    if bad.size:
        k = int(bad[0])
        if raw[k] < 0:
            msg = (
                f"relative vertex index {int(raw[k])} reaches before the first vertex ({int(before[k])} defined so far)"
            )
        else:
            msg = f"face refers to vertex {int(raw[k])} but the file defines {total}"
        raise ObjParseError(msg, path=path, line=int(corner_lines[k]), hint="the file is truncated or corrupt")
    forward = np.flatnonzero((raw > 0) & (idx >= before))
    if forward.size:
        findings.append(
            info(
                "forward-reference",
                f"{forward.size} face corner(s) refer to vertices defined later in the file (resolved)",
                path,
                int(corner_lines[forward[0]]),
            )
        )
    return idx


def resolve_attr_index(
    raw: IntArray,
    corner_lines: IntArray,
    element_lines: IntArray,
    keyword: str,
    what: str,
    path: str,
    findings: list[Finding],
) -> IntArray:
    """0-based texcoord/normal indices, -1 where absent; invalid ones are dropped with a warning."""
    present = raw != 0
    if not present.any():
        return np.full(raw.shape, -1, dtype=np.int64)
    total = element_lines.size
    if total == 0:
        first = int(corner_lines[np.flatnonzero(present)[0]])
        findings.append(
            warning(
                f"{keyword}-missing",
                f"faces refer to {what} but the file has no '{keyword}' lines: dropped",
                path,
                first,
            )
        )
        return np.full(raw.shape, -1, dtype=np.int64)
    idx, _ = _absolute(raw, corner_lines, element_lines)
    bad = present & ((idx < 0) | (idx >= total))
    if bad.any():
        first = int(corner_lines[np.flatnonzero(bad)[0]])
        findings.append(
            warning(
                f"{keyword}-index-out-of-range",
                f"{int(bad.sum())} face corner(s) refer to {what} past the {total} defined: dropped for those corners",
                path,
                first,
            )
        )
    return np.where(present & ~bad, idx, -1)
