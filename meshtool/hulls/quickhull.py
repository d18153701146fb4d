"""Convex hulls in numpy: 3-D quickhull with a vertex budget, and the 2-D hull of a polygon's points.

The single convex hull of ``obj2bin`` (``--hulls convex``) and the hulls of parts are made here, so a
small asset's conversion never imports scipy or trimesh (about 0.3 s and 0.6 s of CPU to import, more than
the rest of its conversion). :mod:`meshtool.hulls.compute` falls back to qhull (scipy) when :func:`hull3` declines
(``None``): nearly degenerate input whose visible region is not a disc.

:func:`hull3` inserts points farthest first: the start is a large tetrahedron of extreme points
(:func:`start_tetrahedron`), then, one at a time, the point farthest outside the current hull (largest
face-plane excess) until none is outside by more than a tolerance, or the vertex budget is spent. That is
qhull's quickhull with a global order; with a budget it is the farthest-point insertion that keeps the
surface left outside small (see :func:`meshtool.hulls.compute._qhull_subset`). Each point outside the hull
remembers the face it is farthest outside; an insertion compares the outside points with the new faces
only (and the points of removed faces with every face), so the points inside drop out as the hull grows.
Deterministic: the same points give the same hull (ties go to the first point in the order kept).

tests/test_perf_hull.py compares the hulls with scipy's qhull (vertex sets, volumes) on generated clouds
with many coplanar and co-circular points.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

#: Up to this budget, the point inserted is the farthest outside the whole hull (farthest-point insertion,
#: what a small budget's quality needs); above it, the farthest outside its own face (quickhull's order, the
#: same exact hull in the end, with no per-insertion pass over every face).
EXACT_ORDER_BUDGET = 256
#: Points within this fraction of the input's extent outside a face count as on it (inside).
RELATIVE_TOLERANCE = 1e-10


@dataclass(frozen=True, slots=True)
class Hull3:
    """A closed convex triangle mesh made of some of the input points.

    Attributes:
        vertices: (v,) indices into the input points, ascending.
        faces: (2v - 4, 3) indices into ``vertices``, counter-clockwise seen from outside.
        reduced: The budget stopped the insertion with points still outside (the hull cuts corners).
    """

    vertices: IntArray
    faces: IntArray
    reduced: bool


def tolerance(points: FloatArray) -> float:
    """The distance, in the points' unit, within which a point counts as on a face plane."""
    extent = float(np.ptp(points, axis=0).max()) if len(points) else 0.0
    return max(RELATIVE_TOLERANCE * extent, 1e-14 * float(np.abs(points).max(initial=0.0)))


def start_tetrahedron(points: FloatArray) -> list[int]:
    """Indices of four points spanning a large tetrahedron.

    The point of smallest x, the point farthest from it, the point farthest from their line and the point
    farthest from the plane of those three (each the first such on ties).
    """
    a = int(np.argmin(points[:, 0]))
    b = int(np.argmax(np.linalg.norm(points - points[a], axis=1)))
    ab = (points[b] - points[a]) / max(float(np.linalg.norm(points[b] - points[a])), 1e-300)
    rel = points - points[a]
    c = int(np.argmax(np.linalg.norm(rel - np.outer(rel @ ab, ab), axis=1)))
    normal = np.cross(points[b] - points[a], points[c] - points[a])
    d = int(np.argmax(np.abs(rel @ normal)))
    return [a, b, c, d]


def hull3(points: FloatArray, budget: int | None = None) -> Hull3 | None:
    """The convex hull of (n, 3) ``points``, with at most ``budget`` vertices.

    Args:
        points: (n, 3) float64, any unit; duplicates allowed (the first of equal points is used).
        budget: Most hull vertices (>= 4); ``None`` for the exact hull.

    Returns:
        The hull, or ``None`` when the points span no volume (fewer than 4, flat, straight) or the
        insertion met a configuration it does not handle exactly (the caller then uses qhull).
    """
    pts = np.ascontiguousarray(points, dtype=np.float64)
    n = len(pts)
    if n < 4 or not np.isfinite(pts).all():
        return None
    if n > PREFILTER_POINTS:
        return _prefiltered(pts, budget)
    return _hull3(pts, budget)


def _hull3(pts: FloatArray, budget: int | None, exact: bool | None = None) -> Hull3 | None:
    """:func:`hull3` of (n, 3) finite float64 points, every point considered.

    ``exact``: insert the point farthest outside the whole hull (default: with a budget up to
    :data:`EXACT_ORDER_BUDGET`), else the farthest outside its own face.
    """
    n = len(pts)
    if n < 4:
        return None
    eps = tolerance(pts)
    start = start_tetrahedron(pts)
    if len(set(start)) < 4:
        return None
    a, b, c, d = start
    volume = float(np.dot(np.cross(pts[b] - pts[a], pts[c] - pts[a]), pts[d] - pts[a]))
    if abs(volume) <= eps * max(float(np.ptp(pts, axis=0).max()), 1e-300) ** 2:
        return None
    if exact is None:
        exact = budget is not None and budget <= EXACT_ORDER_BUDGET
    state = _State(pts, eps, exact)
    if volume > 0:  # d above abc: abc must face away from it
        b, c = c, b
    for triple in ((a, b, c), (a, d, b), (b, d, c), (c, d, a)):
        if not state.add_face(*triple):
            return None
    state.vertex_faces[[a, b, c, d]] = 3
    rest = np.ones(n, dtype=bool)
    rest[start] = False
    state.assign(np.flatnonzero(rest), list(range(4)))
    vertices = 4
    limit = n if budget is None else max(4, budget)
    while vertices < limit:
        p, face = state.farthest()
        if p < 0:
            break
        added = state.insert(p, face)
        if added is None:
            return None
        vertices += added
    return state.result(reduced=state.farthest()[0] >= 0)


def _prefiltered(pts: FloatArray, budget: int | None) -> Hull3 | None:
    """:func:`hull3` of many points: first drop those inside hulls of some of them (Akl-Toussaint).

    A point inside the hull of other points is no vertex, and its excess over any plane is at most theirs,
    so the farthest-first order is unchanged. Two such hulls: of the extremes in fixed directions, then
    (when many points are left) a coarse hull of up to :data:`COARSE_VERTICES` vertices in quickhull's
    cheaper per-face order. The inside tests run in chunks (no n x faces temporary).
    """
    eps = tolerance(pts)
    chosen = np.unique([int(np.argmax(pts @ direction)) for direction in _DIRECTIONS])  # contiguous passes
    inner = _hull3(pts[chosen], None)
    if inner is None:
        return _hull3(pts, budget)
    kept = _outside(pts, pts[chosen][inner.vertices], inner.faces, eps)
    kept[chosen] = True
    chosen = np.flatnonzero(kept)
    if len(chosen) > PREFILTER_POINTS and (budget is None or budget < COARSE_VERTICES):
        coarse = _hull3(pts[chosen], COARSE_VERTICES, exact=False)
        if coarse is not None:
            corners = chosen[coarse.vertices]
            kept = _outside(pts[chosen], pts[corners], coarse.faces, eps)
            kept[coarse.vertices] = True
            chosen = chosen[kept]
    made = _hull3(pts[chosen], budget)
    if made is None:
        return None
    return Hull3(chosen[made.vertices], made.faces, made.reduced)


def _outside(pts: FloatArray, corners: FloatArray, faces: IntArray, eps: float) -> npt.NDArray[np.bool_]:
    """Which of ``pts`` are outside the convex hull (``corners``, ``faces``) or within ``eps`` of it."""
    tri = corners[faces]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    offsets = (normals * tri[:, 0]).sum(axis=1)
    out = np.zeros(len(pts), dtype=bool)
    rows = max(256, CHUNK // len(faces))
    for start in range(0, len(pts), rows):
        out[start : start + rows] = (pts[start : start + rows] @ normals.T - offsets).max(axis=1) > -eps
    return out


def _fibonacci_directions(count: int) -> FloatArray:
    """``count`` unit vectors spread evenly over the sphere (a Fibonacci lattice), plus the six axes."""
    k = np.arange(count) + 0.5
    z = 1 - 2 * k / count
    r = np.sqrt(1 - z * z)
    angle = np.pi * (1 + 5**0.5) * k
    spread = np.c_[r * np.cos(angle), r * np.sin(angle), z]
    return np.concatenate([spread, np.eye(3), -np.eye(3)])


#: Above this many points, :func:`hull3` drops the points inside the hull of their extremes first.
PREFILTER_POINTS = 4096
#: Vertices of the coarse hull that drops most of the points left (its faces' count is about twice that).
COARSE_VERTICES = 256
#: Directions whose extreme points make that first hull; rows per chunk of the inside test.
_DIRECTIONS = _fibonacci_directions(42)
CHUNK = 1 << 18  # rows x faces per block of the inside test (2 MiB of float64)


class _State:
    """The faces (vertex triples, planes), the directed-edge map and the outside sets of :func:`hull3`."""

    def __init__(self, pts: FloatArray, eps: float, exact_order: bool) -> None:
        self.pts, self.eps, self.exact_order = pts, eps, exact_order
        self.faces: list[tuple[int, int, int]] = []
        self.normals: list[list[float]] = []
        self.offsets: list[float] = []
        self.alive: list[bool] = []
        self.edges: dict[tuple[int, int], int] = {}
        self.vertex_faces = np.zeros(len(pts), dtype=np.int64)
        #: The points outside the hull, the face each is farthest outside and by how much.
        self.candidates = np.zeros(0, dtype=np.int64)
        self.owner = np.zeros(0, dtype=np.int64)
        self.excess = np.zeros(0, dtype=np.float64)

    def add_face(self, i: int, j: int, k: int) -> bool:
        """Add face (i, j, k); ``False`` when it is degenerate or an edge is already used that way."""
        return self.add_faces([(i, j)], k)

    def add_faces(self, bases: list[tuple[int, int]], k: int) -> bool:
        """Add the faces (i, j, k) of each base edge (i, j); ``False`` when one is degenerate or clashes."""
        p = self.pts
        base = np.asarray(bases, dtype=np.int64)
        normal = np.cross(p[base[:, 1]] - p[base[:, 0]], p[k] - p[base[:, 0]])
        length = np.sqrt((normal * normal).sum(axis=1))
        if not (length > 0).all():
            return False
        normal /= length[:, None]
        offsets = (normal * p[base[:, 0]]).sum(axis=1)
        for (i, j), n, offset in zip(bases, normal.tolist(), offsets.tolist(), strict=True):
            if (i, j) in self.edges or (j, k) in self.edges or (k, i) in self.edges:
                return False
            index = len(self.faces)
            self.faces.append((i, j, k))
            self.normals.append(n)
            self.offsets.append(offset)
            self.alive.append(True)
            self.edges[(i, j)] = self.edges[(j, k)] = self.edges[(k, i)] = index
        return True

    def assign(self, chosen: IntArray, faces: list[int]) -> None:
        """Give each of ``chosen`` to the face of ``faces`` it is farthest outside, beyond the tolerance."""
        if not len(chosen):
            return
        normals = np.array([self.normals[f] for f in faces])
        offsets = np.array([self.offsets[f] for f in faces])
        excess = self.pts[chosen] @ normals.T - offsets
        best = np.argmax(excess, axis=1)
        value = excess[np.arange(len(chosen)), best]
        out = value > self.eps
        self.candidates = np.concatenate([self.candidates, chosen[out]])
        self.owner = np.concatenate([self.owner, np.asarray(faces, dtype=np.int64)[best[out]]])
        self.excess = np.concatenate([self.excess, value[out]])

    def farthest(self) -> tuple[int, int]:
        """(point, face) of the point farthest outside the hull, or (-1, -1) when none is outside."""
        if not len(self.excess):
            return -1, -1
        k = int(np.argmax(self.excess))
        return int(self.candidates[k]), int(self.owner[k])

    def insert(self, p: int, start: int) -> int | None:
        """Add point ``p`` (outside face ``start``): the change in vertex count, ``None`` if it cannot."""
        x, y, z = self.pts[p].tolist()
        visible, stack, horizon = {start}, [start], []
        while stack:
            f = stack.pop()
            face = self.faces[f]
            for edge in ((face[0], face[1]), (face[1], face[2]), (face[2], face[0])):
                g = self.edges[(edge[1], edge[0])]
                if g in visible:
                    continue
                nx, ny, nz = self.normals[g]
                if nx * x + ny * y + nz * z - self.offsets[g] > self.eps:
                    visible.add(g)
                    stack.append(g)
                else:
                    horizon.append(edge)
        following = dict(horizon)
        if len(following) != len(horizon) or not _one_cycle(following):
            return None
        counts = self.vertex_faces
        for f in visible:  # the horizon is one loop around a disc of visible faces: replace the disc
            self.alive[f] = False
            face = self.faces[f]
            for v in face:
                counts[v] -= 1
            for edge in ((face[0], face[1]), (face[1], face[2]), (face[2], face[0])):
                del self.edges[edge]
        first = len(self.faces)
        if not self.add_faces(horizon, p):
            return None
        for i, _ in horizon:  # each horizon vertex gains two faces, p one per edge
            counts[i] += 2
        counts[p] += len(horizon)
        self._update(p, visible, list(range(first, len(self.faces))))
        return 1 - _fallen_inside(self, visible)

    def _update(self, p: int, visible: set[int], new: list[int]) -> None:
        """Keep every outside point's farthest face exact after ``p`` replaced the ``visible`` faces by ``new``.

        A point whose face survived compares it with the new faces; a point whose face was removed is
        measured against every face alive (it may be farthest outside an old one).
        """
        keep = self.candidates != p
        self.candidates, self.owner, self.excess = self.candidates[keep], self.owner[keep], self.excess[keep]
        dead = np.zeros(len(self.faces), dtype=bool)
        dead[list(visible)] = True
        orphan = dead[self.owner]
        rest = ~orphan
        if rest.any() and self.exact_order:
            normals = np.array([self.normals[f] for f in new])
            offsets = np.array([self.offsets[f] for f in new])
            excess = self.pts[self.candidates[rest]] @ normals.T - offsets
            best = np.argmax(excess, axis=1)
            value = excess[np.arange(len(best)), best]
            better = value > self.excess[rest]
            where = np.flatnonzero(rest)[better]
            self.owner[where] = np.asarray(new, dtype=np.int64)[best[better]]
            self.excess[where] = value[better]
        if orphan.any():
            moved = self.candidates[orphan]
            self.candidates, self.owner, self.excess = self.candidates[rest], self.owner[rest], self.excess[rest]
            # outside the new hull, a point of a removed face is outside one of the new faces (they cover
            # the visible region's cone): only the global farthest-first order needs every face
            every = [f for f, alive in enumerate(self.alive) if alive] if self.exact_order else new
            self.assign(moved, every)

    def result(self, reduced: bool) -> Hull3 | None:
        """The alive faces as a :class:`Hull3`, checked closed (V - E + F = 2)."""
        faces = np.array([f for f, alive in zip(self.faces, self.alive, strict=True) if alive], dtype=np.int64)
        vertices, local = np.unique(faces, return_inverse=True)
        if len(faces) != 2 * len(vertices) - 4 or len(self.edges) != 3 * len(faces):
            return None
        return Hull3(vertices.astype(np.int64), local.reshape(-1, 3).astype(np.int64), reduced)


def _fallen_inside(state: _State, visible: set[int]) -> int:
    """How many vertices of the removed faces lost every face (fell inside the hull)."""
    return len({v for f in visible for v in state.faces[f] if state.vertex_faces[v] == 0})


def _one_cycle(following: dict[int, int]) -> bool:
    """Whether the edges ``i -> following[i]`` form a single closed loop through all their vertices."""
    start = next(iter(following))
    v, steps = following[start], 1
    while v != start:
        if v not in following or steps > len(following):
            return False
        v, steps = following[v], steps + 1
    return steps == len(following)


def hull2(points: FloatArray) -> IntArray | None:
    """Indices of the convex hull of (n, 2) ``points`` in counter-clockwise order (Andrew's monotone chain).

    Collinear points on an edge are left out; the first vertex is the lowest (x, y). ``None`` when the
    points span no area (fewer than 3 distinct, or all on a line).
    """
    pts = np.asarray(points, dtype=np.float64)
    if len(pts) < 3:
        return None
    order = np.lexsort((pts[:, 1], pts[:, 0]))
    eps = tolerance(pts) * max(float(np.ptp(pts, axis=0).max()), 1e-300)
    xs, ys = pts[order, 0].tolist(), pts[order, 1].tolist()

    def chain(indices: range) -> list[int]:
        out: list[int] = []
        for k in indices:
            while len(out) >= 2:
                i, j = out[-2], out[-1]
                cross = (xs[j] - xs[i]) * (ys[k] - ys[i]) - (ys[j] - ys[i]) * (xs[k] - xs[i])
                if cross > eps:
                    break
                out.pop()
            out.append(k)
        return out

    lower = chain(range(len(xs)))
    upper = chain(range(len(xs) - 1, -1, -1))
    ring = lower[:-1] + upper[:-1]
    if len(ring) < 3:
        return None
    return order[np.asarray(ring, dtype=np.int64)].astype(np.int64)
