"""Surface integrals of a triangle mesh in plain numpy: area, volume, centre of mass, inertia, sampling.

The same formulas (and the same floating-point operations, in the same order) as trimesh 4/5's
``trimesh.triangles.mass_properties`` (D. Eberly, "Polyhedral Mass Properties (Revisited)",
geometrictools.com), ``Trimesh.is_watertight`` and ``trimesh.sample.sample_surface``, so the results are
bit-identical to trimesh's (tests/test_surface.py checks) without importing trimesh, whose import costs
more CPU than packing a small asset.

All inputs: ``positions`` (n, 3) in metres (any float dtype, computed in float64) and ``faces`` (m, 3)
vertex indices; outputs in metres, square metres, cubic metres, kg m^2 at unit density (1 kg/m^3).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class MassProperties:
    """Volume integrals of a closed surface at unit density.

    Attributes:
        volume: Signed volume, m^3 (positive for outward-facing triangles).
        center_mass: (3,) centre of mass, m.
        inertia: (3, 3) inertia tensor about the centre of mass, axes of the mesh frame, kg m^2 per kg/m^3.
    """

    volume: float
    center_mass: FloatArray
    inertia: FloatArray


def triangles(positions: npt.ArrayLike, faces: npt.ArrayLike) -> FloatArray:
    """(m, 3, 3) float64 corner positions of every face."""
    return np.asarray(positions, dtype=np.float64)[np.asarray(faces, dtype=np.int64)]


def crosses(tris: FloatArray) -> FloatArray:
    """(m, 3) cross product of each triangle's two edges from corner 0 (twice the area vector)."""
    vectors = tris[:, 1:, :] - tris[:, :2, :]
    result: FloatArray = np.cross(vectors[:, 0], vectors[:, 1])
    return result


def face_areas(cross: FloatArray) -> FloatArray:
    """(m,) triangle areas from :func:`crosses`, m^2."""
    result: FloatArray = np.sqrt((cross**2).sum(axis=1)) / 2.0
    return result


def is_watertight(faces: npt.ArrayLike) -> bool:
    """Whether every edge is shared by exactly two faces (trimesh's definition; winding not checked)."""
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if f.shape[0] == 0:
        return False
    edges = np.sort(f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    key = edges[:, 0] * (int(edges[:, 1].max()) + 1) + edges[:, 1]
    _, counts = np.unique(key, return_counts=True)
    return bool((counts == 2).all())


def mass_properties(tris: FloatArray, cross: FloatArray | None = None) -> MassProperties:
    """Volume, centre of mass and inertia of the closed surface made of ``tris`` (unit density).

    Args:
        tris: (m, 3, 3) corners, see :func:`triangles`.
        cross: Their :func:`crosses`, when already computed.

    Returns:
        The integrals; meaningful only for a closed, consistently wound surface (zero volume gives
        non-finite centre and inertia, as in trimesh).
    """
    if cross is None:
        cross = crosses(tris)
    t0, t1, t2 = tris[:, 0, :], tris[:, 1, :], tris[:, 2, :]
    f1 = t0 + t1 + t2
    f2 = t0**2 + t1**2 + t0 * t1 + t2 * f1
    f3 = (t0**3) + (t0**2) * (t1) + (t0) * (t1**2) + (t1**3) + (t2 * f2)
    g0 = f2 + (t0 + f1) * t0
    g1 = f2 + (t1 + f1) * t1
    g2 = f2 + (t2 + f1) * t2
    integral = np.zeros((10, len(f1)))
    integral[0] = cross[:, 0] * f1[:, 0]
    integral[1:4] = (cross * f2).T
    integral[4:7] = (cross * f3).T
    for i in range(3):
        j = np.mod(i + 1, 3)
        integral[i + 7] = cross[:, i] * ((t0[:, j] * g0[:, i]) + (t1[:, j] * g1[:, i]) + (t2[:, j] * g2[:, i]))
    integrated = integral.sum(axis=1) / np.array([6, 24, 24, 24, 60, 60, 60, 120, 120, 120], dtype=np.float64)
    volume = integrated[0]
    with np.errstate(divide="ignore", invalid="ignore"):
        center = integrated[1:4] / volume
        inertia = np.zeros((3, 3))
        inertia[0, 0] = integrated[5] + integrated[6] - (volume * (center[[1, 2]] ** 2).sum())
        inertia[1, 1] = integrated[4] + integrated[6] - (volume * (center[[0, 2]] ** 2).sum())
        inertia[2, 2] = integrated[4] + integrated[5] - (volume * (center[[0, 1]] ** 2).sum())
        inertia[0, 1] = -(integrated[7] - (volume * np.prod(center[[0, 1]])))
        inertia[1, 2] = -(integrated[8] - (volume * np.prod(center[[1, 2]])))
        inertia[0, 2] = -(integrated[9] - (volume * np.prod(center[[0, 2]])))
    inertia[2, 0] = inertia[0, 2]
    inertia[2, 1] = inertia[1, 2]
    inertia[1, 0] = inertia[0, 1]
    return MassProperties(float(volume), center, inertia * 1.0)


def volume(positions: npt.ArrayLike, faces: npt.ArrayLike) -> float:
    """Signed volume enclosed by the triangles, m^3 (garbage unless the surface is closed)."""
    tris = triangles(positions, faces)
    return mass_properties(tris).volume


def sample_surface(positions: npt.ArrayLike, faces: npt.ArrayLike, count: int, seed: int) -> FloatArray:
    """``count`` points on the surface, uniformly by area (trimesh.sample.sample_surface's draws).

    Args:
        positions: (n, 3) vertices.
        faces: (m, 3) triangles, at least one with non-zero area.
        count: Number of points.
        seed: Seed of ``numpy.random.default_rng``.

    Returns:
        (count, 3) points.
    """
    vertices = np.asarray(positions, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    weight_cum = np.cumsum(face_areas(crosses(vertices[f])))
    random = np.random.default_rng(seed).random
    face_pick = random(count) * weight_cum[-1]
    face_index = np.searchsorted(weight_cum, face_pick)
    tri_origins = vertices[f[:, 0]]
    tri_vectors = vertices[f[:, 1:]].copy()
    tri_vectors -= np.tile(tri_origins, (1, 2)).reshape((-1, 2, 3))
    tri_origins = tri_origins[face_index]
    tri_vectors = tri_vectors[face_index]
    random_lengths = random((len(tri_vectors), 2, 1))
    random_test = random_lengths.sum(axis=1).reshape(-1) > 1.0
    random_lengths[random_test] -= 1.0
    random_lengths = np.abs(random_lengths)
    sample_vector = (tri_vectors * random_lengths).sum(axis=1)
    result: FloatArray = sample_vector + tri_origins
    return result
