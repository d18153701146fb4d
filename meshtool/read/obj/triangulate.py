"""Polygon triangulation that keeps concave polygons' area.

Triangles pass through; quads are split along the diagonal that touches a reflex corner (which is what ear
clipping does for four corners, computed for all quads at once); larger polygons are projected onto their
best-fit plane (Newell normal) and ear-clipped with earcut. Every output triangle keeps the winding of its
polygon, so face normals keep pointing the same way.

Bounded work: earcut is fast on simple polygons but can take cubic time on degenerate ones (a face of
10,000 corners that walks around the same 3 vertices took over 5 minutes). Polygons of more than
:data:`EARCUT_FREE` corners are therefore checked first, in O(n log n): consecutive repeated corners are
dropped; a polygon with no area is fanned (its triangles have no area either); a convex one is fanned
(exact); one that visits a point twice or does not turn exactly once around (self-overlapping, crossing)
is *hopeless*: it is fanned, triangles repeating the same three vertices are dropped, and the caller
reports it (``Triangulation.fanned``). Only polygons that look simple reach earcut; as earcut still takes
about quadratic time on large ones (a 65,536-corner concave polygon takes seconds), polygons of more than
:data:`EARCUT_SMALL` corners draw their squared corner count from a per-call budget, :data:`EARCUT_BUDGET`;
once it is spent such polygons are fanned too (``Triangulation.over_budget``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mapbox_earcut
import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

#: Polygons up to this many corners go to earcut unchecked (its worst case at this size is a fraction of a
#: millisecond); larger ones are checked first (see the module description).
EARCUT_FREE = 32
#: Polygons up to this many corners that reach earcut are not charged to the budget (at most ~2 ms each).
EARCUT_SMALL = 1024
#: Squared corner counts of the larger polygons earcut may take in one call (one polygon of 32,768 corners,
#: or 1,024 of 1,025): about 1 to 5 seconds of earcut in the worst case measured.
EARCUT_BUDGET = 2**30


@dataclass(slots=True)
class Triangulation:
    """Triangles as corner indices.

    Attributes:
        corners: (M, 3) indices into the polygon corner arrays (``SourceMesh.corner_*``).
        face: (M,) index of the polygon each triangle came from.
        lost: Triangles that ear clipping could not produce (zero-area or self-overlapping polygons give
            fewer than ``n - 2``); these are counted as degenerate by callers.
        identity: True when every polygon was already a triangle (``corners`` is ``arange(C).reshape(-1, 3)``).
        fanned: Indices of the polygons that were self-overlapping (a point visited twice, or not turning
            exactly once around) and were fan-triangulated instead of ear-clipped; their triangles may overlap.
        over_budget: Indices of the large concave polygons fan-triangulated because the ear-clipping budget
            (:data:`EARCUT_BUDGET`) was spent.
    """

    corners: IntArray
    face: IntArray
    lost: int
    identity: bool = False
    fanned: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    over_budget: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))


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
        first = offsets[quad]
        p = positions[corner_v[first[:, None] + np.arange(4)]]
        normal = _newell(p)
        # the turn at corners 1 and 3 only (the two that decide the diagonal): the edges into and out of
        # them, their cross product and its dot with the normal, the same operations as over all four
        odd = p[:, 1::2]  # corners 1, 3
        edge_in = odd - p[:, 0::2]  # 1 - 0, 3 - 2
        edge_out = p[:, 2::-2] - odd  # 2 - 1, 0 - 3
        turn = np.einsum("qkj,qj->qk", np.cross(edge_in, edge_out), normal)
        reflex_odd = (turn[:, 0] < 0) | (turn[:, 1] < 0)
        chosen = (first[:, None, None] + np.where(reflex_odd[:, None, None], _DIAG13, _DIAG02)).reshape(-1, 3)
        pieces.append((np.repeat(quad, 2), chosen, np.zeros(0, dtype=np.int64)))

    lost = 0
    big_ids: list[int] = []
    big_tris: list[IntArray] = []
    fanned: list[int] = []
    over_budget: list[int] = []
    budget = EARCUT_BUDGET
    for f in np.flatnonzero(face_sizes > 4).tolist():
        c = offsets[f] + np.arange(face_sizes[f])
        if face_sizes[f] <= EARCUT_FREE:
            local = _earclip(positions[corner_v[c]])
        else:
            local, status, cost = _checked(positions[corner_v[c]], corner_v[c], budget)
            budget -= cost
            if status == "hopeless":
                fanned.append(f)
            elif status == "over-budget":
                over_budget.append(f)
        lost += int(face_sizes[f]) - 2 - len(local)
        big_ids.extend([f] * len(local))
        big_tris.append(c[local])
    if big_tris:
        pieces.append((np.asarray(big_ids, dtype=np.int64), np.concatenate(big_tris), np.zeros(0, dtype=np.int64)))
    fanned_ids = np.asarray(fanned, dtype=np.int64)
    over_ids = np.asarray(over_budget, dtype=np.int64)

    if not pieces:
        empty = np.zeros(0, dtype=np.int64)
        return Triangulation(np.zeros((0, 3), dtype=np.int64), empty, lost, False, fanned_ids, over_ids)
    if len(pieces) == 1:  # one size class: already in polygon order
        identity = bool(tri.size == face_sizes.size)
        return Triangulation(
            pieces[0][1].astype(np.int64, copy=False), pieces[0][0], lost, identity, fanned_ids, over_ids
        )
    face = np.concatenate([p[0] for p in pieces])
    corners = np.concatenate([p[1] for p in pieces]).astype(np.int64, copy=False)
    order = np.argsort(face, kind="stable")
    return Triangulation(corners[order], face[order], lost, False, fanned_ids, over_ids)


#: A quad's two triangles (local corners) split along the diagonal 0-2, and along 1-3.
_DIAG02 = np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int64)
_DIAG13 = np.array([[0, 1, 3], [1, 2, 3]], dtype=np.int64)


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


def _fan(n: int) -> IntArray:
    """Fan triangles (0, i, i + 1) of an n-gon, as (n - 2, 3) local corner indices."""
    return np.stack([np.zeros(n - 2, dtype=np.int64), np.arange(1, n - 1), np.arange(2, n)], axis=1)


def _project(points: FloatArray) -> FloatArray | None:
    """The polygon in 2D, in its best-fit plane, wound counter-clockwise; ``None`` when it has no area."""
    normal = _newell(points)
    length = float(np.linalg.norm(normal))
    if not np.isfinite(length) or length == 0.0:
        return None
    normal = normal / length
    helper = np.eye(3)[int(np.argmin(np.abs(normal)))]
    u = np.cross(normal, helper)
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)  # u x v = normal: the projected polygon has positive area
    flat: FloatArray = np.ascontiguousarray(np.stack([(points - points[0]) @ u, (points - points[0]) @ v], axis=1))
    return flat


def _checked(points: FloatArray, vertex: IntArray, budget: int) -> tuple[IntArray, str, int]:
    """Triangulate a large polygon in bounded time.

    Args:
        points: (n, 3) corner positions.
        vertex: (n,) vertex index of each corner (corners sharing a vertex are the same point).
        budget: What is left of :data:`EARCUT_BUDGET`.

    Returns:
        Local triangles, how they were made (``ok``, ``hopeless`` or ``over-budget``) and the budget used.
    """
    same = (vertex == np.roll(vertex, 1)) | (points == np.roll(points, 1, axis=0)).all(axis=1)
    kept = np.flatnonzero(~same)
    if kept.size < 3:
        return np.zeros((0, 3), dtype=np.int64), "ok", 0
    flat = _project(points[kept])
    if flat is None:  # no net area: a fan without repeats (what is left has no area or overlaps itself)
        return kept[_unique_fan(vertex[kept])], "ok", 0
    if np.unique(flat, axis=0).shape[0] < kept.size:
        return kept[_unique_fan(vertex[kept])], "hopeless", 0
    edge = np.roll(flat, -1, axis=0) - flat  # edge k runs from corner k to corner k + 1
    before = np.roll(edge, 1, axis=0)
    cross = before[:, 0] * edge[:, 1] - before[:, 1] * edge[:, 0]
    dot = (before * edge).sum(axis=1)
    turns = float(np.arctan2(cross, dot).sum()) / (2 * np.pi)
    if round(turns) != 1:  # a simple polygon turns exactly once around (counter-clockwise after _project)
        return kept[_unique_fan(vertex[kept])], "hopeless", 0
    if (cross >= 0).all():  # convex: the fan is exact (collinear corners give triangles of no area)
        return kept[_fan(kept.size)], "ok", 0
    cost = kept.size**2 if kept.size > EARCUT_SMALL else 0
    if cost > budget:
        return kept[_fan(kept.size)], "over-budget", 0
    return kept[_earcut(flat)], "ok", cost


def _unique_fan(vertex: IntArray) -> IntArray:
    """A fan over a polygon, without triangles that repeat the same three vertices (first kept)."""
    fan = _fan(vertex.size)
    _, first = np.unique(np.sort(vertex[fan], axis=1), axis=0, return_index=True)
    result: IntArray = fan[np.sort(first)]
    return result


def _earclip(points: FloatArray) -> npt.NDArray[np.int64]:
    """Ear-clip one polygon (n, 3); returns (k, 3) local corner indices wound like the polygon."""
    flat = _project(points)
    if flat is None:
        return _fan(len(points))
    return _earcut(flat)


def _earcut(flat: FloatArray) -> IntArray:
    """Ear-clip a counter-clockwise 2D polygon (n, 2); returns (k, 3) counter-clockwise triangles."""
    n = len(flat)
    result = mapbox_earcut.triangulate_float64(flat, np.array([n], dtype=np.uint32))
    tris = np.asarray(result, dtype=np.int64).reshape(-1, 3)
    if tris.size:
        a, b, c = flat[tris[:, 0]], flat[tris[:, 1]], flat[tris[:, 2]]
        signed = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
        flip = signed < 0
        tris[flip] = tris[flip][:, [0, 2, 1]]
    return tris
