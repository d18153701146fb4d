"""Tessellated primitives: closed, outward, unit normals, and textures tiled as MuJoCo's renderer tiles them.

Ground truth for the tiling: MuJoCo's own renderer (EGL), a camera looking straight down on a black and
white checker (2 x 2 squares per image), counting the colour changes along one row of pixels.
"""

from __future__ import annotations

import numpy as np
import pytest

from simrun.export.tessellate import box, capsule, cylinder, plane, sphere

HALF = 1.0


def _mujoco_tiles(geom: str, repeat: float, uniform: bool) -> float:
    """Checker images MuJoCo draws across the 2 m wide top face of a plane or box of half size 1 m."""
    mujoco = pytest.importorskip("mujoco")
    xml = f"""<mujoco><asset>
      <texture name="c" type="2d" builtin="checker" width="256" height="256" rgb1="0 0 0" rgb2="1 1 1"/>
      <material name="m" texture="c" texrepeat="{repeat} {repeat}" texuniform="{str(uniform).lower()}"/></asset>
      <visual><headlight ambient="1 1 1" diffuse="0 0 0" specular="0 0 0"/></visual>
      <worldbody><geom type="{geom}" size="{HALF} {HALF} {HALF}" material="m"/>
      <camera name="top" pos="0 0 {2 * HALF if geom == "box" else HALF}" fovy="90"/></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    try:
        renderer = mujoco.Renderer(model, 400, 400)
    except Exception as exc:  # no GL here
        pytest.skip(f"MuJoCo cannot render here ({exc}); set MUJOCO_GL=egl")
    renderer.update_scene(data, "top")
    row = renderer.render()[200, :, 0] > 128
    renderer.close()
    changes = np.count_nonzero(np.diff(row.astype(int)))
    return (changes + 1) / 2  # two squares per image


@pytest.mark.parametrize("uniform", [False, True], ids=["per-face", "texuniform"])
@pytest.mark.parametrize("repeat", [1.0, 2.0, 6.0])
@pytest.mark.parametrize("kind", ["plane", "box"])
def test_textures_tile_as_mujoco_draws_them(kind: str, repeat: float, uniform: bool) -> None:
    half = np.full(3, HALF)
    surface = (plane if kind == "plane" else box)(half, np.array([repeat, repeat]), uniform)
    top = np.flatnonzero(surface.normals[:, 2] > 0.5)
    assert surface.uvs is not None
    tiles = np.ptp(surface.uvs[top, 0])  # images across the 2 m top face
    assert tiles == pytest.approx(_mujoco_tiles(kind, repeat, uniform), abs=0.5)


@pytest.mark.parametrize(
    "surface",
    [
        box(np.array([0.1, 0.2, 0.3]), np.ones(2), False),
        sphere(np.full(3, 0.2)),
        sphere(np.array([0.1, 0.2, 0.3])),
        capsule(0.05, 0.2),
        cylinder(0.1, 0.3),
    ],
    ids=["box", "sphere", "ellipsoid", "capsule", "cylinder"],
)
def test_primitives_face_outward_with_unit_normals(surface) -> None:  # type: ignore[no-untyped-def]
    np.testing.assert_allclose(np.linalg.norm(surface.normals, axis=1), 1.0, atol=1e-12)
    a, b, c = (surface.positions[surface.triangles[:, k]] for k in range(3))
    cross = np.cross(b - a, c - a)
    assert (np.linalg.norm(cross, axis=1) > 0).all()  # no zero-area triangle (the validator's hint)
    volume = np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6  # positive: faces wind outward
    centroid = (a + b + c) / 3
    assert volume > 0 and (np.einsum("ij,ij->i", cross, centroid) > -1e-12).all()
    assert surface.uvs is not None and surface.uvs.shape == (len(surface.positions), 2)
