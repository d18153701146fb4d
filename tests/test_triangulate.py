import numpy as np
import trimesh

from meshtool.obj.parse import parse_obj
from meshtool.obj.triangulate import triangulate_polygons


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
