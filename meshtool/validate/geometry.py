"""Geometry rules (G004..G011): topology, orientation, volume and size of a triangle mesh.

The mesh is welded by position first (vertices split at UV or normal seams are one vertex for topology),
so an ordinary textured cube is closed and consistently wound.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import trimesh

from meshtool.findings import Finding
from meshtool.validate.config import Limits
from meshtool.validate.rules import hit

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

#: Smallest singular value / largest of the centred vertices below which the mesh counts as flat.
COPLANAR_TOLERANCE = 1e-9


def geometry_findings(positions: FloatArray, faces: IntArray, path: str, limits: Limits) -> list[Finding]:
    """G004..G011 for one triangle mesh.

    Args:
        positions: (n, 3) vertex positions, metres, Z-up.
        faces: (m, 3) triangles (degenerate ones already dropped).
        path: The source file named in the findings.
        limits: Budgets and thresholds.

    Returns:
        The findings, in rule order.
    """
    out: list[Finding] = []
    if faces.shape[0] == 0:
        return out
    mesh = trimesh.Trimesh(positions, faces, process=False)
    mesh.merge_vertices(merge_tex=True, merge_norm=True)
    welded = np.asarray(mesh.faces, dtype=np.int64)
    # the same triangle twice: the same corners in the same cyclic order (a back face is not a duplicate)
    rolled = np.take_along_axis(welded, (np.argmin(welded, axis=1)[:, None] + np.arange(3)) % 3, axis=1)
    _, first = np.unique(rolled, axis=0, return_index=True)
    duplicates = len(welded) - len(first)
    if duplicates:
        out.append(hit("G004", f"{duplicates} of {len(welded)} triangles repeat another triangle", path))
        welded = welded[np.sort(first)]  # the rest of the checks see each triangle once

    directed = welded[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    _, group, counts = np.unique(np.sort(directed, axis=1), axis=0, return_inverse=True, return_counts=True)
    boundary = int((counts == 1).sum())
    non_manifold = int((counts > 2).sum())
    # an edge of two triangles is consistently wound when they run it in opposite directions
    forward = np.bincount(group.ravel(), weights=(directed[:, 0] < directed[:, 1]), minlength=len(counts))
    flipped = int(((counts == 2) & (forward != 1)).sum())
    consistent = flipped == 0
    if not consistent:
        out.append(hit("G005", f"{flipped} edges are run the same way by both of their triangles", path))
    closed = boundary == 0 and non_manifold == 0
    volume = _signed_volume(np.asarray(mesh.vertices, dtype=np.float64), welded) if closed and consistent else None
    if volume is not None and volume < 0:
        out.append(hit("G006", f"closed mesh with volume {volume:.3g} m^3: the faces point inwards", path))
    if boundary:
        out.append(hit("G007", f"{boundary} boundary edges: the surface is not closed", path))
    if non_manifold:
        out.append(hit("G008", f"{non_manifold} edges are shared by more than two triangles", path))

    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    flat = _is_flat(vertices)
    if flat:
        out.append(hit("G009", f"all {len(vertices)} vertices lie in one plane", path))
    elif volume is not None:
        extent = np.ptp(vertices, axis=0)
        box = float(np.prod(extent))
        size = abs(volume)
        if size < limits.min_volume_m3 or (box > 0 and size / box < limits.min_volume_fraction):
            out.append(
                hit(
                    "G010",
                    f"volume {size:.3g} m^3 is {size / box if box else 0:.2g} of its bounding box "
                    f"({' x '.join(f'{e:.3g}' for e in extent)} m)",
                    path,
                )
            )
    if len(vertices) > limits.max_vertices:
        out.append(hit("G011", f"{len(vertices)} vertices, budget {limits.max_vertices}", path))
    return out


def _signed_volume(vertices: FloatArray, faces: IntArray) -> float:
    """Signed volume of a closed triangle mesh (positive when the faces point outwards), m^3."""
    a, b, c = vertices[faces[:, 0]], vertices[faces[:, 1]], vertices[faces[:, 2]]
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def _is_flat(vertices: FloatArray) -> bool:
    if len(vertices) < 4:
        return True
    centred = vertices - vertices.mean(axis=0)
    singular = np.linalg.svd(centred, compute_uv=False)
    return bool(singular[0] == 0 or singular[2] / singular[0] < COPLANAR_TOLERANCE)
