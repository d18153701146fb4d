"""PLY reader: ASCII and binary (both byte orders), faces and triangle strips, colours, normals, uvs.

The header is parsed and checked line by line (``format``, ``element``, ``property [list]``, ``comment``,
``obj_info``, ``end_header``; anything else is an error naming the line). Every element count is checked
against the data actually present before anything is allocated for it: a binary element needs at least
``count * smallest row`` bytes (an error with the byte offset where its data starts otherwise), an ASCII
element one line per row (an error naming the line where the data ended otherwise). ASCII values are
``[+-]digits[.digits][e[+-]digits]``, ``nan`` or ``inf`` (Python's ``float`` alone reads ``1_0`` as 10);
every row must have exactly the values its properties take. Vertex indices are checked before they index
anything: a negative one, one that is not a whole number or one past the vertex count is an error naming
the face (and its line, or the byte offset of the index). Lists longer than the data, or with a negative
length, are errors too.

Faces are fanned into triangles (faces with fewer than 3 corners are skipped, ``face-too-small``; more
than :data:`~meshtool.read.obj.faces.MAX_FACE_CORNERS` corners is an error, as for OBJ). Triangle strips
(``element tristrips`` with a ``vertex_indices`` list, ``-1`` restarting a strip, every row its own strip)
are decoded with alternating winding; the degenerate triangles that stitch strips are dropped.

Texture coordinates come from vertex properties (``s t``, ``u v``, ``texture_u texture_v``,
``texture_s texture_t``) or a per-face ``texcoord`` list, and the texture image from a ``comment
TextureFile NAME`` header line (resolved by the asset's resolver, like an MTL ``map_Kd``). PLY has no unit
and no up axis. Locations of findings count faces (triangles for a file of triangle strips only).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from meshtool.errors import FormatError
from meshtool.findings import Finding, info, warning
from meshtool.read.obj.faces import MAX_FACE_CORNERS
from meshtool.read.obj.mtl import Material, TextureMap
from meshtool.read.ply_body import READ, AnyArray, Rows, ascii_body, binary_body, number
from meshtool.read.ply_header import Element, Header, head, parse_header
from meshtool.read.source_mesh import FloatArray, IntArray, Piece, SourceFrame, SourceMesh, assemble

if TYPE_CHECKING:
    from pathlib import Path

    from meshtool.files.resolve import Resolver

FRAME = SourceFrame(None, "PLY has no unit", None, "PLY has no up axis")
_UV_NAMES = (("s", "t"), ("u", "v"), ("texture_u", "texture_v"), ("texture_s", "texture_t"))


def read_ply(data: bytes, path: str) -> SourceMesh:
    """Read a PLY file.

    Args:
        data: The file's bytes.
        path: Name for findings and errors.

    Returns:
        The mesh: one part, a textured material when the header names a ``TextureFile``.

    Raises:
        FormatError: Not a PLY file, a malformed header, data shorter than the header declares, a malformed
            value, a list or vertex index out of range (naming the line or byte offset).
    """
    header = parse_header(data, path)
    findings: list[Finding] = []
    if header.encoding == "ascii":
        rows = ascii_body(data, header, path, findings)
    else:
        rows = binary_body(data, header, path, findings)
    return _mesh(header, rows, path, findings)


# ----------------------------------------------------------------------------------------------------------
# the mesh


def _mesh(header: Header, rows: dict[str, Rows], path: str, findings: list[Finding]) -> SourceMesh:
    elements = {e.name: e for e in header.elements}
    binary = header.encoding != "ascii"
    vertex = elements.get("vertex")
    if vertex is None:
        raise head(path, 2, "no 'vertex' element")
    if not vertex.has("x", "y", "z"):
        raise head(path, vertex.line, "the 'vertex' element has no x, y and z properties")
    v = rows["vertex"].scalars
    nv = vertex.count
    positions = np.stack([np.asarray(v[a], dtype=np.float64) for a in "xyz"], axis=1).reshape(-1, 3)
    for name in elements:
        if name not in READ and elements[name].count:
            findings.append(info("ply-element-ignored", f"element {name!r} is not read", path))
    triangles: list[IntArray] = []
    locations: list[IntArray] = []
    corners: AnyArray | None = None
    face = elements.get("face")
    n_faces = face.count if face is not None else 0
    if face is not None and face.count:
        listed = _index_list(face, path)
        values, n = rows["face"].lists[listed]
        _check_indices(rows["face"], listed, nv, binary, path, strips=False)
        tris, source, corners = _fan(values.astype(np.int64), n, face, rows["face"], path, findings, binary)
        triangles.append(tris)
        locations.append(source)
        corners = _face_texcoords(rows["face"], n, corners, path, findings)
        if face.has("red", "green", "blue"):
            findings.append(info("ply-face-colors-dropped", "per-face colours are not kept (vertex colours are)", path))
    strips = elements.get("tristrips")
    n_strip_triangles = 0
    if strips is not None and strips.count:
        listed = _index_list(strips, path)
        values, n = rows["tristrips"].lists[listed]
        _check_indices(rows["tristrips"], listed, nv, binary, path, strips=True)
        tris = _strip_triangles(values.astype(np.int64), n)
        n_strip_triangles = tris.shape[0]
        triangles.append(tris)
        locations.append(np.arange(1, tris.shape[0] + 1, dtype=np.int64) + n_faces)
        if corners is not None:
            corners = None
            findings.append(
                warning("ply-texcoord-dropped", "per-face texture coordinates dropped: the file also has strips", path)
            )
    faces = np.concatenate(triangles) if triangles else np.zeros((0, 3), dtype=np.int64)
    where_faces = np.concatenate(locations) if locations else np.zeros(0, dtype=np.int64)
    materials: list[Material] = []
    if header.texture is not None:
        name, line = header.texture
        materials.append(
            Material("ply_texture", line, colors={"Kd": (1.0, 1.0, 1.0)}, maps={"map_Kd": TextureMap(name, {}, line)})
        )
    piece = Piece(
        "default",
        0 if materials else -1,
        positions,
        faces,
        where_faces,
        uvs=_vertex_uvs(vertex, v),
        normals=np.stack([np.asarray(v[a], dtype=np.float64) for a in ("nx", "ny", "nz")], axis=1)
        if vertex.has("nx", "ny", "nz")
        else None,
        colors=_colors(vertex, v),
    )
    if piece.uvs is None and corners is not None:
        piece.corner_uvs = corners
    record: dict[str, Any] = {
        "encoding": header.encoding,
        "vertices": int(nv),
        "faces": n_faces or int(faces.shape[0]),
    }
    location = "face"
    if strips is not None:
        record["tristrips"] = int(strips.count)
        record["strip_triangles"] = int(n_strip_triangles)
        location = "face" if n_faces else "triangle"
    return assemble([piece], path, "ply", location, materials, FRAME, findings, record)


def _index_list(element: Element, path: str) -> str:
    listed = element.index_list()
    if listed is None:
        raise head(path, element.line, f"the {element.name!r} element has no 'vertex_indices' list")
    return listed


def _check_indices(rows: Rows, listed: str, nv: int, binary: bool, path: str, *, strips: bool) -> None:
    """Every index a whole number in ``0 .. nv - 1`` (``-1`` too for strips), else an error naming the row."""
    values = rows.lists[listed][0]
    if values.size == 0:
        return
    low = -1 if strips else 0
    with np.errstate(invalid="ignore"):
        bad = ~((values >= low) & (values < nv))
        if values.dtype.kind == "f":
            bad |= np.floor(values) != values
    if not bad.any():
        return
    k = int(np.flatnonzero(bad)[0])
    row, where = rows.locate(listed, k)
    value = number(float(values[k]))
    if values.dtype.kind == "f" and not float(values[k]).is_integer():
        reason = "which is not a whole number"
    elif values[k] < low:
        reason = "but PLY vertex indices start at 0" + (" (-1 ends a strip)" if strips else "")
    else:
        reason = f"but the file has {nv:,} vertices (0 to {nv - 1:,})" if nv else "but the file has no vertices"
    noun = f"strip {row + 1:,}" if strips else f"face {row + 1:,}"
    raise FormatError(
        f"{noun} refers to vertex {value}, {reason}",
        path=path,
        line=None if binary else where,
        offset=where if binary else None,
        hint="the file is corrupt, or its header's vertex count or byte order is wrong"
        if binary
        else "the file is corrupt, or its header's vertex count is wrong",
    )


def _fan(
    indices: IntArray, n: IntArray, face: Element, rows: Rows, path: str, findings: list[Finding], binary: bool
) -> tuple[IntArray, IntArray, IntArray]:
    """Faces fanned into triangles: (m, 3) vertex indices, the 1-based face of each, and its flat corners."""
    huge = np.flatnonzero(n > MAX_FACE_CORNERS)
    if huge.size:
        k = int(huge[0])
        raise FormatError(
            f"face {k + 1:,} has {int(n[k]):,} corners, more than the limit of {MAX_FACE_CORNERS:,}",
            path=path,
            line=None if binary else int(rows.where[k]),
            offset=int(rows.where[k]) if binary else None,
            hint="split the polygon into smaller faces (or triangulate it) in the exporter",
            code="limit-face-corners",
        )
    small = np.flatnonzero(n < 3)
    if small.size and binary:  # in binary data, a short face is the mark of rows read at the wrong offset
        k = int(small[0])
        raise FormatError(
            f"face {k + 1:,} has {int(n[k])} corner(s); a face needs at least 3",
            path=path,
            offset=int(rows.where[k]),
            hint="the header's vertex or face count or its byte order is wrong, or the file is corrupt",
        )
    if small.size:
        findings.append(
            warning(
                "face-too-small",
                f"{small.size:,} face(s) with fewer than 3 corners skipped (the first is face {int(small[0]) + 1:,})",
                path,
            )
        )
    if n.size and bool((n == 3).all()):  # triangles already
        corners = np.arange(3 * n.size, dtype=np.int64).reshape(-1, 3)
        return indices.reshape(-1, 3), np.arange(1, n.size + 1, dtype=np.int64), corners
    per_face = np.maximum(n - 2, 0)
    first = np.cumsum(n) - n  # each face's first corner in the flat list
    face_of = np.repeat(np.arange(n.size, dtype=np.int64), per_face)
    step = np.arange(face_of.size, dtype=np.int64) - np.repeat(np.cumsum(per_face) - per_face, per_face) + 1
    base = first[face_of]
    corners = np.stack([base, base + step, base + step + 1], axis=1)
    return indices[corners], face_of + 1, corners


def _strip_triangles(indices: IntArray, lengths: IntArray) -> IntArray:
    """Triangles of strips: every row a strip, ``-1`` restarting one; odd triangles flipped; degenerate dropped."""
    seq = np.insert(indices, np.cumsum(lengths), -1)  # -1 after every row: rows are separate strips
    if seq.size < 3:
        return np.zeros((0, 3), dtype=np.int64)
    breaks = seq < 0
    strip_start = np.maximum.accumulate(np.where(breaks, np.arange(seq.size), -1)) + 1  # index after last -1
    i = np.arange(seq.size - 2)
    a, b, c = seq[:-2], seq[1:-1], seq[2:]
    keep = (a >= 0) & (b >= 0) & (c >= 0) & (a != b) & (b != c) & (a != c)
    odd = (i - strip_start[:-2]) % 2 == 1
    tris = np.stack([np.where(odd, b, a), np.where(odd, a, b), c], axis=1)
    out: IntArray = tris[keep].astype(np.int64)
    return out


def _face_texcoords(
    rows: Rows, n: IntArray, corners: IntArray, path: str, findings: list[Finding]
) -> FloatArray | None:
    """(m * 3, 2) corner texture coordinates from a per-face ``texcoord`` list (two values per corner)."""
    listed = rows.lists.get("texcoord")
    if listed is None:
        return None
    values, lengths = listed
    if not np.array_equal(lengths, 2 * n):
        findings.append(
            warning(
                "ply-texcoord-dropped",
                "per-face texture coordinates dropped: some face's 'texcoord' list is not two values per corner",
                path,
            )
        )
        return None
    uv = np.asarray(values, dtype=np.float64).reshape(-1, 2)
    out: FloatArray = uv[corners.reshape(-1)]
    return out


def _vertex_uvs(vertex: Element, v: dict[str, AnyArray]) -> FloatArray | None:
    for u, w in _UV_NAMES:
        if vertex.has(u, w):
            out: FloatArray = np.stack([np.asarray(v[u], dtype=np.float64), np.asarray(v[w], dtype=np.float64)], 1)
            return out
    return None


def _colors(vertex: Element, v: dict[str, AnyArray]) -> FloatArray | None:
    """Vertex colours 0..1: integer channels divided by 255 (65535 for 16-bit), float channels as they are."""
    if not vertex.has("red", "green", "blue"):
        return None
    kinds = {p.name: p.kind for p in vertex.properties}
    channels = []
    for name in ("red", "green", "blue"):
        kind = kinds[name]
        scale = 1.0 if kind[0] == "f" else 65535.0 if kind == "u2" else 255.0
        channels.append(np.asarray(v[name], dtype=np.float64) / scale)
    out: FloatArray = np.stack(channels, axis=1)
    return out


def read(data: bytes, path: str, src: Path, resolver: Resolver) -> SourceMesh:
    """The formats registry's reader (:data:`meshtool.formats.MESH_FORMATS`): :func:`read_ply`."""
    return read_ply(data, path)
