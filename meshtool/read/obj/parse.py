"""OBJ reader: bytes in, plain arrays out.

The reader classifies every line by its first bytes with numpy, gathers all ``v``/``vt``/``vn``/``f`` lines
into one block per kind and parses each block in one vectorised call; only the rare statements (``o``,
``g``, ``usemtl``, ``mtllib``, ``s``, ``l``, ``p``, unknown ones) go through a Python loop. When a block does
not parse in one go (an inline comment, a bad number, an odd face corner) the block is parsed line by line,
which either succeeds or raises an error naming the exact line.

Indices in the returned data are 0-based and absolute (negative OBJ indices are resolved against the
number of elements defined before the statement, as the OBJ specification says).
"""

from __future__ import annotations

import re
from collections import Counter
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from meshtool.errors import ObjParseError
from meshtool.findings import Finding, info, warning
from meshtool.read.obj.comments import strip_statement_comment
from meshtool.read.obj.faces import read_faces, resolve_attr_index, resolve_vertex_index
from meshtool.read.obj.lines import (
    OTHER,
    SKIP,
    VN,
    VT,
    F,
    FloatArray,
    FloatBlocks,
    IntArray,
    Lines,
    V,
    classify,
    columns,
    float_blocks,
    reject_control_bytes,
    vector_block,
)
from meshtool.read.source_mesh import SourceMesh
from meshtool.read.textio import decode_text

if TYPE_CHECKING:
    from pathlib import Path

    from meshtool.files.resolve import Resolver

BoolArray = npt.NDArray[np.bool_]

DEFAULT_PART = "default"
#: Most MTL files one OBJ may name (over all its ``mtllib`` statements); further names are ignored with a
#: warning. Each name costs a file-system search, so a line of 100,000 names must not mean 100,000 of them.
MAX_MTLLIBS = 256
#: Largest magnitude of a texture coordinate, a normal component or a vertex colour value. Larger (or
#: non-finite) values are dropped with a warning: they mean nothing, and past 3.4e38 they turn into
#: infinities in float32 outputs. Vertex positions are limited after unit conversion (see normalise).
MAX_ATTRIBUTE = 1e6

_FREEFORM = frozenset(
    (
        "vp cstype deg bmat step curv curv2 surf parm trim hole scrv sp end con mg bevel c_interp d_interp lod "
        "maplib usemap shadow_obj trace_obj ctech stech call csh t vw"
    ).split()
)
_MTL_NAME = re.compile(r'"([^"]+)"|(\S.*?\.mtl)(?=\s|$)|(\S+)', re.IGNORECASE)


@dataclass(slots=True)
class MtllibRef:
    """One file named by an ``mtllib`` statement.

    Attributes:
        name: The file name as written (escaped spaces and quotes removed).
        line: 1-based line of the ``mtllib`` statement.
    """

    name: str
    line: int


@dataclass(slots=True)
class _State:
    """Statements handled one by one: events keyed by line number."""

    material_lines: list[int] = field(default_factory=list)
    material_ids: list[int] = field(default_factory=list)
    material_names: list[str] = field(default_factory=list)
    part_lines: list[int] = field(default_factory=lambda: [0])
    part_ids: list[int] = field(default_factory=lambda: [0])
    part_names: list[str] = field(default_factory=lambda: [DEFAULT_PART])
    mtllibs: list[MtllibRef] = field(default_factory=list)
    mtllibs_capped: bool = False
    skipped: Counter[str] = field(default_factory=Counter)
    first_line: dict[str, int] = field(default_factory=dict)
    recognised: int = 0


def parse_obj(data: bytes | str, path: str = "<obj>") -> SourceMesh:
    """Parse an OBJ file.

    Args:
        data: File contents as bytes (any supported encoding) or already-decoded text.
        path: Name used in findings and errors (``path:line``).

    Returns:
        The parsed file; polygons are kept as polygons (see :mod:`meshtool.read.obj.triangulate`).

    Raises:
        ObjParseError: Empty or non-OBJ data, a malformed number, an index of 0, an index outside the
            defined vertices, a relative index before the first vertex.
    """
    raw_bytes = data.encode("utf-8") if isinstance(data, str) else data
    decoded = decode_text(raw_bytes, path, ObjParseError)
    findings = list(decoded.findings)
    reject_control_bytes(decoded.data, path)
    lines = classify(decoded.data)
    state = _State()
    _read_statements(lines, state, path, findings)
    n_numeric = int(np.count_nonzero((lines.kinds >= V) & (lines.kinds <= F)))  # V, VT, VN, F: 1 to 4
    if n_numeric == 0 and state.recognised == 0:
        other = np.flatnonzero(lines.kinds == OTHER)
        if other.size:
            first = int(other[0])
            raise ObjParseError(
                f"not an OBJ file: no OBJ statements, found {lines.text(first)[:40]!r}",
                path=path,
                line=first + 1,
                hint="pass a Wavefront OBJ text file",
            )
        raise ObjParseError("empty OBJ file, no geometry: no statements", path=path, hint="export the mesh again")

    read = float_blocks(lines)
    positions, colors, vertex_lines = _read_vertices(lines, path, findings, read)
    texcoords, _ = _read_vectors(lines, VT, "vt", 1, 3, path, read)
    normals, _ = _read_vectors(lines, VN, "vn", 3, 3, path, read)
    faces = read_faces(lines, path, findings)
    face_sizes, face_lines, corner_v, corner_vt, corner_vn = faces

    corner_lines = np.repeat(face_lines, face_sizes)
    corner_v = resolve_vertex_index(corner_v, corner_lines, vertex_lines, path, findings)
    vt_lines = np.flatnonzero(lines.kinds == VT) + 1
    vn_lines = np.flatnonzero(lines.kinds == VN) + 1
    corner_vt = resolve_attr_index(corner_vt, corner_lines, vt_lines, "vt", "texture coordinates", path, findings)
    corner_vn = resolve_attr_index(corner_vn, corner_lines, vn_lines, "vn", "normals", path, findings)
    corner_vt = _drop_invalid(corner_vt, texcoords, vt_lines, "vt", "texture coordinates", path, findings)
    corner_vn = _drop_invalid(corner_vn, normals, vn_lines, "vn", "normals", path, findings)

    face_material = _events_at(face_lines, state.material_lines, state.material_ids, -1)
    face_part = _events_at(face_lines, state.part_lines, state.part_ids, 0)
    header = []
    for i in range(len(lines.kinds)):
        if lines.kinds[i] != SKIP:
            break
        text = lines.text(i)
        if text.startswith("#"):
            header.append(text[1:].strip())
    return SourceMesh(
        path=path,
        positions=positions,
        colors=colors,
        texcoords=texcoords,
        normals=normals,
        vertex_lines=vertex_lines,
        face_sizes=face_sizes,
        face_lines=face_lines,
        face_material=face_material,
        face_part=face_part,
        corner_v=corner_v,
        corner_vt=corner_vt,
        corner_vn=corner_vn,
        material_names=state.material_names,
        part_names=state.part_names,
        mtllibs=state.mtllibs,
        header_comments=header,
        encoding=decoded.encoding,
        line_endings=decoded.line_endings,
        findings=findings,
    )


def parse_mtllib_names(rest: str) -> list[str]:
    """Split the argument of an ``mtllib`` statement into file names.

    Names may contain spaces, so the text is split after each ``.mtl`` (case-insensitive) that ends a word;
    text without a ``.mtl`` suffix is split at whitespace. Backslash-escaped spaces and quotes are removed.

    Args:
        rest: Everything after ``mtllib``.

    Returns:
        The file names in order.
    """
    rest = rest.replace("\\ ", " ").strip()
    names = [next(g for g in m.groups() if g is not None) for m in _MTL_NAME.finditer(rest)]
    return [n.strip().strip('"') for n in names if n.strip().strip('"')]


# ----------------------------------------------------------------------------------------------------------
# line classification and one-by-one statements


def _read_statements(lines: Lines, state: _State, path: str, findings: list[Finding]) -> None:
    current_o: str | None = None
    current_g: str | None = None
    materials: dict[str, int] = {}
    parts: dict[str, int] = {DEFAULT_PART: 0}
    for i in np.flatnonzero(lines.kinds == OTHER).tolist():
        line_no = i + 1
        words = strip_statement_comment(lines.text(i)).split(None, 1)
        if not words:
            continue
        keyword = words[0]
        rest = words[1].strip() if len(words) > 1 else ""
        if keyword in ("o", "g"):
            state.recognised += 1
            if keyword == "o":
                current_o, current_g = (rest or None), None
            else:
                current_g = rest or DEFAULT_PART
            name = current_g or current_o or DEFAULT_PART
            state.part_lines.append(line_no)
            state.part_ids.append(parts.setdefault(name, len(parts)))
        elif keyword == "usemtl":
            state.recognised += 1
            if not rest:
                findings.append(warning("usemtl-empty", "'usemtl' without a name ignored", path, line_no))
                continue
            if rest not in materials:
                materials[rest] = len(materials)
            state.material_lines.append(line_no)
            state.material_ids.append(materials[rest])
        elif keyword == "mtllib":
            state.recognised += 1
            names = parse_mtllib_names(rest)
            if not names:
                findings.append(warning("mtllib-empty", "'mtllib' without a file name ignored", path, line_no))
            room = MAX_MTLLIBS - len(state.mtllibs)
            if len(names) > room and not state.mtllibs_capped:
                state.mtllibs_capped = True
                findings.append(
                    warning(
                        "mtllib-too-many",
                        f"more than {MAX_MTLLIBS} MTL file names (this statement names {len(names)}): "
                        f"the names past the first {MAX_MTLLIBS} are ignored",
                        path,
                        line_no,
                    )
                )
            state.mtllibs.extend(MtllibRef(n, line_no) for n in names[: max(room, 0)])
        elif keyword == "s":
            state.recognised += 1
        else:
            state.skipped[keyword] += 1
            state.first_line.setdefault(keyword, line_no)
    state.material_names = list(materials)
    state.part_names = list(parts)
    for keyword, count in sorted(state.skipped.items()):
        line_no = state.first_line[keyword]
        if keyword in ("l", "p"):
            state.recognised += count
            kind = "line" if keyword == "l" else "point"
            findings.append(
                info(
                    f"{kind}s-skipped",
                    f"{count} '{keyword}' ({kind}) element(s) skipped: not surface geometry",
                    path,
                    line_no,
                )
            )
        elif keyword in _FREEFORM:
            state.recognised += count
            findings.append(
                info(
                    "freeform-skipped",
                    f"{count} free-form '{keyword}' statement(s) skipped (not supported)",
                    path,
                    line_no,
                )
            )
        else:
            findings.append(
                warning(
                    "unknown-statement",
                    f"{count} unknown '{keyword[:20]}' statement(s) ignored",
                    path,
                    line_no,
                )
            )


def _events_at(face_lines: IntArray, event_lines: list[int], event_values: list[int], default: int) -> IntArray:
    if not event_lines:
        return np.full(face_lines.shape, default, dtype=np.int64)
    pos = np.searchsorted(np.asarray(event_lines, dtype=np.int64), face_lines, side="right") - 1
    values = np.asarray(event_values, dtype=np.int64)
    return np.where(pos >= 0, values[np.maximum(pos, 0)], default)


def _read_vertices(
    lines: Lines, path: str, findings: list[Finding], read: FloatBlocks | None
) -> tuple[FloatArray, FloatArray | None, IntArray]:
    values, counts, line_numbers = vector_block(lines, V, "v", path, read)
    if counts.size == 0:
        return np.zeros((0, 3)), None, line_numbers
    short = np.flatnonzero(counts < 3)
    if short.size:
        raise ObjParseError(
            f"'v' statement has {int(counts[short[0]])} coordinate(s), needs x y z",
            path=path,
            line=int(line_numbers[short[0]]),
            hint="fix or remove the line",
        )
    if (counts == 3).all():
        return values.reshape(-1, 3), None, line_numbers
    positions = columns(values, counts, [0, 1, 2])
    with_w = np.flatnonzero(counts == 4)
    if with_w.size:
        findings.append(
            info(
                "vertex-w-ignored",
                f"{with_w.size} vertex weight(s) 'w' ignored",
                path,
                int(line_numbers[with_w[0]]),
            )
        )
    odd = np.flatnonzero((counts == 5) | (counts > 6))
    if odd.size:
        findings.append(
            warning(
                "vertex-extra-values",
                f"{odd.size} 'v' statement(s) with {int(counts[odd[0]])} values: only x y z used",
                path,
                int(line_numbers[odd[0]]),
            )
        )
    colored = counts == 6
    colors = None
    if colored.any():
        colors = np.ones((counts.size, 3), dtype=np.float64)
        colors[colored] = columns(values, counts, [3, 4, 5])[colored]
        missing = np.flatnonzero(~colored)
        if missing.size:
            findings.append(
                warning(
                    "vertex-colors-partial",
                    f"{missing.size} vertices have no colour while others do; they are white",
                    path,
                    int(line_numbers[missing[0]]),
                )
            )
    if colors is not None and not _valid_rows(colors).all():
        bad = np.flatnonzero(~_valid_rows(colors))
        colors[bad] = 1.0
        findings.append(
            warning(
                "vertex-colors-invalid",
                f"{bad.size} vertex colour(s) are not finite numbers or beyond +-{MAX_ATTRIBUTE:g}: white used",
                path,
                int(line_numbers[bad[0]]),
            )
        )
    return positions, colors, line_numbers


def _valid_rows(values: FloatArray) -> BoolArray:
    """Rows whose values are all finite and within :data:`MAX_ATTRIBUTE`."""
    with np.errstate(invalid="ignore"):
        within = np.abs(values) <= MAX_ATTRIBUTE
    result: BoolArray = np.all(within, axis=1)
    return result


def _drop_invalid(
    index: IntArray,
    values: FloatArray,
    element_lines: IntArray,
    keyword: str,
    what: str,
    path: str,
    findings: list[Finding],
) -> IntArray:
    """Corners lose a texcoord/normal that is not finite or beyond :data:`MAX_ATTRIBUTE` (-1), with a warning."""
    if values.shape[0] == 0:
        return index
    with np.errstate(invalid="ignore"):
        if bool((np.abs(values) <= MAX_ATTRIBUTE).all()):  # the usual case: every row valid (one reduction)
            return index
    invalid = ~_valid_rows(values)
    hit = (index >= 0) & invalid[np.maximum(index, 0)]
    if not hit.any():
        return index  # unused: dropped with the other unused ones
    first = int(element_lines[int(index[np.flatnonzero(hit)[0]])])
    findings.append(
        warning(
            f"{keyword}-invalid",
            f"{int(invalid.sum())} '{keyword}' statement(s) hold values that are not finite or beyond "
            f"+-{MAX_ATTRIBUTE:g}: the {int(hit.sum())} face corner(s) using them lose their {what}",
            path,
            first,
        )
    )
    return np.where(hit, -1, index)


def _read_vectors(
    lines: Lines, kind: int, keyword: str, least: int, most: int, path: str, read: FloatBlocks | None
) -> tuple[FloatArray, IntArray]:
    values, counts, line_numbers = vector_block(lines, kind, keyword, path, read)
    width = 2 if keyword == "vt" else 3
    if counts.size == 0:
        return np.zeros((0, width)), line_numbers
    bad = np.flatnonzero((counts < least) | (counts > most))
    if bad.size:
        raise ObjParseError(
            f"'{keyword}' statement has {int(counts[bad[0]])} value(s), expected {least} to {most}",
            path=path,
            line=int(line_numbers[bad[0]]),
            hint="fix or remove the line",
        )
    if (counts == width).all():
        return values.reshape(-1, width), line_numbers
    return columns(values, counts, list(range(width))), line_numbers


def read(data: bytes, path: str, src: Path, resolver: Resolver) -> SourceMesh:
    """The formats registry's reader (:data:`meshtool.formats.MESH_FORMATS`): :func:`parse_obj`."""
    return parse_obj(data, path)
