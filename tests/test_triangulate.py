import numpy as np
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from meshtool.read.obj.parse import parse_obj
from meshtool.read.obj.triangulate import triangulate_polygons


def areas_and_normals(positions, tris):
    p = positions[tris]
    cross = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    return 0.5 * np.linalg.norm(cross, axis=1), cross


def test_concave_polygons_keep_their_area_and_winding(fixtures):
    obj = parse_obj((fixtures / "crlf_ngon" / "shapes.obj").read_bytes())
    tri = triangulate_polygons(obj.positions, obj.face_sizes, obj.corner_v)
    assert tri.lost == 0
    assert np.bincount(tri.face).tolist() == [4, 2, 8]  # n - 2 triangles per polygon
    areas, cross = areas_and_normals(obj.positions, obj.corner_v[tri.corners])
    per_face = np.bincount(tri.face, weights=areas)
    star = obj.positions[obj.corner_v[-10:]][:, :2]
    star_area = 0.5 * abs(np.dot(star[:, 0], np.roll(star[:, 1], -1)) - np.dot(star[:, 1], np.roll(star[:, 0], -1)))
    np.testing.assert_allclose(per_face, [3.0, 0.5, star_area], rtol=1e-12)
    # every triangle faces +z like its counter-clockwise polygon
    assert (cross[:, 2] > 0).all()


def test_trimesh_fan_gets_the_concave_polygons_wrong(fixtures):
    """The reason ear clipping exists here: trimesh's fan over-covers concave polygons."""
    mesh = trimesh.load(fixtures / "crlf_ngon" / "shapes.obj", process=False)
    ours = parse_obj((fixtures / "crlf_ngon" / "shapes.obj").read_bytes())
    tri = triangulate_polygons(ours.positions, ours.face_sizes, ours.corner_v)
    areas, _ = areas_and_normals(ours.positions, ours.corner_v[tri.corners])
    assert len(mesh.faces) == len(tri.corners) == 14
    assert abs(mesh.area - areas.sum()) > 0.5


def test_concave_quad_splits_at_the_reflex_corner():
    positions = np.array([[0, 0, 0], [1, -1, 0], [0, -0.5, 0], [-1, -1, 0]], dtype=float)
    for shift in range(4):
        order = np.roll(np.arange(4), shift)
        tri = triangulate_polygons(positions, np.array([4]), order)
        areas, cross = areas_and_normals(positions, order[tri.corners])
        np.testing.assert_allclose(areas.sum(), 0.5)
        assert (cross[:, 2] < 0).all()  # clockwise seen from +z: kept clockwise


def test_non_planar_polygon_is_triangulated_in_its_best_fit_plane():
    angles = np.linspace(0, 2 * np.pi, 7)[:-1]
    ring = np.stack([np.cos(angles), np.sin(angles), 0.01 * np.cos(3 * angles)], axis=1)
    rot = trimesh.transformations.rotation_matrix(0.7, [1, 1, 0])[:3, :3]
    tri = triangulate_polygons(ring @ rot.T, np.array([6]), np.arange(6))
    assert len(tri.corners) == 4
    _, cross = areas_and_normals(ring @ rot.T, tri.corners)
    assert (cross @ (rot @ [0, 0, 1]) > 0).all()


# ------------------------------------------------------------------------------------------------------
# large and degenerate polygons (issue 21): bounded work, the area kept where there is one


def shoelace(points_2d):
    """Signed area of a 2D polygon (analytic, independent of the triangulator)."""
    x, y = points_2d[:, 0], points_2d[:, 1]
    return 0.5 * (np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def flat(points_2d):
    return np.concatenate([points_2d, np.zeros((len(points_2d), 1))], axis=1)


def comb(teeth):
    """A simple concave comb, counter-clockwise: ``teeth`` teeth 1 wide and 9 deep on a base 1 high."""
    pts = [(0.0, 0.0)]
    for i in range(teeth):
        x = 2.0 * i
        pts += [(x, 10.0), (x + 1, 10.0), (x + 1, 1.0), (x + 2, 1.0)]
    pts += [(2.0 * teeth, 0.0)]
    return np.array(pts)[::-1]


def one(points_2d):
    n = len(points_2d)
    return triangulate_polygons(flat(points_2d), np.array([n]), np.arange(n))


def test_large_convex_polygon_is_fanned_exactly_and_not_reported():
    angles = np.linspace(0, 2 * np.pi, 5000, endpoint=False)
    circle = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    tri = one(circle)
    areas, cross = areas_and_normals(flat(circle), tri.corners)
    assert len(tri.corners) == 4998 and tri.lost == 0 and tri.fanned.size == 0
    np.testing.assert_allclose(areas.sum(), shoelace(circle), rtol=1e-12)
    assert (cross[:, 2] > 0).all()


def test_large_concave_simple_polygon_is_ear_clipped_with_its_area():
    points = comb(500)
    tri = one(points)
    areas, cross = areas_and_normals(flat(points), tri.corners)
    assert len(tri.corners) == len(points) - 2 and tri.fanned.size == 0
    np.testing.assert_allclose(areas.sum(), shoelace(points), rtol=1e-12)
    assert shoelace(points) == 500 * 9 + 2 * 500  # teeth plus base
    assert (cross[:, 2] > 0).all()


def test_repeated_and_collinear_corners_of_a_large_polygon_are_cleaned_first():
    # a 100-corner square: every corner written twice, each side split by collinear corners
    side = np.linspace(0, 1, 13)[:-1]
    square = np.concatenate(
        [
            np.stack([side, 0 * side], 1),
            np.stack([1 + 0 * side, side], 1),
            np.stack([1 - side, 1 + 0 * side], 1),
            np.stack([0 * side, 1 - side], 1),
        ]
    )
    doubled = np.repeat(square, 2, axis=0)
    positions = flat(square)
    corner_v = np.repeat(np.arange(len(square)), 2)
    tri = triangulate_polygons(positions, np.array([corner_v.size]), corner_v)
    areas, _ = areas_and_normals(positions, corner_v[tri.corners])
    assert len(doubled) == 96 and tri.fanned.size == 0
    np.testing.assert_allclose(areas.sum(), 1.0, rtol=1e-12)


def test_self_crossing_star_is_fanned_and_reported():
    n = 1001  # {1001/500}: every edge crosses most others, it winds 500 times
    angles = 2 * np.pi * ((np.arange(n) * 500) % n) / n
    star = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    tri = one(star)
    assert tri.fanned.tolist() == [0]
    assert len(tri.corners) <= n - 2


def test_polygon_visiting_a_point_twice_is_fanned_without_repeated_triangles():
    n = 100_000  # over the reader's corner limit: the triangulator itself stays fast
    positions = flat(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]]))
    corner_v = np.arange(n) % 3
    tri = triangulate_polygons(positions, np.array([n]), corner_v)
    assert tri.fanned.tolist() == [0]
    triangles = {tuple(sorted(t)) for t in corner_v[tri.corners].tolist()}
    assert len(triangles) == len(tri.corners)  # each vertex triple once
    areas, _ = areas_and_normals(positions, corner_v[tri.corners])
    np.testing.assert_allclose(areas.sum(), 0.5)  # the triangle the face walks around, once


def test_zero_area_large_polygon_gives_no_area():
    line = np.stack([np.arange(200) % 7, np.zeros(200)], axis=1).astype(float)
    tri = one(line)
    areas, _ = areas_and_normals(flat(line), tri.corners)
    assert areas.sum() == 0.0


def test_ear_clipping_budget_fans_large_concave_polygons_once_spent(monkeypatch):
    from meshtool.read.obj import triangulate

    points = comb(300)  # 1202 corners: over EARCUT_SMALL, charged 1202**2
    monkeypatch.setattr(triangulate, "EARCUT_BUDGET", int(1.5 * len(points) ** 2))
    n = len(points)
    positions = flat(np.concatenate([points, points + np.array([0.0, 20.0])]))
    corner_v = np.concatenate([np.arange(n), n + np.arange(n), np.arange(n)])
    tri = triangulate_polygons(positions, np.array([n, n, n]), corner_v)
    assert tri.over_budget.tolist() == [1, 2] and tri.fanned.size == 0
    areas, _ = areas_and_normals(positions, corner_v[tri.corners])
    np.testing.assert_allclose(areas[tri.face == 0].sum(), shoelace(points), rtol=1e-12)


@settings(max_examples=60, deadline=None)
@given(
    radii=st.lists(st.floats(0.05, 1.0), min_size=33, max_size=400),
    jitter=st.floats(0.0, 0.45),
    axis=st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(0.1, 1)),
    seed=st.integers(0, 2**16),
)
def test_simple_star_shaped_polygons_keep_their_area_and_winding(radii, jitter, axis, seed):
    """Star-shaped polygons (simple by construction) over the checked path: never fanned, area by shoelace."""
    n = len(radii)
    rng = np.random.default_rng(seed)
    angles = 2 * np.pi * (np.arange(n) + jitter * rng.uniform(-1, 1, n)) / n
    ring = np.stack([np.cos(angles), np.sin(angles)], axis=1) * np.asarray(radii)[:, None]
    rot = trimesh.geometry.align_vectors([0, 0, 1], np.asarray(axis) / np.linalg.norm(axis))[:3, :3]
    positions = flat(ring) @ rot.T
    tri = triangulate_polygons(positions, np.array([n]), np.arange(n))
    assert tri.fanned.size == 0 and tri.over_budget.size == 0
    areas, cross = areas_and_normals(positions, tri.corners)
    np.testing.assert_allclose(areas.sum(), shoelace(ring), rtol=1e-9)
    assert (cross @ (rot @ [0, 0, 1]) >= -1e-12).all()  # every triangle faces like the polygon
