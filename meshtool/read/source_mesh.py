"""The in-memory mesh model every reader fills, and the helper that assembles it from pieces.

Every reader (OBJ, STL, PLY, glTF/GLB, COLLADA) returns a :class:`SourceMesh` (defined with the other stage
records in :mod:`meshtool.stages`), the read stage's record: the
polygons and attributes, and what OBJ keeps elsewhere (its MTL files) or not at all: the materials the format
defines, the unit and up axis it declares, and what the source locations of findings count (lines for text
formats, facets/faces/triangles for binary ones). The normaliser consumes every format the same way
(:func:`meshtool.repair.mesh.build_mesh`).

Readers build the model from :class:`Piece` objects (one per primitive, polygon group or solid), which
:func:`assemble` concatenates into the flat arrays, in piece order.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from meshtool.findings import Finding, warning
from meshtool.stages import SourceFrame as SourceFrame
from meshtool.stages import SourceMesh as SourceMesh

if TYPE_CHECKING:
    from meshtool.read.obj.mtl import Material

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

#: Largest magnitude of a texture coordinate, normal component or colour value kept (as for OBJ).
MAX_ATTRIBUTE = 1e6


@dataclass(slots=True)
class Piece:
    """One part of a mesh with per-vertex attributes (a glTF primitive, a COLLADA triangle set, an STL solid).

    Shapes: ``n`` vertices, ``m`` triangles.

    Attributes:
        part: Part name (node, geometry or solid name).
        material: Index into the material list, -1 for none.
        positions: (n, 3) float64, already placed (node transforms baked).
        faces: (m, 3) int64 indices into ``positions``, counter-clockwise.
        locations: (m,) source location of each triangle (see :class:`SourceMesh`).
        uvs: (n, 2) texture coordinates (OBJ convention: v up) or ``None``.
        normals: (n, 3) or ``None``.
        colors: (n, 3) linear 0..1 or ``None``.
        corner_uvs: (m * 3, 2) texture coordinates per triangle corner (PLY ``texcoord`` lists), used when
            ``uvs`` is ``None``.
    """

    part: str
    material: int
    positions: FloatArray
    faces: IntArray
    locations: IntArray
    uvs: FloatArray | None = None
    normals: FloatArray | None = None
    colors: FloatArray | None = None
    corner_uvs: FloatArray | None = None


def assemble(
    pieces: list[Piece],
    path: str,
    fmt: str,
    location: str,
    materials: list[Material],
    frame: SourceFrame,
    findings: list[Finding],
    record: dict[str, Any] | None = None,
) -> SourceMesh:
    """Concatenate pieces into one :class:`SourceMesh` (pieces keep their order; nothing is merged).

    Args:
        pieces: The pieces.
        path: Source file name for findings.
        fmt: Format name.
        location: What piece ``locations`` count.
        materials: Material definitions; ``Piece.material`` indexes them.
        frame: The declared unit and up axis.
        findings: What the reader noticed so far (extended here, then stored in the result).
        record: Format-specific facts for ``asset.json``.

    Returns:
        The mesh; every polygon is a triangle.
    """
    unbound = bool(materials) and any(p.material < 0 for p in pieces)
    materials = _unique_materials(materials, unbound)
    if unbound:
        pieces = [p if p.material >= 0 else _with_material(p, len(materials) - 1) for p in pieces]
    part_names: list[str] = []
    part_ids: dict[str, int] = {}
    pos, col, uvs, nrm = [], [], [], []
    corner_v, corner_vt, corner_vn, face_lines, vertex_lines = [], [], [], [], []
    face_material, face_part = [], []
    v_off = t_off = n_off = 0
    any_colors = any(p.colors is not None for p in pieces)
    for p in pieces:
        n = p.positions.shape[0]
        faces = p.faces.reshape(-1, 3).astype(np.int64)
        pos.append(np.asarray(p.positions, dtype=np.float64).reshape(-1, 3))
        if any_colors:
            col.append(np.ones((n, 3)) if p.colors is None else _clean(p.colors, 3, path, "colors", findings, 1.0))
        flat = faces.ravel()
        corner_v.append(flat + v_off)
        if p.uvs is not None:
            uvs.append(_clean(p.uvs, 2, path, "texture coordinates", findings, 0.0))
            corner_vt.append(flat + t_off)
            t_off += n
        elif p.corner_uvs is not None:
            uvs.append(_clean(p.corner_uvs, 2, path, "texture coordinates", findings, 0.0))
            corner_vt.append(np.arange(flat.size, dtype=np.int64) + t_off)
            t_off += flat.size
        else:
            corner_vt.append(np.full(flat.shape, -1, dtype=np.int64))
        if p.normals is not None:
            nrm.append(_clean(p.normals, 3, path, "normals", findings, 0.0))
            corner_vn.append(flat + n_off)
            n_off += n
        else:
            corner_vn.append(np.full(flat.shape, -1, dtype=np.int64))
        locations = np.asarray(p.locations, dtype=np.int64).reshape(-1)
        face_lines.append(locations)
        vertex_lines.append(first_use(faces, locations, n))
        face_material.append(np.full(faces.shape[0], p.material, dtype=np.int64))
        part = part_ids.setdefault(p.part, len(part_ids))
        if part == len(part_names):
            part_names.append(p.part)
        face_part.append(np.full(faces.shape[0], part, dtype=np.int64))
        v_off += n

    def cat(arrays: list[Any], shape: tuple[int, ...], dtype: Any) -> Any:
        if not arrays:
            return np.zeros(shape, dtype=dtype)
        joined = arrays[0] if len(arrays) == 1 else np.concatenate(arrays)
        return joined.astype(dtype, copy=False)

    corners = cat(corner_v, (0,), np.int64)
    material_names = [m.name for m in materials]
    return SourceMesh(
        path=path,
        positions=cat(pos, (0, 3), np.float64),
        colors=cat(col, (0, 3), np.float64) if any_colors else None,
        texcoords=cat(uvs, (0, 2), np.float64),
        normals=cat(nrm, (0, 3), np.float64),
        vertex_lines=cat(vertex_lines, (0,), np.int64),
        face_sizes=np.full(corners.size // 3, 3, dtype=np.int64),
        face_lines=cat(face_lines, (0,), np.int64),
        face_material=cat(face_material, (0,), np.int64),
        face_part=cat(face_part, (0,), np.int64),
        corner_v=corners,
        corner_vt=cat(corner_vt, (0,), np.int64),
        corner_vn=cat(corner_vn, (0,), np.int64),
        material_names=material_names,
        part_names=part_names or ["default"],
        mtllibs=[],
        header_comments=[],
        encoding="binary" if location != "line" else "utf-8",
        line_endings="lf",
        findings=findings,
        format=fmt,
        location=location,
        materials=list(materials),
        frame=frame,
        record=record or {},
    )


def _unique_materials(materials: list[Material], unbound: bool) -> list[Material]:
    """Materials with pairwise distinct names (``_2``... appended), and a grey ``default`` when asked.

    ``unbound``: some pieces have no material while others have one (as OBJ faces before any ``usemtl``).
    """
    from meshtool.read.obj.mtl import Material

    out: list[Material] = []
    taken: set[str] = set()
    for m in materials:
        name, n = m.name, 2
        while name in taken:
            name, n = f"{m.name}_{n}", n + 1
        taken.add(name)
        out.append(
            m if name == m.name else Material(name, m.line, dict(m.colors), dict(m.scalars), m.illum, dict(m.maps))
        )
    if unbound and out:
        name, n = "default", 2
        while name in taken:
            name, n = f"default_{n}", n + 1
        out.append(Material(name, 0, colors={"Kd": (0.8, 0.8, 0.8)}, illum=1))
    return out


def _with_material(piece: Piece, material: int) -> Piece:
    return Piece(
        piece.part,
        material,
        piece.positions,
        piece.faces,
        piece.locations,
        piece.uvs,
        piece.normals,
        piece.colors,
        piece.corner_uvs,
    )


def _clean(values: Any, width: int, path: str, what: str, findings: list[Finding], fill: float) -> FloatArray:
    """``values`` as (n, width) float64; non-finite or huge rows replaced by ``fill`` with a warning."""
    out = np.asarray(values, dtype=np.float64).reshape(-1, width)
    with np.errstate(invalid="ignore"):
        bad = ~(np.abs(out) <= MAX_ATTRIBUTE).all(axis=1)
    if bad.any():
        out = out.copy()
        out[bad] = fill
        findings.append(
            warning(
                f"{what.replace(' ', '-')}-invalid",
                f"{int(bad.sum())} vertex {what} not finite or beyond +-{MAX_ATTRIBUTE:g}: replaced by {fill:g}",
                path,
            )
        )
    return out


def first_use(faces: IntArray, locations: IntArray, n: int) -> IntArray:
    """(n,) the location of the first triangle that uses each of ``n`` vertices (the first location if none)."""
    default = int(locations[0]) if locations.size else 0
    first = np.full(n, np.iinfo(np.int64).max, dtype=np.int64)
    if faces.size:
        np.minimum.at(first, faces.reshape(-1), np.repeat(locations, 3))
    first[first == np.iinfo(np.int64).max] = default
    return first


def merge_rows(rows: FloatArray) -> tuple[FloatArray, IntArray]:
    """Rows with exactly equal values merged, in order of first occurrence.

    Exact (bitwise after turning -0.0 into 0.0): rows are grouped by a hash of their bits, and every group is
    checked to hold equal rows (a collision falls back to an exact lexicographic sort). float32 rows (binary
    STL) are compared as float32, which is exact and reads half the memory.

    Args:
        rows: (n, k) float32 or float64.

    Returns:
        The distinct rows as float64 and, for each input row, the index of its distinct row.
    """
    single = np.asarray(rows).dtype == np.float32
    values: npt.NDArray[np.floating[Any]] = np.array(rows, dtype=np.float32 if single else np.float64, order="C")
    np.add(values, 0.0, out=values)  # -0.0 -> 0.0, in place
    n = values.shape[0]
    if n == 0:
        return values.astype(np.float64), np.zeros(0, dtype=np.int64)
    bits: npt.NDArray[Any] = values.view(np.uint32 if single else np.uint64).reshape(n, -1)
    mixed = np.zeros(n, dtype=np.uint64)
    with np.errstate(over="ignore"):
        for k in range(bits.shape[1]):
            mixed ^= bits[:, k].astype(np.uint64, copy=False)
            mixed *= np.uint64(0x9E3779B97F4A7C15)
            mixed ^= mixed >> np.uint64(29)
    order = np.argsort(mixed)
    sorted_hash = mixed[order]
    start = np.concatenate([[True], sorted_hash[1:] != sorted_hash[:-1]])
    group_sorted = np.cumsum(start) - 1
    group = np.empty(n, dtype=np.int64)
    group[order] = group_sorted
    firsts = np.minimum.reduceat(order, np.flatnonzero(start))  # first occurrence of each group
    if not (bits == bits[firsts[group]]).all():  # a hash collision: exact sort instead
        order = np.lexsort(bits.T[::-1])
        ordered = bits[order]
        start = np.concatenate([[True], (ordered[1:] != ordered[:-1]).any(axis=1)])
        group[order] = np.cumsum(start) - 1
        firsts = np.minimum.reduceat(order, np.flatnonzero(start))
    rank = np.empty(firsts.size, dtype=np.int64)
    by_first = np.argsort(firsts)
    rank[by_first] = np.arange(firsts.size)
    return values[firsts[by_first]].astype(np.float64), rank[group]


def transform_points(matrix: FloatArray, points: FloatArray) -> FloatArray:
    """``points`` (n, 3) transformed by the 4x4 ``matrix``."""
    if np.array_equal(matrix, np.eye(4)):
        return points
    result: FloatArray = np.einsum("ij,kj->ik", points, matrix[:3, :3]) + matrix[:3, 3]
    return result


def transform_normals(matrix: FloatArray, normals: FloatArray) -> FloatArray:
    """``normals`` (n, 3) transformed by the inverse transpose of ``matrix``'s 3x3 part, renormalised."""
    linear = matrix[:3, :3]
    if np.array_equal(linear, np.eye(3)):
        return normals
    try:
        inverse_t = np.linalg.inv(linear).T
    except np.linalg.LinAlgError:
        return normals
    out = np.einsum("ij,kj->ik", normals, inverse_t)
    length = np.linalg.norm(out, axis=1, keepdims=True)
    result: FloatArray = np.divide(out, length, out=np.zeros_like(out), where=length > 0)
    return result


def mirrors(matrix: FloatArray) -> bool:
    """Whether ``matrix`` flips handedness (negative determinant): triangle winding must be reversed."""
    return bool(np.linalg.det(matrix[:3, :3]) < 0)
