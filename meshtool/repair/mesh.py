"""Triangle meshes built from parsed mesh data: cleaned, compacted and ordered.

:func:`build_mesh` turns a :class:`~meshtool.read.source_mesh.SourceMesh` and its triangles as read
(:func:`meshtool.read.triangles.read_triangles`) into a :class:`TriMesh`: degenerate triangles dropped, unused
vertices (:func:`meshtool.read.triangles.kept_vertices`), texcoords and normals removed (order kept), and triangles
ordered by material (first use) and then part name, so each material is one contiguous run.
Coordinates stay in the source's units and axes; see :mod:`meshtool.frame.units` for conversion.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from meshtool.findings import Finding, info, warning
from meshtool.read.source_mesh import SourceMesh
from meshtool.read.triangles import read_triangles, used_mask
from meshtool.stages import SourceTriangles

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

DEFAULT_MATERIAL = "default"
_UNSAFE = re.compile(r"[^A-Za-z0-9_.-]+")


@dataclass(slots=True)
class TriMesh:
    """An indexed triangle mesh with per-triangle material and part.

    Shapes: ``V`` vertices, ``T`` texcoords, ``N`` normals, ``M`` triangles.

    Attributes:
        positions: (V, 3) float64.
        colors: (V, 3) float64 vertex colours or ``None``.
        texcoords: (T, 2) float64.
        normals: (N, 3) float64.
        faces: (M, 3) vertex indices, counter-clockwise seen from the front.
        face_uv: (M, 3) texcoord indices, rows of -1 where the triangle has none.
        face_normal: (M, 3) normal indices, rows of -1 where the triangle has none.
        face_material: (M,) index into ``material_names``.
        face_part: (M,) index into ``part_names``.
        face_lines: (M,) line of the source ``f`` statement.
        material_names: Material names (as in the source) in order of first use.
        part_names: Part names, made safe (``[A-Za-z0-9_.-]``) and unique.
        source_polygons: Number of polygons read.
        degenerate: Triangles dropped as degenerate (repeated vertex or zero area).
    """

    positions: FloatArray
    colors: FloatArray | None
    texcoords: FloatArray
    normals: FloatArray
    faces: IntArray
    face_uv: IntArray
    face_normal: IntArray
    face_material: IntArray
    face_part: IntArray
    face_lines: IntArray
    material_names: list[str]
    part_names: list[str]
    source_polygons: int
    degenerate: int


def safe_identifier(name: str, fallback: str) -> str:
    """Make a name safe for MTL/OBJ/MJCF: runs of other characters become ``_``.

    Idempotent: a safe name is returned unchanged.
    """
    cleaned = _UNSAFE.sub("_", name.strip()).strip("_")
    return cleaned or fallback


def unique_names(names: list[str], fallback: str) -> list[str]:
    """Safe, pairwise distinct names (``_2``, ``_3``... appended in order on clashes)."""
    out: list[str] = []
    taken: set[str] = set()
    for name in names:
        base = safe_identifier(name, fallback)
        candidate, n = base, 2
        while candidate.casefold() in taken:
            candidate, n = f"{base}_{n}", n + 1
        taken.add(candidate.casefold())
        out.append(candidate)
    return out


def build_mesh(obj: SourceMesh, triangles: SourceTriangles | None = None) -> tuple[TriMesh, list[Finding]]:
    """Clean the triangles of parsed mesh data.

    Args:
        obj: Parsed mesh (any format).
        triangles: ``obj``'s polygons as the read stage triangulated them
            (:func:`meshtool.read.triangles.read_triangles`); ``None``: triangulated here, and the
            triangulation's findings are returned too.

    Returns:
        The mesh and findings (degenerate faces, dropped attributes, unused non-finite vertices).

    Raises:
        ObjParseError: When a face uses a vertex with a non-finite coordinate (``triangles`` not given).
    """
    findings: list[Finding] = []
    path = obj.path
    if triangles is None:
        triangles = read_triangles(obj)
        findings.extend(triangles.findings)
    tri, faces = triangles.tri, triangles.faces
    if tri.identity:  # all triangles: views instead of gathers
        uv = obj.corner_vt.reshape(-1, 3).copy()
        nrm = obj.corner_vn.reshape(-1, 3).copy()
        lines, material, part = obj.face_lines, obj.face_material, obj.face_part
    else:
        uv = obj.corner_vt[tri.corners]
        nrm = obj.corner_vn[tri.corners]
        lines = obj.face_lines[tri.face]
        material = obj.face_material[tri.face]
        part = obj.face_part[tri.face]

    degenerate = triangles.degenerate
    dropped = int(degenerate.sum()) + tri.lost
    if dropped:
        first = int(lines[np.flatnonzero(degenerate)[0]]) if degenerate.any() else None
        findings.append(info("degenerate-faces", f"{dropped} degenerate triangle(s) dropped (zero area)", path, first))
    if degenerate.any():
        keep = ~degenerate
        faces, uv, nrm, lines = faces[keep], uv[keep], nrm[keep], lines[keep]
        material, part = material[keep], part[keep]

    if obj.texcoords.shape[0]:
        uv = _whole_triangles(uv, path, findings)
    normals = obj.normals
    if normals.shape[0]:
        normals, nrm = _fill_normals(obj.positions, faces, normals, nrm, path, findings)

    kept = triangles.kept  # the one rule of which vertices stay (kept_vertices); the frame decided on them too
    if faces.size:
        positions, colors, faces = _compact_vertices(obj, faces, kept)
    else:
        if not kept.all():
            findings.append(
                warning(
                    "non-finite-vertices",
                    f"{int((~kept).sum())} vertices with non-finite coordinates dropped",
                    path,
                )
            )
        positions = obj.positions[kept]
        colors = obj.colors[kept] if obj.colors is not None else None
    texcoords, uv = _compact(obj.texcoords, uv)
    with_uv = uv[:, 0] >= 0
    if with_uv.any() and not with_uv.all():
        # MuJoCo's OBJ reader discards all texture coordinates when some faces have none: give those a
        # texcoord at (0, 0) so the textured faces keep theirs.
        uv[~with_uv] = texcoords.shape[0]
        texcoords = np.concatenate([texcoords, np.zeros((1, 2))])
        findings.append(
            info("texcoords-filled", f"{int((~with_uv).sum())} triangle(s) without texcoords mapped to (0, 0)", path)
        )
    normals, nrm = _compact(normals, nrm)

    material_names, material = _first_use_order(material, obj.material_names)
    part_names_all = unique_names(obj.part_names, "part")
    part_order = np.argsort(np.asarray(part_names_all, dtype=object), kind="stable") if part_names_all else np.zeros(0)
    rank = np.empty(len(part_names_all), dtype=np.int64)
    rank[part_order.astype(np.int64)] = np.arange(len(part_names_all))
    if material.size and (material.min() != material.max() or part.min() != part.max()):
        order = np.lexsort((rank[part], material))
        faces, uv, nrm, material, part, lines = (a[order] for a in (faces, uv, nrm, material, part, lines))
    else:  # one material and part: the order stands; copies, so the mesh shares no memory with ``obj``
        faces, uv, nrm, material, part, lines = (a.copy() for a in (faces, uv, nrm, material, part, lines))
    return (
        TriMesh(
            positions=positions,
            colors=colors,
            texcoords=texcoords,
            normals=normals,
            faces=faces,
            face_uv=uv,
            face_normal=nrm,
            face_material=material,
            face_part=part,
            face_lines=lines,
            material_names=material_names,
            part_names=part_names_all,
            source_polygons=int(obj.face_sizes.size),
            degenerate=dropped,
        ),
        findings,
    )


def _whole_triangles(uv: IntArray, path: str, findings: list[Finding]) -> IntArray:
    """Texcoord indices per triangle, all three or none (-1)."""
    present = uv >= 0
    has_uv = present.all(axis=1)
    partial = present.any(axis=1) & ~has_uv
    if partial.any():
        findings.append(
            warning(
                "texcoords-partial",
                f"{int(partial.sum())} triangle(s) with texcoords on only some corners: dropped",
                path,
            )
        )
    if not has_uv.all():
        uv[~has_uv] = -1
    return uv


def _fill_normals(
    positions: FloatArray, faces: IntArray, normals: FloatArray, nrm: IntArray, path: str, findings: list[Finding]
) -> tuple[FloatArray, IntArray]:
    """Give triangles without (complete) normals their flat face normal when others have normals."""
    has_n = (nrm >= 0).all(axis=1)
    if has_n.all():
        return normals, nrm
    if not has_n.any():
        nrm[:] = -1
        return normals, nrm
    missing = np.flatnonzero(~has_n)
    nrm[missing] = (normals.shape[0] + np.arange(missing.size))[:, None]
    findings.append(info("normals-partial", f"{missing.size} triangle(s) without normals got flat face normals", path))
    return np.concatenate([normals, _face_normals(positions, faces[missing])]), nrm


def _face_normals(positions: FloatArray, faces: IntArray) -> FloatArray:
    p = positions[faces]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    result: FloatArray = np.divide(n, length, out=np.zeros_like(n), where=length > 0)
    return result


def _compact_vertices(
    obj: SourceMesh, faces: IntArray, kept: npt.NDArray[np.bool_]
) -> tuple[FloatArray, FloatArray | None, IntArray]:
    """The ``kept`` vertices (order kept) and ``faces`` renumbered to them."""
    colors = obj.colors
    if kept.all():
        return obj.positions, colors, faces
    remap = np.cumsum(kept) - 1
    return obj.positions[kept], colors[kept] if colors is not None else None, remap[faces]


def _compact(values: FloatArray, index: IntArray) -> tuple[FloatArray, IntArray]:
    """Drop rows of ``values`` no index uses; remap ``index`` (-1 stays -1); order is kept."""
    present = index >= 0
    if not present.any():
        return values[:0], index
    used = used_mask(index, values.shape[0])
    if used.all():
        return values, index
    remap = np.cumsum(used) - 1
    return values[used], np.where(present, remap[np.maximum(index, 0)], -1)


def _first_use_order(material: IntArray, names: list[str]) -> tuple[list[str], IntArray]:
    """Renumber materials by first use; faces with no ``usemtl`` (-1) get :data:`DEFAULT_MATERIAL`."""
    if material.size == 0:
        return [], material
    labels = [DEFAULT_MATERIAL, *names]
    ids = material + 1
    _, first = np.unique(ids, return_index=True)
    by_label: dict[str, int] = {}
    for i in ids[np.sort(first)].tolist():
        by_label.setdefault(labels[i], len(by_label))
    table = np.asarray([by_label.get(label, -1) for label in labels], dtype=np.int64)
    return list(by_label), table[ids]
