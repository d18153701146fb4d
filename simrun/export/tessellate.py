"""Triangle meshes with normals and texture coordinates for MuJoCo's primitive geoms and compiled meshes.

Used by the animated exports (glTF and the browser page). Every shape is in the geom's own frame (MuJoCo's
conventions: boxes by half sizes, capsules and cylinders along z by radius and half length, planes facing
+z), metres. Texture coordinates follow glTF (``v = 0`` at the image's top row, as MuJoCo's texture data):
box faces each show the whole image, spheres, ellipsoids, capsules and cylinder sides are mapped by
longitude (u) and latitude or height (v), cylinder caps and planes by x and y. Planes and box faces tile
the image ``texrepeat`` times over the face, or, with ``texuniform``, ``texrepeat / 2`` times per metre (as
MuJoCo's renderer draws them: measured, a 10-repeat uniform checker plane shows 5 tiles per metre); meshes
keep MuJoCo's texture coordinates. (MuJoCo's renderer maps 2D textures onto spheres, capsules and
cylinders its own way; those differ.) Normals are unit length, per vertex; vertices are split where
normals or texture coordinates change (box edges, cylinder rims, the longitude seam), so flat faces shade
flat.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np
import numpy.typing as npt

#: Segments around spheres, capsules and cylinders; rings from pole to pole.
SEGMENTS, RINGS = 32, 16
#: Half size drawn for an infinite plane (MuJoCo draws a size-0 plane as its visual extent), metres.
INFINITE_PLANE = 50.0

F64 = npt.NDArray[np.float64]
I64 = npt.NDArray[np.int64]


@dataclass(frozen=True)
class Surface:
    """A triangle mesh ready for glTF.

    Attributes:
        positions: (n, 3) vertex positions, metres, geom frame.
        normals: (n, 3) unit vertex normals.
        uvs: (n, 2) texture coordinates (glTF convention), or ``None`` for a mesh without them.
        triangles: (k, 3) vertex indices, counter-clockwise seen from outside.
    """

    positions: F64
    normals: F64
    uvs: F64 | None
    triangles: I64


def _unit(vectors: F64, fallback: F64) -> F64:
    lengths = np.linalg.norm(vectors, axis=1, keepdims=True)
    good = lengths[:, 0] > 1e-12
    out = np.where(good[:, None], vectors / np.where(lengths > 1e-12, lengths, 1.0), fallback)
    return np.asarray(out, dtype=np.float64)


def _grid(rows: int, cols: int, offset: int = 0) -> I64:
    """Triangles of a (rows + 1) x (cols + 1) vertex grid, skipping the zero-area halves at collapsed rows."""
    out = []
    for r in range(rows):
        for c in range(cols):
            a = offset + r * (cols + 1) + c
            b, d = a + 1, a + cols + 1
            out.append((a, d, b))
            out.append((b, d, d + 1))
    return np.asarray(out, dtype=np.int64)


def box(half: F64, repeat: F64, uniform: bool) -> Surface:
    """A box of half sizes ``half``: 6 faces of 4 vertices, each face showing the image (tiled by ``repeat``)."""
    positions: list[F64] = []
    normals: list[F64] = []
    uvs: list[list[float]] = []
    triangles: list[tuple[int, int, int]] = []
    for axis in range(3):
        for sign in (1.0, -1.0):
            u_axis, v_axis = (axis + 1) % 3, (axis + 2) % 3
            if sign < 0:
                u_axis, v_axis = v_axis, u_axis  # keep the winding counter-clockwise from outside
            normal = np.zeros(3)
            normal[axis] = sign
            scale = repeat * (np.array([half[u_axis], half[v_axis]]) if uniform else 1.0)  # see the module
            base = len(positions)
            for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                p = np.zeros(3)
                p[axis], p[u_axis], p[v_axis] = sign * half[axis], su * half[u_axis], sv * half[v_axis]
                positions.append(p)
                normals.append(normal)
                uvs.append([(su + 1) / 2 * scale[0], (1 - sv) / 2 * scale[1]])
            triangles += [(base, base + 1, base + 2), (base, base + 2, base + 3)]
    return Surface(np.array(positions), np.array(normals), np.array(uvs), np.array(triangles, dtype=np.int64))


def plane(half: F64, repeat: F64, uniform: bool) -> Surface:
    """A quad facing +z of half sizes ``half[:2]`` (0: :data:`INFINITE_PLANE`), the image tiled ``repeat`` times."""
    hx, hy = (float(h) if h > 0 else INFINITE_PLANE for h in half[:2])
    corners = np.array([[-hx, -hy, 0.0], [hx, -hy, 0.0], [hx, hy, 0.0], [-hx, hy, 0.0]])
    if uniform:
        uvs = np.stack([corners[:, 0] * repeat[0] / 2, -corners[:, 1] * repeat[1] / 2], axis=1)
    else:
        uvs = np.stack([(corners[:, 0] / (2 * hx) + 0.5) * repeat[0], (0.5 - corners[:, 1] / (2 * hy)) * repeat[1]], 1)
    normals = np.tile([0.0, 0.0, 1.0], (4, 1))
    return Surface(corners, normals, uvs, np.array([(0, 1, 2), (0, 2, 3)], dtype=np.int64))


def _rings(profile: list[tuple[float, float, float, float]]) -> Surface:
    """A surface of revolution about z from rows (radius, z, normal's z component, v), pole to pole."""
    rows = len(profile) - 1
    angles = np.linspace(0.0, 2 * math.pi, SEGMENTS + 1)
    positions, normals, uvs = [], [], []
    for radius, z, nz, v in profile:
        nr = math.sqrt(max(0.0, 1.0 - nz * nz))
        for k, angle in enumerate(angles):
            c, s = math.cos(angle), math.sin(angle)
            positions.append((radius * c, radius * s, z))
            normals.append((nr * c, nr * s, nz))
            uvs.append((k / SEGMENTS, v))
    triangles = _grid(rows, SEGMENTS)
    p = np.array(positions)
    # drop the zero-area triangles at the poles (two corners at the same point)
    first, second, third = p[triangles[:, 0]], p[triangles[:, 1]], p[triangles[:, 2]]
    keep = np.linalg.norm(np.cross(second - first, third - first), axis=1) > 1e-15
    return Surface(p, np.array(normals), np.array(uvs), triangles[keep])


def sphere(radii: F64) -> Surface:
    """A sphere (equal ``radii``) or ellipsoid of semi-axes ``radii``."""
    profile = []
    for r in range(RINGS + 1):
        theta = math.pi * r / RINGS
        profile.append((math.sin(theta), math.cos(theta), math.cos(theta), r / RINGS))
    unit = _rings(profile)
    normals = _unit(unit.normals / radii, unit.normals)  # the normal of x.x/a^2 = 1 scales by 1/a
    return Surface(unit.positions * radii, normals, unit.uvs, unit.triangles)


def capsule(radius: float, half_length: float) -> Surface:
    """A capsule along z: a cylinder of ``half_length`` with hemispherical ends of ``radius``."""
    half_rings = RINGS // 2
    total = 2 * half_length + math.pi * radius
    profile = []
    for r in range(half_rings + 1):  # north cap, pole to equator
        theta = math.pi / 2 * r / half_rings
        profile.append(
            (radius * math.sin(theta), half_length + radius * math.cos(theta), math.cos(theta), theta * radius)
        )
    for r in range(half_rings + 1):  # south cap, equator to pole
        theta = math.pi / 2 + math.pi / 2 * r / half_rings
        arc = 2 * half_length + theta * radius
        profile.append((radius * math.sin(theta), -half_length + radius * math.cos(theta), math.cos(theta), arc))
    rows = [(rad, z, nz, v / total) for rad, z, nz, v in profile]
    return _rings(rows)


def cylinder(radius: float, half_length: float) -> Surface:
    """A closed cylinder along z: the side (u around, v top to bottom) and two flat caps."""
    side = _rings([(radius, half_length, 0.0, 0.0), (radius, -half_length, 0.0, 1.0)])
    parts = [side]
    angles = np.linspace(0.0, 2 * math.pi, SEGMENTS, endpoint=False)
    for sign in (1.0, -1.0):
        ring = np.stack([radius * np.cos(angles), radius * np.sin(angles), np.full(SEGMENTS, sign * half_length)], 1)
        positions = np.vstack([[0.0, 0.0, sign * half_length], ring])
        normals = np.tile([0.0, 0.0, sign], (SEGMENTS + 1, 1))
        uvs = np.stack([positions[:, 0] / (2 * radius) + 0.5, 0.5 - sign * positions[:, 1] / (2 * radius)], 1)
        k = np.arange(SEGMENTS)
        triangles = np.stack([np.zeros(SEGMENTS, dtype=np.int64), 1 + k, 1 + (k + 1) % SEGMENTS], 1)
        if sign < 0:
            triangles = triangles[:, [0, 2, 1]]
        parts.append(Surface(positions, normals, uvs, triangles))
    return merge(parts)


def merge(parts: list[Surface]) -> Surface:
    """One surface from several (all with texture coordinates, or none)."""
    offsets = np.cumsum([0] + [len(p.positions) for p in parts[:-1]])
    uvs = None if any(p.uvs is None for p in parts) else np.vstack([p.uvs for p in parts if p.uvs is not None])
    return Surface(
        np.vstack([p.positions for p in parts]),
        np.vstack([p.normals for p in parts]),
        uvs,
        np.vstack([p.triangles + o for p, o in zip(parts, offsets, strict=True)]),
    )


def compiled_surface(model: mujoco.MjModel, mesh_id: int) -> Surface:
    """A compiled MuJoCo mesh with its own normals and texture coordinates, one vertex per distinct corner.

    Each triangle corner names a vertex, a normal and (when the mesh has them) a texture coordinate;
    corners naming the same three become one glTF vertex.
    """
    f0, nf = int(model.mesh_faceadr[mesh_id]), int(model.mesh_facenum[mesh_id])
    v0, n0 = int(model.mesh_vertadr[mesh_id]), int(model.mesh_normaladr[mesh_id])
    corners_v = np.asarray(model.mesh_face[f0 : f0 + nf], dtype=np.int64).ravel()
    corners_n = np.asarray(model.mesh_facenormal[f0 : f0 + nf], dtype=np.int64).ravel()
    t0 = int(model.mesh_texcoordadr[mesh_id])
    textured = t0 >= 0 and int(model.mesh_texcoordnum[mesh_id]) > 0
    corners_t = np.asarray(model.mesh_facetexcoord[f0 : f0 + nf], dtype=np.int64).ravel() if textured else corners_v * 0
    keys = np.stack([corners_v, corners_n, corners_t], axis=1)
    unique, inverse = np.unique(keys, axis=0, return_inverse=True)
    positions = np.asarray(model.mesh_vert[v0 + unique[:, 0]], dtype=np.float64)
    raw = np.asarray(model.mesh_normal[n0 + unique[:, 1]], dtype=np.float64)
    triangles = np.asarray(inverse, dtype=np.int64).reshape(-1, 3)
    normals = _unit(raw, _face_normals_at_vertices(positions, triangles))
    uvs = np.asarray(model.mesh_texcoord[t0 + unique[:, 2]], dtype=np.float64) if textured else None
    return Surface(positions, normals, uvs, triangles)


def _face_normals_at_vertices(positions: F64, triangles: I64) -> F64:
    """Area-weighted vertex normals (for corners whose stored normal is zero), +z where even those vanish."""
    a, b, c = (positions[triangles[:, k]] for k in range(3))
    face = np.cross(b - a, c - a)
    summed = np.zeros_like(positions)
    for k in range(3):
        np.add.at(summed, triangles[:, k], face)
    return _unit(summed, np.tile([0.0, 0.0, 1.0], (len(positions), 1)))


def geom_surface(model: mujoco.MjModel, g: int, repeat: F64, uniform: bool) -> Surface | None:
    """The surface of geom ``g`` in its own frame (``None`` for height fields and SDF geoms)."""
    kind, size = int(model.geom_type[g]), np.asarray(model.geom_size[g], dtype=np.float64)
    if kind == int(mujoco.mjtGeom.mjGEOM_BOX):
        return box(size, repeat, uniform)
    if kind == int(mujoco.mjtGeom.mjGEOM_PLANE):
        return plane(size, repeat, uniform)
    if kind == int(mujoco.mjtGeom.mjGEOM_SPHERE):
        return sphere(np.full(3, size[0]))
    if kind == int(mujoco.mjtGeom.mjGEOM_ELLIPSOID):
        return sphere(size)
    if kind == int(mujoco.mjtGeom.mjGEOM_CAPSULE):
        return capsule(float(size[0]), float(size[1]))
    if kind == int(mujoco.mjtGeom.mjGEOM_CYLINDER):
        return cylinder(float(size[0]), float(size[1]))
    if kind == int(mujoco.mjtGeom.mjGEOM_MESH):
        surface = compiled_surface(model, int(model.geom_dataid[g]))
        if surface.uvs is not None and not np.array_equal(repeat, [1.0, 1.0]):
            surface = Surface(surface.positions, surface.normals, surface.uvs * repeat, surface.triangles)
        return surface
    return None
