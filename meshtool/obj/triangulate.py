"""Polygon triangulation that keeps concave polygons' area.

Triangles pass through; quads are split along the diagonal that touches a reflex corner (which is what ear
clipping does for four corners, computed for all quads at once); larger polygons are projected onto their
best-fit plane (Newell normal) and ear-clipped with earcut. Every output triangle keeps the winding of its
polygon, so face normals keep pointing the same way.
"""

from __future__ import annotations

from dataclasses import dataclass

import mapbox_earcut
import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


@dataclass(slots=True)
class Triangulation:
    """Triangles as corner indices.

    Attributes:
        corners: (M, 3) indices into the polygon corner arrays (``ObjData.corner_*``).
        face: (M,) index of the polygon each triangle came from.
        lost: Triangles that ear clipping could not produce (zero-area or self-overlapping polygons give
            fewer than ``n - 2``); these are counted as degenerate by callers.
        identity: True when every polygon was already a triangle (``corners`` is ``arange(C).reshape(-1, 3)``).
    """

    corners: IntArray
    face: IntArray
    lost: int
    identity: bool = False


def triangulate_polygons(positions: FloatArray, face_sizes: IntArray, corner_v: IntArray) -> Triangulation:
    """Triangulate polygons given by corner lists.

    Args:
        positions: (V, 3) vertex positions (any units; only directions and areas matter).
        face_sizes: (F,) corners per polygon, each >= 3.
        corner_v: (C,) vertex index of each corner, polygons stored one after another.

    Returns:
        The triangles, grouped by polygon in polygon order.
    """
    face_sizes = np.asarray(face_sizes, dtype=np.int64)
    offsets = np.cumsum(face_sizes) - face_sizes
    pieces: list[tuple[IntArray, IntArray, IntArray]] = []  # (polygon ids, triangles) per size class

    tri = np.flatnonzero(face_sizes == 3)
    if tri.size:
        pieces.append((tri, offsets[tri, None] + np.arange(3), np.zeros(0, dtype=np.int64)))

    quad = np.flatnonzero(face_sizes == 4)
    if quad.size:
        c = offsets[quad, None] + np.arange(4)
        p = positions[corner_v[c]]
        normal = _newell(p)
        edge_in = p - np.roll(p, 1, axis=1)
        edge_out = np.roll(p, -1, axis=1) - p
        turn = np.einsum("qkj,qj->qk", np.cross(edge_in, edge_out), normal)
        reflex_odd = (turn[:, 1] < 0) | (turn[:, 3] < 0)
        diag02 = np.stack([c[:, [0, 1, 2]], c[:, [0, 2, 3]]], axis=1)
        diag13 = np.stack([c[:, [0, 1, 3]], c[:, [1, 2, 3]]], axis=1)
        chosen = np.where(reflex_odd[:, None, None], diag13, diag02).reshape(-1, 3)
        pieces.append((np.repeat(quad, 2), chosen, np.zeros(0, dtype=np.int64)))

    lost = 0
    big_ids: list[int] = []
    big_tris: list[IntArray] = []
    for f in np.flatnonzero(face_sizes > 4).tolist():
        c = offsets[f] + np.arange(face_sizes[f])
        local = _earclip(positions[corner_v[c]])
        lost += int(face_sizes[f]) - 2 - len(local)
        big_ids.extend([f] * len(local))
        big_tris.append(c[local])
    if big_tris:
        pieces.append((np.asarray(big_ids, dtype=np.int64), np.concatenate(big_tris), np.zeros(0, dtype=np.int64)))

    if not pieces:
        return Triangulation(np.zeros((0, 3), dtype=np.int64), np.zeros(0, dtype=np.int64), lost)
    if len(pieces) == 1:  # one size class: already in polygon order
        identity = bool(tri.size == face_sizes.size)
        return Triangulation(pieces[0][1].astype(np.int64, copy=False), pieces[0][0], lost, identity)
    face = np.concatenate([p[0] for p in pieces])
    corners = np.concatenate([p[1] for p in pieces]).astype(np.int64, copy=False)
    order = np.argsort(face, kind="stable")
    return Triangulation(corners[order], face[order], lost)


def _newell(points: FloatArray) -> FloatArray:
    """Newell normals of polygons: (..., n, 3) -> (..., 3), length = twice the projected area."""
    nxt = np.roll(points, -1, axis=-2)
    a, b = points, nxt
    return np.stack(
        [
            ((a[..., 1] - b[..., 1]) * (a[..., 2] + b[..., 2])).sum(-1),
            ((a[..., 2] - b[..., 2]) * (a[..., 0] + b[..., 0])).sum(-1),
            ((a[..., 0] - b[..., 0]) * (a[..., 1] + b[..., 1])).sum(-1),
        ],
        axis=-1,
    )


def _earclip(points: FloatArray) -> npt.NDArray[np.int64]:
    """Ear-clip one polygon (n, 3); returns (k, 3) local corner indices wound like the polygon."""
    n = len(points)
    normal = _newell(points)
    length = float(np.linalg.norm(normal))
    if not np.isfinite(length) or length == 0.0:
        return np.stack([np.zeros(n - 2, dtype=np.int64), np.arange(1, n - 1), np.arange(2, n)], axis=1)
    normal = normal / length
    helper = np.eye(3)[int(np.argmin(np.abs(normal)))]
    u = np.cross(normal, helper)
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    flat = np.ascontiguousarray(np.stack([(points - points[0]) @ u, (points - points[0]) @ v], axis=1))
    result = mapbox_earcut.triangulate_float64(flat, np.array([n], dtype=np.uint32))
    tris = np.asarray(result, dtype=np.int64).reshape(-1, 3)
    if tris.size:
        a, b, c = flat[tris[:, 0]], flat[tris[:, 1]], flat[tris[:, 2]]
        signed = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
        flip = signed < 0
        tris[flip] = tris[flip][:, [0, 2, 1]]
    return tris
