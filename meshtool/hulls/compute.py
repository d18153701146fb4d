"""Collision geometry: convex hulls of a mesh, of each part, or of a CoACD decomposition, within budgets.

Every hull returned is a closed convex triangle mesh (:mod:`meshtool.hulls.quickhull` in numpy for small inputs;
qhull through scipy for large ones and the nearly degenerate input the numpy hull declines) with at most
``max_hull_vertices`` vertices and a thickness of at least ``min_thickness`` metres along every direction,
so MuJoCo never meets a flat or degenerate hull. Decomposition runs CoACD in a subprocess (see
:mod:`meshtool.hulls.decompose`), cached and deterministic.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from meshtool.errors import MeshtoolError
from meshtool.findings import info, warning
from meshtool.hulls import quickhull
from meshtool.hulls.options import MAX_HULL_COORDINATE as MAX_HULL_COORDINATE
from meshtool.hulls.options import MODES as MODES
from meshtool.hulls.options import PRESETS as PRESETS
from meshtool.hulls.options import HullOptions as HullOptions
from meshtool.repair.mesh import TriMesh
from meshtool.stages import HullSet as HullSet
from meshtool.work.progress import report as report_progress

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


@dataclass(slots=True)
class Hull:
    """One convex collision hull.

    Attributes:
        vertices: (n, 3) metres.
        faces: (k, 3) counter-clockwise seen from outside.
        part: Index of the mesh part it covers.
    """

    vertices: FloatArray
    faces: IntArray
    part: int


def convex_hull(points: FloatArray, options: HullOptions) -> tuple[FloatArray, IntArray, list[str]]:
    """A valid convex hull of ``points`` within the options' vertex budget and minimum thickness.

    qhull never fails the caller: when it refuses the points (precision trouble), they are hulled again
    with joggled input (``QJ``); when that fails too, their thickened bounding box is the hull (note
    ``boxed``).

    Returns:
        Vertices, faces and notes (``thickened``, ``reduced``, ``boxed``) about what was changed.

    Raises:
        MeshtoolError: When a coordinate is not finite or beyond :data:`MAX_HULL_COORDINATE` (code
            ``hull-input``): no hull of such points exists in float64.
    """
    pts = np.unique(np.asarray(points, dtype=np.float64), axis=0)
    if pts.size and not (np.abs(pts) <= MAX_HULL_COORDINATE).all():
        raise MeshtoolError(
            f"cannot make a collision hull of points that are not finite or beyond +-{MAX_HULL_COORDINATE:g} m",
            hint="fix the coordinates or scale the mesh down (--units, --scale)",
            code="hull-input",
        )
    notes: list[str] = []
    extent = float(np.ptp(pts, axis=0).max()) if len(pts) else 0.0
    thickness = min(options.min_thickness, 0.05 * extent) if extent > 0 else options.min_thickness
    thickness = max(thickness, 1e-6)
    flat = _flat_prism(pts, thickness, options.max_hull_vertices)
    # a small asset's hull in numpy: scipy's import (~0.3 s CPU) costs more than the rest of its conversion;
    # beyond NUMPY_HULL_POINTS points or EXACT_ORDER_BUDGET vertices qhull's C is the faster of the two
    small = flat is not None or len(pts) <= NUMPY_HULL_POINTS
    if small and options.max_hull_vertices <= quickhull.EXACT_ORDER_BUDGET:
        made = _numpy_hull(pts, flat, thickness, options.max_hull_vertices)
        if made is not None:
            return made
    from scipy.spatial import QhullError  # qhull: large inputs, and what the numpy hull declines

    picked = False
    if flat is None and len(pts) > PREFILTER_POINTS:
        pts = _extreme_points(pts)
        if len(pts) > options.max_hull_vertices:  # pick the budget's vertices before any exact hull
            pts, picked = _farthest_insertion(pts, options.max_hull_vertices), True
    for qhull_options in ("QbB Pp Qt", "QJ Pp"):
        try:
            if flat is not None:  # a few points already: qhull never sees a large flat facet
                thick, thickened = flat[0], True
                if flat[1]:
                    notes.append("reduced")
            else:
                thick, thickened = _thicken(pts, thickness)
            vertices, faces = _qhull(thick, qhull_options)
            if len(vertices) > options.max_hull_vertices:
                subset = _qhull_subset(vertices, options.max_hull_vertices)
                vertices, faces = _qhull(subset, qhull_options)
                if "reduced" not in notes:
                    notes.append("reduced")
        except (QhullError, ValueError, IndexError, ZeroDivisionError, np.linalg.LinAlgError):
            notes = []
            continue
        if len(vertices) >= 4 and len(faces) >= 4 and np.isfinite(vertices).all():
            if picked and "reduced" not in notes:
                notes.append("reduced")
            return vertices, faces, (["thickened"] if thickened else []) + notes
        notes = []
    vertices, faces = _box(pts, thickness)
    return vertices, faces, ["boxed"]


#: Largest number of distinct points hulled in numpy (:mod:`meshtool.hulls.quickhull`); more go to qhull.
NUMPY_HULL_POINTS = 16384


def _qhull(points: FloatArray, qhull_options: str) -> tuple[FloatArray, IntArray]:
    """Qhull's hull of ``points`` (scipy, no trimesh): the vertices it uses and faces wound outward.

    Raises:
        QhullError, ValueError: As ``scipy.spatial.ConvexHull`` does.
    """
    from scipy.spatial import ConvexHull

    hull = ConvexHull(points, qhull_options=qhull_options)
    faces = np.asarray(hull.simplices, dtype=np.int64)
    tri = points[faces]
    inward = (np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]) * hull.equations[:, :3]).sum(axis=1) < 0
    faces[inward] = faces[inward][:, ::-1]
    used, local = np.unique(faces, return_inverse=True)
    vertices: FloatArray = np.asarray(points[used], dtype=np.float64)
    return vertices, local.reshape(-1, 3).astype(np.int64)


def _numpy_hull(
    pts: FloatArray, flat: tuple[FloatArray, bool] | None, thickness: float, budget: int
) -> tuple[FloatArray, IntArray, list[str]] | None:
    """:func:`convex_hull` by :func:`meshtool.hulls.quickhull.hull3`; ``None`` when it declines (qhull then runs)."""
    notes: list[str] = []
    if flat is not None:
        thick, thickened = flat[0], True
        if flat[1]:
            notes.append("reduced")
    else:
        thick, thickened = _thicken(pts, thickness)
    made = quickhull.hull3(thick, budget)
    if made is None:
        return None
    vertices = thick[made.vertices]
    if len(vertices) < 4 or not np.isfinite(vertices).all():
        return None
    if made.reduced and "reduced" not in notes:
        notes.append("reduced")
    return vertices, made.faces, (["thickened"] if thickened else []) + notes


#: Above this many points, the points that can be hull vertices are found first with joggled input.
PREFILTER_POINTS = 2048


def _extreme_points(pts: FloatArray) -> FloatArray:
    """The points of ``pts`` that are vertices of its hull, found in O(n log n) with joggled input (``QJ``).

    qhull's exact hull merges coplanar facets one point at a time: many co-planar or co-circular points (a
    finely divided cylinder: 10k points took 16 s) make that quadratic. Joggling (perturbing the input by
    ~1e-11 of its size) avoids every merge; the points it keeps are then hulled exactly as before. A point
    that joggling drops lies within that tolerance of the hull. When qhull refuses, all points are kept.
    """
    from scipy.spatial import ConvexHull, QhullError

    try:
        keep = np.sort(ConvexHull(pts, qhull_options="QJ").vertices)
    except (QhullError, ValueError):
        return pts
    kept: FloatArray = pts[keep]
    return kept


def _box(pts: FloatArray, thickness: float) -> tuple[FloatArray, IntArray]:
    """The axis-aligned bounding box of ``pts``, each side at least ``thickness``: 8 vertices, 12 faces."""
    lo = pts.min(axis=0) if len(pts) else np.zeros(3)
    hi = pts.max(axis=0) if len(pts) else np.zeros(3)
    centre, half = (lo + hi) / 2, np.maximum((hi - lo) / 2, thickness / 2)
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=np.float64)
    return corners * half + centre, _BOX_FACES.copy()


#: The 12 triangles of the corners of :func:`_box` (x, y, z each -1 then 1), counter-clockwise from outside.
_BOX_FACES = np.array(
    [
        [0, 1, 3],
        [0, 3, 2],
        [4, 6, 7],
        [4, 7, 5],
        [0, 4, 5],
        [0, 5, 1],
        [2, 3, 7],
        [2, 7, 6],
        [0, 2, 6],
        [0, 6, 4],
        [1, 5, 7],
        [1, 7, 3],
    ],
    dtype=np.int64,
)


def _thicken(pts: FloatArray, thickness: float) -> tuple[FloatArray, bool]:
    """Give a flat, straight or point-like set at least ``thickness`` along its thin principal directions."""
    if len(pts) == 0:
        return pts, False
    centre = pts.mean(axis=0)
    if len(pts) >= 3:
        _, _singular, axes = np.linalg.svd(pts - centre, full_matrices=False)  # (3, 3); U would be (n, n)
        spans = np.ptp((pts - centre) @ axes.T, axis=0)
    else:
        axes = np.eye(3)
        spans = np.ptp(pts - centre, axis=0) if len(pts) > 1 else np.zeros(3)
    thin = [k for k in range(3) if spans[k] < thickness]
    if not thin and len(pts) >= 4:
        return pts, False
    if not thin:
        thin = [2]
    out = pts
    for k in thin:
        offset = axes[k] * (thickness / 2)
        out = np.concatenate([out + offset, out - offset])
    return out, True


def _flat_prism(pts: FloatArray, thickness: float, budget: int) -> tuple[FloatArray, bool] | None:
    """The thickened points of a flat, straight or point-like set of at least 4 points, few of them.

    qhull's work on a large flat facet grows with the square of its vertices (it merges coplanar facets
    one point at a time): the thickened hull of a flat disc with 20 000 points on its rim took minutes.
    Here a flat set is hulled in its plane instead (2-D qhull, O(n log n)) and that polygon is stood on
    the thin direction, from the points' extent less ``thickness / 2`` to it plus ``thickness / 2`` (as
    :func:`_thicken` offsets): a prism when both of its faces fit the vertex ``budget``, else an antiprism,
    its vertices alternately on the top and the bottom face, the polygon first cut to ``budget`` vertices
    by farthest-point insertion (:func:`_polygon_subset`). (Its section through the middle is a polygon
    with twice the vertices of either face, so it follows a rim twice as closely as a prism of half the
    vertices.) A straight set keeps its two end points, a point-like set one point, each boxed the same way.

    Returns:
        The points to hull and whether the polygon was cut or split (``reduced``); ``None`` for fewer than
        4 points or a set that is not thin along any principal direction (those go through :func:`_thicken`).
    """
    if len(pts) < 4:
        return None
    centre = pts.mean(axis=0)
    _, _singular, axes = np.linalg.svd(pts - centre, full_matrices=False)  # (3, 3); U would be (n, n)
    local = (pts - centre) @ axes.T
    lo, hi = local.min(axis=0), local.max(axis=0)
    thin = [k for k in range(3) if hi[k] - lo[k] < thickness]
    if not thin:
        return None
    wide = [k for k in range(3) if k not in thin]

    def up(chosen: IntArray, k: int) -> FloatArray:
        return pts[chosen] + np.outer(hi[k] + thickness / 2 - local[chosen, k], axes[k])

    def down(chosen: IntArray, k: int) -> FloatArray:
        return pts[chosen] - np.outer(local[chosen, k] - lo[k] + thickness / 2, axes[k])

    if len(wide) == 2:
        ring = quickhull.hull2(local[:, wide])  # counter-clockwise
        if ring is None:
            return None
        if 2 * len(ring) <= budget or len(ring) < 4:  # a triangle's prism is cut in 3-D if need be
            chosen = np.sort(ring)
            return np.concatenate([up(chosen, thin[0]), down(chosen, thin[0])]), False
        if len(ring) > budget:
            ring = ring[_polygon_subset(local[ring][:, wide], budget)]
        return np.concatenate([up(ring[0::2], thin[0]), down(ring[1::2], thin[0])]), True
    chosen = np.array([0])
    if len(wide) == 1:
        chosen = np.unique([int(np.argmin(local[:, wide[0]])), int(np.argmax(local[:, wide[0]]))])
    out = pts[chosen]
    for k in thin:  # a box across the thin directions: each copy moved to one side of the extent
        rel = local[chosen, k]
        out = np.concatenate(
            [
                out + np.outer(hi[k] + thickness / 2 - rel, axes[k]),
                out - np.outer(rel - lo[k] + thickness / 2, axes[k]),
            ]
        )
        chosen = np.concatenate([chosen, chosen])
    return out, False


def _polygon_subset(ring: FloatArray, keep: int) -> IntArray:
    """Indices of at most ``keep`` vertices of a convex polygon (``ring``, in order) that approximate it closely.

    The 2-D farthest-point insertion of :func:`_qhull_subset`: start from a large triangle, then add the
    vertex farthest outside the current polygon. For points in convex position, a vertex between two chosen
    ones can only be outside the chord joining them, so each insertion looks at one arc: O(n x keep) at worst.
    Deterministic (ties go to the earliest vertex of an arc, then the lowest index).
    """
    import heapq

    m = len(ring)
    a = int(np.argmin(ring[:, 0]))
    b = int(np.argmax(np.linalg.norm(ring - ring[a], axis=1)))
    rel, d = ring - ring[a], ring[b] - ring[a]
    c = int(np.argmax(np.abs(rel[:, 0] * d[1] - rel[:, 1] * d[0])))
    chosen = sorted({a, b, c})
    heap: list[tuple[float, int, int, int]] = []

    def arc(i: int, j: int) -> None:
        """Queue the vertex between chosen ``i`` and ``j`` (cyclic order) farthest outside their chord."""
        between = np.arange(i + 1, j if j > i else j + m) % m
        if not len(between):
            return
        edge = ring[j] - ring[i]
        normal = np.array([edge[1], -edge[0]]) / max(float(np.linalg.norm(edge)), 1e-300)
        excess = np.abs((ring[between] - ring[i]) @ normal)
        k = int(np.argmax(excess))
        heapq.heappush(heap, (-float(excess[k]), int(between[k]), i, j))

    for n, i in enumerate(chosen):
        arc(i, chosen[(n + 1) % len(chosen)])
    while len(chosen) < keep and heap:
        excess, k, i, j = heapq.heappop(heap)
        if -excess <= 1e-12:
            break
        chosen.append(k)
        arc(i, k)
        arc(k, j)
    return np.sort(np.asarray(chosen, dtype=np.int64))


def _qhull_subset(points: FloatArray, budget: int) -> FloatArray:
    """At most ``budget`` of ``points`` whose hull approximates theirs closely.

    Farthest-point insertion: start from a tetrahedron of extreme points, then add, one at a time, the point
    farthest outside the current hull (largest face-plane excess) until the budget is spent or every point
    is inside. Compared with stopping qhull early (its ``TA`` option, MuJoCo's ``maxhullvert`` approach),
    the surface left outside a 64-vertex hull is about 4x smaller on a fine sphere and 6x on the Stanford
    bunny, in similar time. Deterministic (ties go to the lowest index).
    """
    from scipy.spatial import ConvexHull

    return _farthest_insertion(points[np.sort(ConvexHull(points).vertices)], budget)


def _farthest_insertion(candidates: FloatArray, budget: int) -> FloatArray:
    """At most ``budget`` of ``candidates`` (points on their hull) by farthest-point insertion (see above)."""
    from scipy.spatial import ConvexHull

    if len(candidates) <= budget:
        return candidates
    chosen = _tetrahedron(candidates)
    while len(chosen) < budget:
        planes = ConvexHull(candidates[chosen]).equations  # outward normal n and offset d: n.x + d <= 0 inside
        excess = (candidates @ planes[:, :3].T + planes[:, 3]).max(axis=1)
        excess[chosen] = -np.inf
        k = int(np.argmax(excess))
        if excess[k] <= 1e-12:
            break
        chosen.append(k)
    subset: FloatArray = candidates[np.sort(chosen)]
    return subset


def _tetrahedron(points: FloatArray) -> list[int]:
    """Indices of four points spanning a large tetrahedron (the start of the farthest-point insertion).

    The point of smallest x, the point farthest from it, the point farthest from their line and the point
    farthest from the plane of those three.
    """
    a = int(np.argmin(points[:, 0]))
    b = int(np.argmax(np.linalg.norm(points - points[a], axis=1)))
    ab = (points[b] - points[a]) / np.linalg.norm(points[b] - points[a])
    rel = points - points[a]
    c = int(np.argmax(np.linalg.norm(rel - np.outer(rel @ ab, ab), axis=1)))
    normal = np.cross(points[b] - points[a], points[c] - points[a])
    d = int(np.argmax(np.abs(rel @ normal)))
    return [a, b, c, d]


def compute_hulls(mesh: TriMesh, options: HullOptions, name: str = "<mesh>") -> HullSet:
    """Collision hulls of a mesh (metres, Z-up) according to ``options``.

    Args:
        mesh: The normalised mesh.
        options: See :class:`HullOptions`.
        name: For findings.

    Returns:
        The hulls (empty for mode ``none``) and findings. A failed decomposition of one part falls back to
        that part's convex hull with a warning.
    """
    result = HullSet()
    if options.mode == "none" or mesh.positions.shape[0] == 0:
        return result
    groups = _groups(mesh, options)
    from meshtool.hulls.decompose import Budget, cache_key, decompose, read_hulls, write_hulls

    budget, over_budget = Budget(options.time_budget_s), 0
    problems: list[str] = []  # cache entries found but not used (damaged, answering another key)
    for done, (part, points, faces) in enumerate(groups):
        if options.mode == "decompose":
            report_progress("decomposing parts", done, len(groups))
        key, made = None, None
        if options.mode == "decompose" and faces.shape[0] >= 4 and budget.left() <= 0:
            over_budget += 1
            pieces = [points[np.unique(faces)]]
        elif options.mode == "decompose" and faces.shape[0] >= 4:
            # the finished hulls of a part decomposed before: no CoACD, no qhull (nor their imports)
            key = cache_key(points, faces, options) if options.cache_dir is not None else None
            made = read_hulls(options.cache_dir, key, problems) if key is not None else None
            pieces = []
            if made is not None:
                result.cache_hits += 1
            else:
                pieces, hit, problem = decompose(points, faces, options, budget.left(), problems)
                result.cache_hits += int(hit)
                if problem:
                    result.findings.append(warning("decompose-failed", f"{problem}: convex hull used instead", name))
                    pieces, key = [points], None
        else:
            pieces = [points if faces.shape[0] == 0 else points[np.unique(faces)]]
        if made is None:
            made = []
            for piece in pieces:
                try:
                    made.append(convex_hull(piece, options))
                except MeshtoolError as exc:
                    raise MeshtoolError(exc.message, path=name, hint=exc.hint, code=exc.code) from None
            if key is not None:
                write_hulls(options.cache_dir, key, made)
        for vertices, hull_faces, notes in made:
            result.hulls.append(Hull(vertices, hull_faces, part))
            for note in notes:
                make = warning if note == "boxed" else info
                result.findings.append(make(f"hull-{note}", _NOTE[note].format(part=mesh.part_names[part]), name))
    result.findings += [info("cache-entry-refused", problem, name) for problem in problems]
    if over_budget:
        result.findings.append(
            warning(
                "decompose-budget",
                f"time budget of {options.time_budget_s:g} s spent: {over_budget} part(s) got their convex hull "
                "(raise --time-budget)",
                name,
            )
        )
    if options.mode == "decompose":
        result.findings.append(
            info(
                "hulls-made",
                f"{len(result.hulls)} hull(s) from {len(groups)} part(s) ({result.cache_hits} cached)",
                name,
            )
        )
    return result


_NOTE = {
    "thickened": "a hull of part {part} was flat or thin and was thickened to the minimum thickness",
    "reduced": "a hull of part {part} had too many vertices and was re-hulled within the vertex budget",
    "boxed": "qhull could not hull part {part} (even with joggled input): its bounding box is the hull",
}


def _groups(mesh: TriMesh, options: HullOptions) -> list[tuple[int, FloatArray, IntArray]]:
    """(part, points, faces local to points) per group the mode hulls separately."""
    if options.mode == "convex" or options.merge_parts or mesh.faces.shape[0] == 0:
        return [(0, mesh.positions, mesh.faces)]
    out = []
    for part in sorted(set(mesh.face_part.tolist())):
        faces = mesh.faces[mesh.face_part == part]
        used, inverse = np.unique(faces, return_inverse=True)
        out.append((part, mesh.positions[used], inverse.reshape(-1, 3).astype(np.int64)))
    return out


def quality(mesh: TriMesh, hulls: list[Hull], samples: int = 2000, seed: int = 0) -> dict[str, object]:
    """Hull count, vertices per hull, hull volume / mesh volume and the sampled surface-to-hull distance.

    See :func:`hull_fit`; ``mesh`` gives the positions and faces.
    """
    return hull_fit(mesh.positions, mesh.faces, hulls, samples, seed)


def hull_fit(
    positions: FloatArray, faces: IntArray, hulls: list[Hull], samples: int = 2000, seed: int = 0
) -> dict[str, object]:
    """Hull count, vertices per hull, hull volume / mesh volume and the sampled surface-to-hull distance.

    Args:
        positions: (n, 3) mesh vertices, metres.
        faces: (m, 3) triangles.
        hulls: The collision hulls.
        samples: Surface points sampled for the distance.
        seed: Sampling seed (fixed: the report is deterministic).

    Returns:
        ``hulls`` and ``vertices_per_hull``; with hulls and faces also ``hull_volume_m3``, ``mesh_volume_m3``
        (``None`` unless the mesh is closed), ``volume_ratio`` and the one-sided distance of surface points
        outside the hulls, ``surface_to_hulls_max_m`` and ``surface_to_hulls_mean_m`` (0 inside).
    """
    report: dict[str, object] = {"hulls": len(hulls), "vertices_per_hull": [len(h.vertices) for h in hulls]}
    if not hulls or faces.shape[0] == 0:
        return report
    from meshtool.hulls import surface  # trimesh's formulas without trimesh's import cost (bit-identical)

    volume = float(abs(surface.volume(positions, faces))) if surface.is_watertight(faces) else None
    hull_volume = float(sum(surface.volume(h.vertices, h.faces) for h in hulls))
    points = surface.sample_surface(positions, faces, samples, seed)
    distance = np.full(len(points), np.inf)
    for h in hulls:
        distance = np.minimum(distance, _outside_distance(points, h))
    report.update(
        hull_volume_m3=hull_volume,
        mesh_volume_m3=volume,
        volume_ratio=(hull_volume / volume) if volume else None,
        surface_to_hulls_max_m=float(distance.max()),
        surface_to_hulls_mean_m=float(distance.mean()),
    )
    return report


def _outside_distance(points: FloatArray, hull: Hull) -> FloatArray:
    """Lower bound of the distance from points to a convex hull: the largest face-plane excess (0 inside)."""
    tri = hull.vertices[hull.faces]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-300)
    offsets = (normals * tri[:, 0]).sum(axis=1)
    excess = points @ normals.T - offsets
    result: FloatArray = np.maximum(excess.max(axis=1), 0.0)
    return result
