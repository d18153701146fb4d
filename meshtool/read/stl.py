"""STL reader: binary and ASCII, several solids per ASCII file, binary files whose header says ``solid``.

Binary or ASCII is decided by the size, not by the first word: a file of exactly ``84 + 50 * count`` bytes
(the facet count at byte 80) is binary even when its 80-byte header starts with ``solid`` (SolidWorks and
others write that); otherwise a file that starts with ``solid`` is ASCII. Each ASCII ``solid`` becomes a
part named after it. STL shares no vertices: corners at exactly the same coordinates are merged into one
vertex (in order of first use), so the mesh is connected as it was modelled.

STL has no unit (CAD exports are usually millimetres; the normaliser suggests a unit from the size) and
no up axis. Facet normals are not kept (the winding defines the outside); facets whose stored normal
points against their winding are reported (``stl-normals-disagree``). Locations of findings count facets
in a binary file and lines in an ASCII one.
"""

from __future__ import annotations

import re
from typing import TYPE_CHECKING

import numpy as np

from meshtool.errors import FormatError
from meshtool.findings import Finding, info, warning
from meshtool.read.source_mesh import (
    FloatArray,
    IntArray,
    Piece,
    SourceFrame,
    SourceMesh,
    assemble,
    first_use,
    merge_rows,
)

if TYPE_CHECKING:
    from pathlib import Path

    from meshtool.files.resolve import Resolver

_HEADER = 80
_FACET = np.dtype([("normal", "<f4", (3,)), ("v", "<f4", (3, 3)), ("attr", "<u2")])
_NAME = re.compile(r"^\s*(?:end)?solid\b[ \t]*(.*)$")
FRAME = SourceFrame(None, "STL has no unit", None, "STL has no up axis")


def read_stl(data: bytes, path: str) -> SourceMesh:
    """Read an STL file.

    Args:
        data: The file's bytes.
        path: Name for findings and errors.

    Returns:
        The mesh (one part per ASCII solid, one for a binary file), no materials.

    Raises:
        FormatError: Too short, truncated, a malformed ASCII statement or number.
    """
    if len(data) >= _HEADER + 4:
        count = int(np.frombuffer(data, "<u4", 1, _HEADER)[0])
        if len(data) == _HEADER + 4 + _FACET.itemsize * count:
            return _binary(data, count, path)
    if data.lstrip()[:5].lower() == b"solid":
        return _ascii(data, path)
    if len(data) < _HEADER + 4:
        raise FormatError(
            f"not an STL file: {len(data)} bytes, neither ASCII ('solid ...') nor a binary header of 84 bytes",
            path=path,
            hint="export the mesh again as STL",
        )
    count = int(np.frombuffer(data, "<u4", 1, _HEADER)[0])
    expected = _HEADER + 4 + _FACET.itemsize * count
    if len(data) < expected:
        complete = (len(data) - _HEADER - 4) // _FACET.itemsize
        raise FormatError(
            f"binary STL truncated: the header says {count} facets ({expected} bytes) but the file has "
            f"{len(data)} bytes ({complete} complete facets)",
            path=path,
            offset=_HEADER + 4 + _FACET.itemsize * complete,
            hint="the file was cut short: copy or export it again",
        )
    mesh = _binary(data[:expected], count, path)
    mesh.findings.append(
        warning(
            "stl-trailing-data",
            f"{len(data) - expected} bytes after the {count} facets the header announces: ignored",
            path,
        )
    )
    return mesh


def _binary(data: bytes, count: int, path: str) -> SourceMesh:
    facets = np.frombuffer(data, _FACET, count, _HEADER + 4)
    header = data[:_HEADER].split(b"\0", 1)[0].decode("latin-1").strip()
    findings: list[Finding] = []
    if header.lower().startswith("solid"):
        findings.append(
            info("stl-binary-solid-header", f"binary STL whose header starts with 'solid' ({header[:40]!r})", path)
        )
    corners = facets["v"].reshape(-1, 3)  # float32, merged exactly as float32 (read as float64 after)
    normals = facets["normal"].astype(np.float64)
    locations = np.arange(1, count + 1, dtype=np.int64)
    name = _solid_name(header) if header.lower().startswith("solid") else ""
    return _finish(
        [(name or "default", corners, np.full(count, 3), normals, locations)],
        path,
        "facet",
        findings,
        {"encoding": "binary", "facets": count, "header": header[:80]},
    )


def _ascii(data: bytes, path: str) -> SourceMesh:
    lines = [line.decode("latin-1") for line in data.splitlines()]  # \r, \n, \r\n only: the editor's line numbers
    solids: list[tuple[str, FloatArray, IntArray, FloatArray, IntArray]] = []
    name: str | None = None
    values: list[str] = []
    sizes: list[int] = []
    normals: list[str] = []
    facet_lines: list[int] = []
    vertex_lines: list[int] = []
    in_loop = 0
    current = 0
    for number, raw in enumerate(lines, 1):
        words = raw.split()
        if not words:
            continue
        key = words[0].lower()
        if key == "vertex":
            if len(words) != 4:
                raise _bad(path, number, "'vertex' needs x y z")
            values.extend(words[1:])
            vertex_lines.append(number)
            current += 1
        elif key == "facet":
            if name is None:
                raise _bad(path, number, "'facet' outside a solid")
            if len(words) == 5 and words[1].lower() == "normal":
                normals.extend(words[2:])
            else:
                normals.extend(("0", "0", "0"))
            facet_lines.append(number)
        elif key == "outer":
            in_loop, current = number, 0
        elif key == "endloop":
            if current < 3:
                raise _bad(path, in_loop or number, f"a facet with {current} vertices (needs 3)")
            sizes.append(current)
        elif key == "solid":
            if name is not None:
                raise _bad(path, number, "'solid' inside a solid (missing 'endsolid')")
            match = _NAME.match(raw)
            name = (match.group(1).strip() if match else "") or f"solid{len(solids) + 1}"
            values, sizes, normals, facet_lines, vertex_lines = [], [], [], [], []
        elif key == "endsolid":
            if name is None:
                raise _bad(path, number, "'endsolid' without 'solid'")
            solids.append(_solid(name, values, sizes, normals, facet_lines, vertex_lines, path))
            name = None
        elif key not in ("endfacet",):
            raise _bad(path, number, f"unknown statement {words[0][:20]!r}")
    findings: list[Finding] = []
    if name is not None:  # a last solid without endsolid: keep it, say so
        solids.append(_solid(name, values, sizes, normals, facet_lines, vertex_lines, path))
        findings.append(warning("stl-endsolid-missing", f"solid {name!r} has no 'endsolid': read to the end", path))
    if not solids:
        raise FormatError("ASCII STL without a solid", path=path, hint="export the mesh again")
    record = {"encoding": "ascii", "solids": [s[0] for s in solids], "facets": int(sum(s[2].size for s in solids))}
    return _finish(solids, path, "line", findings, record)


def _solid(
    name: str,
    values: list[str],
    sizes: list[int],
    normals: list[str],
    facet_lines: list[int],
    vertex_lines: list[int],
    path: str,
) -> tuple[str, FloatArray, IntArray, FloatArray, IntArray]:
    corners = _floats(values, vertex_lines, 3, path).reshape(-1, 3)
    size = np.asarray(sizes, dtype=np.int64)
    if int(size.sum()) != corners.shape[0] or size.size != len(facet_lines):
        raise _bad(path, facet_lines[-1] if facet_lines else 1, f"solid {name!r}: facets and loops do not match")
    normal = _floats(normals, facet_lines, 3, path).reshape(-1, 3)
    return name, corners, size, normal, np.asarray(facet_lines, dtype=np.int64)


def _floats(values: list[str], lines: list[int], width: int, path: str) -> FloatArray:
    """``values`` as float64; a value that is not a number is an error naming its line.

    numpy and Python's ``float`` also read ``1_0`` (as 10) and non-ASCII digits: refused, as in OBJ.
    """
    joined = "".join(values)
    strict = "_" not in joined and joined.isascii()
    if strict:
        try:
            return np.array(values, dtype=np.float64)
        except ValueError:
            pass
    for k, value in enumerate(values):
        try:
            if "_" in value or not value.isascii():
                raise ValueError(value)
            float(value)
        except ValueError:
            raise _bad(path, lines[k // width], f"{value[:20]!r} is not a number") from None
    return np.array(values, dtype=np.float64)  # not reached: some value above was refused


def _bad(path: str, line: int, what: str) -> FormatError:
    return FormatError(f"not a valid ASCII STL: {what}", path=path, line=line, hint="fix or export the file again")


def _solid_name(header: str) -> str:
    match = _NAME.match(header)
    return match.group(1).strip() if match else ""


def _finish(
    solids: list[tuple[str, FloatArray, IntArray, FloatArray, IntArray]],
    path: str,
    location: str,
    findings: list[Finding],
    record: dict[str, object],
) -> SourceMesh:
    """Merge equal corners, check facet normals against the winding, assemble the parts."""
    all_corners = np.concatenate([s[1] for s in solids]) if len(solids) > 1 else solids[0][1]
    positions, index = merge_rows(all_corners)  # vertices in order of first use
    pieces: list[Piece] = []
    start = 0
    disagree, first_bad = 0, None
    for name, corners, sizes, normals, locations in solids:
        n = corners.shape[0]
        idx = index[start : start + n]
        start += n
        if (sizes == 3).all():
            faces = idx.reshape(-1, 3)
            face_locations = locations
            stored = normals
        else:  # polygon facets: fan them (they are planar and convex in practice)
            offsets = np.concatenate([[0], np.cumsum(sizes)[:-1]])
            rows = [
                [idx[o], idx[o + k], idx[o + k + 1]]
                for o, s in zip(offsets, sizes, strict=True)
                for k in range(1, s - 1)
            ]
            faces = np.asarray(rows, dtype=np.int64).reshape(-1, 3)
            face_locations = np.repeat(locations, sizes - 2)
            stored = np.repeat(normals, sizes - 2, axis=0)
        bad = _against_winding(positions, faces, stored)
        if bad.any():
            disagree += int(bad.sum())
            first_bad = first_bad or int(face_locations[np.flatnonzero(bad)[0]])
        pieces.append(Piece(name, -1, positions, faces, face_locations))
    if disagree:
        findings.append(
            warning(
                "stl-normals-disagree",
                f"{disagree} facet normal(s) point against the facet's winding (right-hand rule): the winding is kept",
                path,
                first_bad,
            )
        )
    record["merged_vertices"] = int(positions.shape[0])
    mesh = _shared(pieces, positions, path, location, findings, record)
    return mesh


def _shared(
    pieces: list[Piece],
    positions: FloatArray,
    path: str,
    location: str,
    findings: list[Finding],
    record: dict[str, object],
) -> SourceMesh:
    """Assemble pieces that all index one shared vertex array (solids may share corners)."""
    single = Piece("default", -1, positions, np.zeros((0, 3), dtype=np.int64), np.zeros(0, dtype=np.int64))
    mesh = assemble([single], path, "stl", location, [], FRAME, findings, record)
    faces = np.concatenate([p.faces for p in pieces]) if pieces else np.zeros((0, 3), dtype=np.int64)
    names = list(dict.fromkeys(p.part for p in pieces))
    mesh.part_names = names or ["default"]
    mesh.corner_v = faces.reshape(-1).astype(np.int64)
    mesh.corner_vt = np.full(mesh.corner_v.shape, -1, dtype=np.int64)
    mesh.corner_vn = np.full(mesh.corner_v.shape, -1, dtype=np.int64)
    mesh.face_sizes = np.full(faces.shape[0], 3, dtype=np.int64)
    mesh.face_lines = np.concatenate([p.locations for p in pieces]).astype(np.int64)
    mesh.face_material = np.full(faces.shape[0], -1, dtype=np.int64)
    mesh.face_part = np.concatenate([np.full(p.faces.shape[0], names.index(p.part), dtype=np.int64) for p in pieces])
    mesh.vertex_lines = first_use(faces, mesh.face_lines, positions.shape[0])
    return mesh


def _against_winding(positions: FloatArray, faces: IntArray, stored: FloatArray) -> np.ndarray:
    """Facets whose stored (non-zero) normal points against the normal of their winding."""
    if faces.size == 0:
        return np.zeros(0, dtype=bool)
    p = positions[faces]
    winding = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    with np.errstate(invalid="ignore"):
        dot = np.einsum("ij,ij->i", winding, stored)
        wl = np.linalg.norm(winding, axis=1)
        sl = np.linalg.norm(stored, axis=1)
        result: np.ndarray = (dot < 0) & (wl > 0) & (sl > 0)
    return result


def read(data: bytes, path: str, src: Path, resolver: Resolver) -> SourceMesh:
    """The formats registry's reader (:data:`meshtool.formats.MESH_FORMATS`): :func:`read_stl`."""
    return read_stl(data, path)
