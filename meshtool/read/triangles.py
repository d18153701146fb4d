"""The read stage's triangles: a mesh's polygons as the triangles and vertices the file defines.

:func:`read_triangles` triangulates the polygons as read (:func:`meshtool.read.obj.triangulate.triangulate_polygons`),
refuses a face that uses a non-finite vertex, marks the triangles of zero area and decides which vertices reach
the output (:func:`kept_vertices`, the one rule: repair's :func:`meshtool.repair.mesh.build_mesh` compacts the mesh
by it and the frame stage decides on the kept vertices' positions). :func:`check_coordinate_range` refuses absurd
coordinates before any arithmetic on them. Coordinates stay in the file's units and axes; nothing is dropped here.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from meshtool.errors import ObjParseError
from meshtool.findings import Finding, warning
from meshtool.frame.units import UNIT_FACTORS, unit_scale
from meshtool.read.obj.triangulate import EARCUT_BUDGET, EARCUT_FREE, EARCUT_SMALL, triangulate_polygons
from meshtool.stages import SourceMesh, SourceTriangles

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]

#: Largest vertex coordinate magnitude, metres, after ``--units`` and ``--scale`` (1000 km). Beyond it the
#: file is refused: such coordinates are a wrong unit or corrupt data, qhull cannot hull them, and float32
#: (the ``.mbin`` positions) keeps less than a decimetre of precision there and overflows past 3.4e38.
MAX_COORDINATE_M = 1e6


def read_triangles(obj: SourceMesh) -> SourceTriangles:
    """The triangles of ``obj``'s polygons, which of them have zero area, and the vertices the output keeps.

    Args:
        obj: The mesh as read (polygons, source units and axes).

    Returns:
        The record; its findings are the triangulation's (``polygon-fanned``, ``polygon-budget``).

    Raises:
        ObjParseError: A face uses a vertex with a non-finite coordinate (``non-finite``).
    """
    findings: list[Finding] = []
    path = obj.path
    tri = triangulate_polygons(obj.positions, obj.face_sizes, obj.corner_v)
    if tri.fanned.size:
        findings.append(
            warning(
                "polygon-fanned",
                f"{tri.fanned.size} face(s) of more than {EARCUT_FREE} corners overlap themselves (a corner "
                "visited twice, or edges that cross): fan-triangulated, repeated triangles dropped; "
                "the triangles may overlap",
                path,
                int(obj.face_lines[tri.fanned[0]]),
            )
        )
    if tri.over_budget.size:
        findings.append(
            warning(
                "polygon-budget",
                f"{tri.over_budget.size} large concave face(s) fan-triangulated: ear clipping all of them would take "
                f"too long (more than {EARCUT_BUDGET:,} squared corners in faces of over {EARCUT_SMALL} corners); "
                "the triangles may overlap",
                path,
                int(obj.face_lines[tri.over_budget[0]]),
            )
        )
    faces = obj.corner_v.reshape(-1, 3) if tri.identity else obj.corner_v[tri.corners]  # identity: a view
    if faces.size:
        bad_vertex = np.logical_not(np.isfinite(obj.positions).all(axis=1))
        if bad_vertex.any():
            bad_vertex &= used_mask(faces, obj.positions.shape[0])
        if bad_vertex.any():
            vertex = int(np.flatnonzero(bad_vertex)[0])
            face = int(np.flatnonzero((faces == vertex).any(axis=1))[0])
            user = int(obj.face_lines[face] if tri.identity else obj.face_lines[tri.face[face]])
            raise ObjParseError(
                f"vertex {vertex + 1} has a non-finite coordinate {obj.positions[vertex].tolist()} and is used by "
                f"the face on line {user}",
                path=path,
                line=int(obj.vertex_lines[vertex]),
                hint="fix the coordinate or delete the faces that use it",
                code="non-finite",
            )
    degenerate = degenerate_triangles(obj.positions, faces)
    return SourceTriangles(tri, faces, degenerate, kept_vertices(obj.positions, faces, degenerate), findings)


def kept_vertices(positions: FloatArray, faces: IntArray, degenerate: BoolArray) -> BoolArray:
    """Which vertices reach the output: those a triangle of non-zero area uses, else (none) every finite one.

    Args:
        positions: (V, 3) positions as read.
        faces: (M, 3) vertex indices of every triangle.
        degenerate: (M,) the triangles of zero area (:func:`degenerate_triangles`), which are dropped.

    Returns:
        (V,) mask; order is kept (the output's vertices are ``positions[mask]``).
    """
    kept = faces[~degenerate] if degenerate.any() else faces
    if kept.size:
        return used_mask(kept, positions.shape[0])
    finite: BoolArray = np.asarray(np.isfinite(positions).all(axis=1), dtype=np.bool_)
    return finite


def degenerate_triangles(positions: FloatArray, faces: IntArray) -> BoolArray:
    """(M,) triangles with a repeated vertex or exactly zero area (``positions`` (V, 3), ``faces`` (M, 3))."""
    if faces.size == 0:
        return np.zeros(0, dtype=bool)
    a, b, c = faces[:, 0], faces[:, 1], faces[:, 2]
    result: BoolArray = (a == b) | (b == c) | (a == c)
    x, y, z = (np.ascontiguousarray(positions[:, k]) for k in range(3))
    ux, uy, uz = x[b] - x[a], y[b] - y[a], z[b] - z[a]
    vx, vy, vz = x[c] - x[a], y[c] - y[a], z[c] - z[a]
    result |= (uy * vz == uz * vy) & (uz * vx == ux * vz) & (ux * vy == uy * vx)
    return result


def used_mask(index: IntArray, size: int) -> BoolArray:
    """(size,) which rows ``index`` names (entries of -1 name none)."""
    used = np.zeros(size, dtype=bool)
    used[index[index >= 0]] = True
    return used


def check_coordinate_range(obj: SourceMesh, units: str | None, scale: float) -> None:
    """Refuse vertex coordinates beyond :data:`MAX_COORDINATE_M` once converted to metres.

    Only vertices that reach the output are checked (those faces use, or all of them when there are no
    faces); non-finite ones are left to :func:`read_triangles`, which names them.

    Args:
        obj: The parsed OBJ (coordinates in ``units``).
        units: Unit of the coordinates (a key of :data:`meshtool.frame.units.UNIT_FACTORS`), or ``None`` when it
            is not decided yet: then only coordinates beyond the limit in every unit are refused.
        scale: The extra uniform scale.

    Raises:
        ObjParseError: Naming the line of the first vertex out of range.
    """
    positions = obj.positions
    if positions.shape[0] == 0:
        return
    factor = (unit_scale(units) if units else min(unit_scale(u) for u in UNIT_FACTORS)) * scale
    with np.errstate(over="ignore", invalid="ignore"):
        metres = np.abs(positions) * factor
        beyond = (metres > MAX_COORDINATE_M) & np.isfinite(positions)
    rows = beyond.any(axis=1)
    if obj.corner_v.size:
        used = np.zeros(positions.shape[0], dtype=bool)
        used[obj.corner_v] = True
        rows &= used
    if not rows.any():
        return
    k = int(np.flatnonzero(rows)[0])
    value = float(positions[k][beyond[k]][0])
    if units is None:
        shown = " in any unit"
    elif units != "m" or scale != 1.0:
        shown = f" ({float(metres[k][beyond[k]][0]):.4g} m in {units}, scale {scale:g})"
    else:
        shown = ""
    raise ObjParseError(
        f"vertex {k + 1} has the coordinate {value:.6g}{shown}, beyond the limit of +-{MAX_COORDINATE_M:g} m",
        path=obj.path,
        line=int(obj.vertex_lines[k]),
        hint="pass the right --units or a smaller --scale, or fix the coordinate; recentre georeferenced models",
        code="coordinate-range",
    )
