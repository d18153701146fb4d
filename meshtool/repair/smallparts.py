"""Visual meshes MuJoCo refuses: submeshes with fewer than 4 distinct vertices.

Every run of one material and one part becomes its own visual mesh in MJCF, and MuJoCo refuses a mesh
with fewer than 4 vertices ("at least 4 vertices required"). Such a submesh is merged into the nearest
submesh of the same material in another part; when there is none, it is padded with one vertex just off
its first triangle (0.01 % of its size) and one sliver triangle, so it keeps its look and loads. Each
change is a ``part-merged`` or ``part-padded`` warning.

Flat submeshes (all vertices in one plane, at least 4 of them) are left alone: MuJoCo loads them as
visual meshes with ``inertia="shell"``, which meshtool and simrun write for every visual mesh (only the
``legacy``/``exact`` inertia and convex hulls need volume; hulls are thickened in :mod:`meshtool.hulls.compute`).
Merging them would only lose the part structure (a Cornell box's walls would join a block).

The work is O(n log n) in triangles and parts (issue 27: a per-part pass over the whole mesh made 16 000
parts take 50 s): submeshes are grouped by one sort, distinct vertices are counted for all of them at once
(never more than 4: no sort of positions), the nearest submesh of a merge is found through k-d trees of
bounding-box centres, and all paddings are inserted in one pass.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from meshtool.findings import Finding, warning
from meshtool.repair.mesh import TriMesh

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

#: MuJoCo's least number of mesh vertices.
MIN_VERTICES = 4
#: Offset of the padding vertex, relative to the submesh's size, and its least value (metres).
PAD_RELATIVE = 1e-4
PAD_MIN_M = 1e-6


def fix_small_parts(mesh: TriMesh, path: str | None = None) -> list[Finding]:
    """Merge or pad the submeshes of ``mesh`` that MuJoCo cannot load as visual meshes (in place).

    Args:
        mesh: The normalised mesh (metres); triangles stay ordered by material, runs of one part contiguous.
        path: The source file for findings.

    Returns:
        ``part-merged`` and ``part-padded`` warnings.
    """
    if mesh.faces.shape[0] == 0:
        return []
    findings: list[Finding] = []
    groups = _Groups(mesh)
    small = np.flatnonzero(groups.distinct < MIN_VERTICES)
    merged = 0
    if len(small):
        targets = _targets(groups, small)
        for g in small.tolist():
            target = targets.get(g)
            if target is None:
                continue
            material, part = groups.keys[g]
            mesh.face_part[groups.faces[g]] = groups.keys[target][1]
            merged += 1
            findings.append(
                warning(
                    "part-merged",
                    f"part {mesh.part_names[part]!r} ({int(groups.distinct[g])} distinct vertices, material "
                    f"{mesh.material_names[material]!r}) merged into part "
                    f"{mesh.part_names[groups.keys[target][1]]!r} so MuJoCo can load it",
                    path,
                )
            )
    if merged:
        _regroup(mesh)
        groups = _Groups(mesh)
        small = np.flatnonzero(groups.distinct < MIN_VERTICES)
    if not len(small):
        return findings
    _pad(mesh, groups, small)
    padded = [
        warning(
            "part-padded",
            f"part {mesh.part_names[part]!r} (material {mesh.material_names[material]!r}) has fewer than "
            f"{MIN_VERTICES} distinct vertices: padded with a sliver triangle so MuJoCo can load it",
            path,
        )
        for material, part in (groups.keys[g] for g in small.tolist())
    ]
    return findings + padded


class _Groups:
    """The (material, part) submeshes of a mesh, in first-appearance order, found with one sort.

    Attributes:
        keys: ``(material, part)`` of each submesh.
        faces: Its triangle indices, ascending.
        distinct: Its number of distinct vertex positions, counted up to :data:`MIN_VERTICES`.
        lo, hi: (G, 3) corners of its bounding box.
    """

    def __init__(self, mesh: TriMesh) -> None:
        codes = mesh.face_material.astype(np.int64) * (len(mesh.part_names) + 1) + mesh.face_part
        _, first, inverse = np.unique(codes, return_index=True, return_inverse=True)
        inverse = inverse.reshape(-1)
        rank = np.empty(len(first), dtype=np.int64)  # sorted code -> first-appearance order
        rank[np.argsort(first, kind="stable")] = np.arange(len(first))
        group = rank[inverse]
        order = np.argsort(group, kind="stable")
        sizes = np.bincount(group, minlength=len(first))
        self.faces: list[IntArray] = np.split(order, np.cumsum(sizes)[:-1])
        starts = order[np.concatenate([[0], np.cumsum(sizes)[:-1]])]
        self.keys: list[tuple[int, int]] = list(
            zip(mesh.face_material[starts].tolist(), mesh.face_part[starts].tolist(), strict=True)
        )
        owner, vertex = _vertices(group, mesh.faces.astype(np.int64), mesh.positions.shape[0])
        points = mesh.positions[vertex]
        bounds = np.flatnonzero(np.concatenate([[True], owner[1:] != owner[:-1]]))
        self.lo: FloatArray = np.minimum.reduceat(points, bounds, axis=0)
        self.hi: FloatArray = np.maximum.reduceat(points, bounds, axis=0)
        self.distinct = _count_distinct(owner, points, len(first))


def _vertices(group: IntArray, faces: IntArray, count: int) -> tuple[IntArray, IntArray]:
    """(group, vertex index) of every vertex each group uses, once, ordered by group.

    When no vertex is shared between groups (the usual case), that is each used vertex with its one group:
    no sort of the corners.
    """
    corners = faces.reshape(-1)
    owners = np.repeat(group, 3)
    owner_of = np.full(max(count, 1), -1, dtype=np.int64)
    owner_of[corners] = owners
    if (owner_of[corners] == owners).all():
        used = np.flatnonzero(owner_of >= 0)
        order = np.argsort(owner_of[used], kind="stable")
        return owner_of[used][order], used[order]
    pairs = np.unique(owners * count + corners)
    return pairs // count, pairs % count


#: Rows of each group looked at first: a group with MIN_VERTICES distinct among them needs no other pass.
HEAD_ROWS = 16


def _count_distinct(owner: IntArray, points: FloatArray, groups: int) -> IntArray:
    """Distinct rows of ``points`` per ``owner`` (sorted group ids), counted up to :data:`MIN_VERTICES`.

    The first :data:`HEAD_ROWS` rows of every group are counted first; only the groups with fewer than
    ``MIN_VERTICES`` distinct among them and more rows are counted over all their rows. A large mesh (one
    group of 556k vertices) costs a pass to find the heads instead of ``MIN_VERTICES`` passes over every
    vertex (issue 28: 0.3 s of the bunny's 1.3 s).
    """
    if not len(owner):
        return np.zeros(groups, dtype=np.int64)
    first = np.flatnonzero(np.concatenate([[True], owner[1:] != owner[:-1]]))
    sizes = np.diff(first, append=len(owner))
    rank = np.arange(len(owner)) - np.repeat(first, sizes)  # position of each row within its group
    head = np.flatnonzero(rank < HEAD_ROWS)
    distinct = _count_rows(owner[head], points[head], groups)
    longer = np.zeros(groups, dtype=bool)
    longer[owner[first]] = sizes > HEAD_ROWS
    again = longer & (distinct < MIN_VERTICES)
    if again.any():
        rows = np.flatnonzero(again[owner])
        distinct[again] = _count_rows(owner[rows], points[rows], groups)[again]
    return distinct


def _count_rows(owner: IntArray, points: FloatArray, groups: int) -> IntArray:
    """:func:`_count_distinct` over every row given.

    Each round takes every group's first row not equal to any taken before and drops the rows equal to it:
    ``MIN_VERTICES`` linear passes instead of sorting positions (``np.unique(axis=0)`` over every vertex
    was most of this module's time on large meshes).
    """
    distinct = np.zeros(groups, dtype=np.int64)
    left = np.arange(len(owner))
    for _ in range(MIN_VERTICES):
        if not len(left):
            break
        own = owner[left]
        firsts = left[np.concatenate([[True], own[1:] != own[:-1]])]
        distinct[owner[firsts]] += 1
        taken = np.empty((groups, points.shape[1]))
        taken[owner[firsts]] = points[firsts]
        left = left[(points[left] != taken[own]).any(axis=1)]
    return distinct


#: Pairs of (small, candidate) submeshes measured directly; above it candidates come from k-d trees.
_DIRECT_PAIRS = 1 << 16


def _targets(groups: _Groups, small: IntArray) -> dict[int, int]:
    """For each small submesh, the loadable submesh of its material nearest by bounding-box gap.

    Ties go to the lower part index. Submeshes without such a candidate are left out.
    """
    material = np.array([k[0] for k in groups.keys], dtype=np.int64)
    part = np.array([k[1] for k in groups.keys], dtype=np.int64)
    loadable = groups.distinct >= MIN_VERTICES
    out: dict[int, int] = {}
    for m in np.unique(material[small]).tolist():
        a = small[material[small] == m]
        b = np.flatnonzero(loadable & (material == m))
        if not len(b):
            continue
        if len(a) * len(b) <= _DIRECT_PAIRS:
            pa, pb = np.repeat(a, len(b)), np.tile(b, len(a))
        else:
            pa, pb = _near_pairs(groups, a, b)
        gap = _gaps(groups, pa, pb)
        order = np.lexsort((part[pb], gap, pa))
        pa, pb, gap = pa[order], pb[order], gap[order]
        heads = np.flatnonzero(np.concatenate([[True], pa[1:] != pa[:-1]]))
        ends = np.concatenate([heads[1:], [len(pa)]])
        for h, e in zip(heads.tolist(), ends.tolist(), strict=True):
            best = gap[h]
            tied = h + int(np.searchsorted(gap[h:e], best * (1 + 1e-12), side="right"))
            if best > 0 and tied - h > 1:  # within rounding of each other: measured as one pair at a time
                exact = [_gap(groups, int(pa[h]), int(q)) for q in pb[h:tied].tolist()]
                out[int(pa[h])] = min(zip(exact, part[pb[h:tied]].tolist(), pb[h:tied].tolist(), strict=True))[2]
            else:
                out[int(pa[h])] = int(pb[h])
    return out


def _near_pairs(groups: _Groups, a: IntArray, b: IntArray) -> tuple[IntArray, IntArray]:
    """(small, candidate) pairs that include, for each of ``a``, every ``b`` at the least gap from it.

    A gap is at least the distance between the boxes' centres less both half-diagonals. Candidates are
    grouped by half-diagonal (powers of 2), one k-d tree of centres each: the nearest centre of each
    bounds the gap from above, and a ball query per group returns everything that may be nearer.
    """
    from scipy.spatial import cKDTree

    centre = (groups.lo + groups.hi) / 2
    radius = np.sqrt(((groups.hi - groups.lo) ** 2).sum(axis=1)) / 2
    scale = 1e-9 * (1.0 + float(np.abs(np.concatenate([groups.lo[b], groups.hi[b]])).max()))
    sizes = np.frexp(radius[b])[1]
    trees = []
    bound = np.full(len(a), np.inf)
    for size in np.unique(sizes).tolist():
        members = b[sizes == size]
        tree = cKDTree(centre[members])
        _, nearest = tree.query(centre[a])
        bound = np.minimum(bound, _gaps(groups, a, members[nearest]))
        trees.append((tree, members, float(radius[members].max())))
    found_a, found_b = [], []
    for tree, members, largest in trees:
        reach = (bound + radius[a] + largest) * (1 + 1e-9) + scale
        hits = tree.query_ball_point(centre[a], reach, return_sorted=False)
        lengths = np.fromiter((len(h) for h in hits), dtype=np.int64, count=len(hits))
        found_a.append(np.repeat(a, lengths))
        found_b.append(members[np.fromiter((i for h in hits for i in h), dtype=np.int64, count=int(lengths.sum()))])
    return np.concatenate(found_a), np.concatenate(found_b)


def _gaps(groups: _Groups, a: IntArray, b: IntArray) -> FloatArray:
    """Distances between the bounding boxes of submeshes ``a[i]`` and ``b[i]`` (0 where they overlap)."""
    lo = np.maximum(groups.lo[a], groups.lo[b])
    hi = np.minimum(groups.hi[a], groups.hi[b])
    d = np.maximum(lo - hi, 0.0)
    gaps: FloatArray = np.sqrt((d * d).sum(axis=1))
    return gaps


def _gap(groups: _Groups, a: int, b: int) -> float:
    """The gap of :func:`_gaps` as one vector norm (the formula near-ties are settled with)."""
    lo = np.maximum(groups.lo[a], groups.lo[b])
    hi = np.minimum(groups.hi[a], groups.hi[b])
    return float(np.linalg.norm(np.maximum(lo - hi, 0.0)))


def _regroup(mesh: TriMesh) -> None:
    """Reorder triangles by material, then part name (as :func:`~meshtool.repair.mesh.build_mesh` orders them)."""
    names = np.asarray(mesh.part_names, dtype=object)
    rank = np.empty(len(names), dtype=np.int64)
    rank[np.argsort(names, kind="stable")] = np.arange(len(names))
    order = np.lexsort((rank[mesh.face_part], mesh.face_material))
    for name in ("faces", "face_uv", "face_normal", "face_material", "face_part", "face_lines"):
        setattr(mesh, name, getattr(mesh, name)[order])


def _pad(mesh: TriMesh, groups: _Groups, small: IntArray) -> None:
    """Give each of the ``small`` submeshes one vertex just off its first triangle and a sliver triangle.

    The new vertices are appended from the last submesh to the first and each sliver goes right after its
    submesh's last triangle; all are inserted in one pass. (Lengths are ``sqrt(v.dot(v))`` per vector, as
    ``np.linalg.norm`` gives them: the padding does not move by a rounding from one version to the next.)
    """
    rows = sorted(small.tolist(), key=lambda g: -int(groups.faces[g][0]))
    src = np.asarray([int(groups.faces[g][0]) for g in rows], dtype=np.int64)
    at = [int(groups.faces[g][-1]) + 1 for g in rows]
    pa, pb, pc = (mesh.positions[mesh.faces[src, k]] for k in range(3))
    normal = np.cross(pb - pa, pc - pa)
    length = np.array([float(np.sqrt(v.dot(v))) for v in normal])
    normal[length > 0] /= length[length > 0, None]
    normal[length <= 0] = [0.0, 0.0, 1.0]
    diagonal = groups.hi[rows] - groups.lo[rows]
    size = np.array([float(np.sqrt(v.dot(v))) for v in diagonal])
    points = pa + normal * np.maximum(PAD_RELATIVE * size, PAD_MIN_M)[:, None]
    new = mesh.positions.shape[0] + np.arange(len(rows), dtype=np.int64)
    mesh.positions = np.vstack([mesh.positions, points])
    if mesh.colors is not None:
        mesh.colors = np.vstack([mesh.colors, mesh.colors[mesh.faces[src, 0]]])
    mesh.faces = np.insert(mesh.faces, at, np.column_stack([mesh.faces[src, 0], mesh.faces[src, 1], new]), axis=0)
    for name in ("face_uv", "face_normal"):
        values = getattr(mesh, name)
        setattr(mesh, name, np.insert(values, at, values[src][:, [0, 1, 0]], axis=0))
    for name in ("face_material", "face_part", "face_lines"):
        values = getattr(mesh, name)
        setattr(mesh, name, np.insert(values, at, values[src]))
