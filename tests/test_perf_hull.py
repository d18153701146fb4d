"""The numpy convex hull (issue 28): the same hulls as qhull (scipy), and no scipy/trimesh import to make them.

Ground truth is scipy's qhull (``scipy.spatial.ConvexHull``): vertex sets, volumes, and every input point
inside. The clouds are made to be hard: points on a sphere (all on the hull), co-circular rims, lattices
with many coplanar and collinear points, duplicates, a thin slab and a far-off-origin cloud.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from meshtool.hulls.compute import HullOptions, _farthest_insertion, convex_hull
from meshtool.hulls.quickhull import hull2, hull3, tolerance

ROOT = Path(__file__).resolve().parent.parent


def _clouds() -> dict[str, np.ndarray]:
    rng = np.random.default_rng(28)
    sphere = rng.normal(size=(1500, 3))
    t = np.linspace(0, 2 * np.pi, 120, endpoint=False)
    rim = np.c_[np.cos(t), np.sin(t), np.zeros_like(t)]
    lattice = np.stack(np.meshgrid(*[np.linspace(-1, 1, 7)] * 3), -1).reshape(-1, 3)
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
    return {
        "gaussian": rng.normal(size=(3000, 3)),
        "sphere": sphere / np.linalg.norm(sphere, axis=1, keepdims=True),
        "cylinder rims": np.concatenate([rim, rim + np.array([0.0, 0.0, 2.0])]),
        "lattice": lattice,
        "cube with inside points": np.concatenate([rng.uniform(-1, 1, (400, 3)), corners]),
        "duplicates": np.repeat(rng.normal(size=(50, 3)), 3, axis=0),
        "thin slab": rng.uniform(-1, 1, (800, 3)) * [1, 1, 1e-3],
        "far from the origin": rng.normal(size=(500, 3)) + 1e4,
        "cone": np.concatenate([rim, [[0, 0, 1.0]], rng.uniform(-0.3, 0.3, (100, 3))]),
        "uniform ball": rng.uniform(-1, 1, (20000, 3)),
    }


CLOUDS = _clouds()


def _volume(points: np.ndarray, faces: np.ndarray) -> float:
    tri = points[faces] - points.mean(axis=0)  # about the centroid: no cancellation far from the origin
    return float(np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6)


@pytest.mark.parametrize("name", CLOUDS)
def test_exact_hull_is_qhulls(name: str) -> None:
    points = CLOUDS[name]
    made = hull3(points)
    assert made is not None and not made.reduced
    reference = ConvexHull(points)
    vertices = points[made.vertices]
    assert _volume(vertices, made.faces) == pytest.approx(reference.volume, rel=1e-9)
    # every vertex qhull keeps is one of ours (ties: ours may keep a point on a face qhull merged away)
    assert set(map(tuple, points[reference.vertices].tolist())) <= set(map(tuple, vertices.tolist()))
    tri = vertices[made.faces]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    assert (points @ normals.T - (normals * tri[:, 0]).sum(axis=1)).max() <= 10 * tolerance(points)
    # closed and consistently wound: every directed edge once, its reverse once
    edges = {(int(a), int(b)) for f in made.faces for a, b in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0]))}
    assert len(edges) == 3 * len(made.faces) and all((b, a) in edges for a, b in edges)
    assert len(made.faces) == 2 * len(made.vertices) - 4


@pytest.mark.parametrize("name", ["gaussian", "sphere", "uniform ball", "far from the origin"])
def test_budget_hull_is_the_farthest_insertion_of_qhulls_vertices(name: str) -> None:
    """With a budget, the vertices are those farthest-point insertion picks from qhull's hull vertices."""
    points = CLOUDS[name]
    made = hull3(points, 16)
    assert made is not None and made.reduced and len(made.vertices) == 16
    candidates = points[np.sort(ConvexHull(points).vertices)]
    expected = _farthest_insertion(candidates, 16)
    assert sorted(map(tuple, points[made.vertices].tolist())) == sorted(map(tuple, expected.tolist()))


def test_degenerate_input_is_declined() -> None:
    flat = np.c_[np.random.default_rng(1).uniform(size=(50, 2)), np.zeros(50)]
    assert hull3(flat) is None and hull3(flat[:3]) is None
    assert hull3(np.ones((10, 3))) is None


@pytest.mark.parametrize("seed", range(5))
def test_polygon_hull_is_qhulls(seed: int) -> None:
    rng = np.random.default_rng(seed)
    points = np.concatenate([rng.normal(size=(500, 2)), np.round(rng.uniform(-3, 3, (200, 2)))])
    ring = hull2(points)
    assert ring is not None
    reference = ConvexHull(points)
    # the same corners (equal points may be represented by different indices)
    assert sorted(map(tuple, points[ring].tolist())) == sorted(map(tuple, points[reference.vertices].tolist()))
    x, y = points[ring, 0], points[ring, 1]
    area = 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))
    assert area == pytest.approx(reference.volume, rel=1e-12)  # positive: counter-clockwise


@pytest.mark.parametrize("mesh", ["bowl/bowl.obj", "head/Head 1.obj"])
def test_one_convex_hull_imports_neither_scipy_nor_trimesh(mesh: str) -> None:
    """The single hull of a fixture, in a fresh interpreter: the modules it imported are counted."""
    code = (
        "import sys, json\nfrom pathlib import Path\nfrom meshtool.repair.normalise import prepare, NormaliseOptions\n"
        "from meshtool.hulls.compute import HullOptions, convex_hull\n"
        f"asset = prepare(Path({str(ROOT / 'fixtures' / mesh)!r}), NormaliseOptions(strict=False))\n"
        "vertices, faces, notes = convex_hull(asset.mesh.positions, HullOptions())\n"
        "print(json.dumps([len(vertices), sorted(m for m in ('scipy', 'trimesh') if m in sys.modules)]))"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    count, heavy = json.loads(result.stdout)
    assert 4 <= count <= 64 and heavy == []


@pytest.mark.parametrize("name", ["sphere", "lattice", "cone", "thin slab"])
def test_convex_hull_volume_matches_qhull_of_the_same_points(name: str) -> None:
    """The full pipeline (thickening, budget) against qhull's hull of the points it kept."""
    vertices, faces, _notes = convex_hull(CLOUDS[name], HullOptions(max_hull_vertices=256, min_thickness=1e-6))
    assert _volume(vertices, faces) == pytest.approx(ConvexHull(vertices).volume, rel=1e-9)
