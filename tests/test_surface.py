"""meshtool.hulls.surface against trimesh (an independent implementation) and against analytic solids."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from meshtool.hulls import surface


def _meshes() -> list[trimesh.Trimesh]:
    rng = np.random.default_rng(7)
    cloud = trimesh.convex.convex_hull(rng.normal(size=(200, 3)) * [1.0, 2.0, 0.5] + [3.0, -1.0, 2.0])
    return [
        trimesh.creation.box(extents=[1.0, 2.0, 3.0]),
        trimesh.creation.icosphere(subdivisions=3, radius=0.7),
        trimesh.creation.annulus(r_min=0.2, r_max=0.5, height=0.3),
        cloud,
        trimesh.Trimesh(rng.random((30, 3)), rng.integers(0, 30, (40, 3)), process=False),  # open, messy
    ]


@pytest.mark.parametrize("k", range(5))
def test_mass_properties_bit_identical_to_trimesh(k: int) -> None:
    mesh = _meshes()[k]
    positions, faces = np.asarray(mesh.vertices, np.float32), np.asarray(mesh.faces)
    ref = trimesh.Trimesh(positions, faces, process=False, validate=False)
    tris = surface.triangles(positions, faces)
    mine = surface.mass_properties(tris)
    with np.errstate(divide="ignore", invalid="ignore"):
        props = ref.mass_properties
    assert mine.volume == float(props["volume"])
    np.testing.assert_array_equal(mine.center_mass, props["center_mass"])
    np.testing.assert_array_equal(mine.inertia, props["inertia"])
    assert float(surface.face_areas(surface.crosses(tris)).sum()) == float(ref.area)
    assert surface.is_watertight(faces) == ref.is_watertight
    points = surface.sample_surface(positions, faces, 500, seed=3)
    expected, _ = trimesh.sample.sample_surface(ref, 500, seed=3)
    np.testing.assert_array_equal(points, expected)


def test_analytic_box() -> None:
    box = trimesh.creation.box(extents=[1.0, 2.0, 3.0])
    mine = surface.mass_properties(surface.triangles(box.vertices, box.faces))
    assert mine.volume == pytest.approx(6.0)
    np.testing.assert_allclose(mine.center_mass, 0.0, atol=1e-12)
    # solid cuboid: I_xx = m (b^2 + c^2) / 12 with m = volume at unit density
    np.testing.assert_allclose(np.diag(mine.inertia), [6 * 13 / 12, 6 * 10 / 12, 6 * 5 / 12], rtol=1e-12)
    assert surface.is_watertight(box.faces)
    assert not surface.is_watertight(box.faces[:-1])
    assert not surface.is_watertight(np.zeros((0, 3), dtype=np.int64))
