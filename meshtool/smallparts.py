"""Visual meshes MuJoCo refuses: submeshes with fewer than 4 distinct vertices.

Every run of one material and one part becomes its own visual mesh in MJCF, and MuJoCo refuses a mesh
with fewer than 4 vertices ("at least 4 vertices required"). Such a submesh is merged into the nearest
submesh of the same material in another part; when there is none, it is padded with one vertex just off
its first triangle (0.01 % of its size) and one sliver triangle, so it keeps its look and loads. Each
change is a ``part-merged`` or ``part-padded`` warning.

Flat submeshes (all vertices in one plane, at least 4 of them) are left alone: MuJoCo loads them as
visual meshes with ``inertia="shell"``, which meshtool and simrun write for every visual mesh (only the
``legacy``/``exact`` inertia and convex hulls need volume; hulls are thickened in :mod:`meshtool.hulls`).
Merging them would only lose the part structure (a Cornell box's walls would join a block).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from meshtool.findings import Finding, warning
from meshtool.mesh import TriMesh

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
    groups = _groups(mesh)
    verdict = {key: _verdict(mesh, faces) for key, faces in groups.items()}
    merged: dict[tuple[int, int], tuple[int, int]] = {}
    for key, kind in verdict.items():
        if kind is None:
            continue
        material, part = key
        targets = [k for k in groups if k[0] == material and k != key and verdict[k] is None]
        if not targets:
            continue
        target = min(targets, key=lambda k: (_gap(mesh, groups[key], groups[k]), k[1]))
        mesh.face_part[groups[key]] = target[1]
        merged[key] = target
        findings.append(
            warning(
                "part-merged",
                f"part {mesh.part_names[part]!r} ({kind}, material {mesh.material_names[material]!r}) merged into "
                f"part {mesh.part_names[target[1]]!r} so MuJoCo can load it",
                path,
            )
        )
    if merged:
        _regroup(mesh)
        groups = _groups(mesh)
    padded: list[Finding] = []
    for (material, part), faces in sorted(groups.items(), key=lambda item: -int(item[1][0])):
        if _distinct(mesh, faces) >= MIN_VERTICES:
            continue
        _pad(mesh, faces)  # from the last run backwards: inserting after a run leaves earlier runs in place
        padded.append(
            warning(
                "part-padded",
                f"part {mesh.part_names[part]!r} (material {mesh.material_names[material]!r}) has fewer than "
                f"{MIN_VERTICES} distinct vertices: padded with a sliver triangle so MuJoCo can load it",
                path,
            )
        )
    return findings + padded[::-1]


def _groups(mesh: TriMesh) -> dict[tuple[int, int], IntArray]:
    """Face indices of each (material, part) pair, in first-appearance order."""
    keys = mesh.face_material.astype(np.int64) * (len(mesh.part_names) + 1) + mesh.face_part
    _, first, inverse = np.unique(keys, return_index=True, return_inverse=True)
    out: dict[tuple[int, int], IntArray] = {}
    for g in np.argsort(first, kind="stable").tolist():
        faces = np.flatnonzero(inverse == g)
        f = int(faces[0])
        out[(int(mesh.face_material[f]), int(mesh.face_part[f]))] = faces
    return out


def _distinct(mesh: TriMesh, faces: IntArray) -> int:
    return int(np.unique(mesh.positions[np.unique(mesh.faces[faces])], axis=0).shape[0])


def _verdict(mesh: TriMesh, faces: IntArray) -> str | None:
    """``N distinct vertices`` for a submesh MuJoCo refuses, ``None`` for one it loads as it is."""
    points = np.unique(mesh.positions[np.unique(mesh.faces[faces])], axis=0)
    if points.shape[0] < MIN_VERTICES:
        return f"{points.shape[0]} distinct vertices"
    return None


def _gap(mesh: TriMesh, a: IntArray, b: IntArray) -> float:
    """Distance between the bounding boxes of two submeshes (0 when they overlap)."""
    pa, pb = mesh.positions[mesh.faces[a].ravel()], mesh.positions[mesh.faces[b].ravel()]
    lo = np.maximum(pa.min(axis=0), pb.min(axis=0))
    hi = np.minimum(pa.max(axis=0), pb.max(axis=0))
    return float(np.linalg.norm(np.maximum(lo - hi, 0.0)))


def _regroup(mesh: TriMesh) -> None:
    """Reorder triangles by material, then part name (as :func:`meshtool.mesh.build_mesh` orders them), stably."""
    names = np.asarray(mesh.part_names, dtype=object)
    rank = np.empty(len(names), dtype=np.int64)
    rank[np.argsort(names, kind="stable")] = np.arange(len(names))
    order = np.lexsort((rank[mesh.face_part], mesh.face_material))
    for name in ("faces", "face_uv", "face_normal", "face_material", "face_part", "face_lines"):
        setattr(mesh, name, getattr(mesh, name)[order])


def _pad(mesh: TriMesh, faces: IntArray) -> None:
    """Add one vertex just off the first triangle of ``faces`` and a sliver triangle using it."""
    f = int(faces[0])
    a, b, c = (int(i) for i in mesh.faces[f])
    pa, pb, pc = mesh.positions[a], mesh.positions[b], mesh.positions[c]
    normal = np.cross(pb - pa, pc - pa)
    length = float(np.linalg.norm(normal))
    normal = normal / length if length > 0 else np.array([0.0, 0.0, 1.0])
    pts = mesh.positions[np.unique(mesh.faces[faces])]
    size = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0)))
    new_point = pa + normal * max(PAD_RELATIVE * size, PAD_MIN_M)
    d = mesh.positions.shape[0]
    mesh.positions = np.vstack([mesh.positions, new_point[None, :]])
    if mesh.colors is not None:
        mesh.colors = np.vstack([mesh.colors, mesh.colors[a][None, :]])
    at = int(faces[-1]) + 1
    uv, nv = mesh.face_uv[f], mesh.face_normal[f]
    mesh.faces = np.insert(mesh.faces, at, [a, b, d], axis=0)
    mesh.face_uv = np.insert(mesh.face_uv, at, [uv[0], uv[1], uv[0]], axis=0)
    mesh.face_normal = np.insert(mesh.face_normal, at, [nv[0], nv[1], nv[0]], axis=0)
    for name in ("face_material", "face_part", "face_lines"):
        values = getattr(mesh, name)
        setattr(mesh, name, np.insert(values, at, values[f]))
