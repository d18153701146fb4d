"""meshtool urdf reads every mesh format through the readers: no OBJ text, DAE/glTF materials kept."""

import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest
import trimesh

import meshtool.export.obj_write
from meshtool.packfile.read import parse
from meshtool.urdf.import_robot import import_urdf

QUIRKS = Path("urdf") / "quirks" / "quirks_robot" / "urdf" / "quirks.urdf"

ROBOT = """<?xml version="1.0"?>
<robot name="formats">
  <link name="base">
    <visual><geometry><mesh filename="package://formats_robot/meshes/link/link_cm_zup.dae"/></geometry></visual>
  </link>
  <link name="arm">
    <visual><geometry><mesh filename="package://formats_robot/meshes/cube/cube.gltf" scale="-1 1 1"/></geometry>
    </visual>
  </link>
  <joint name="j" type="revolute">
    <parent link="base"/><child link="arm"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/>
  </joint>
</robot>
"""


def _forbid(*args, **kwargs):
    raise AssertionError("the URDF importer must not write OBJ text or scratch folders")


def test_no_obj_text_and_dae_materials_kept(fixtures, monkeypatch):
    monkeypatch.setattr(tempfile, "TemporaryDirectory", _forbid)
    monkeypatch.setattr(tempfile, "mkdtemp", _forbid)
    monkeypatch.setattr(meshtool.export.obj_write, "format_obj", _forbid)
    monkeypatch.setattr(trimesh.exchange.obj, "export_obj", _forbid)
    result = import_urdf(fixtures / QUIRKS)
    painted = parse(result.mbins["meshes/painted.mbin"], "painted")
    by_name = {m["name"]: m for m in painted.materials}
    assert by_name["red"]["colors"]["Kd"] == pytest.approx([0.8, 0.1, 0.1])
    assert "texture-missing" in [f.code for f in result.findings]  # the broken image: geometry kept


@pytest.fixture
def robot(fixtures, tmp_path):
    root = tmp_path / "formats_robot"
    (root / "urdf").mkdir(parents=True)
    (root / "package.xml").write_text("<package><name>formats_robot</name></package>\n")
    shutil.copytree(fixtures / "formats" / "dae" / "cm_zup", root / "meshes" / "link")
    shutil.copytree(fixtures / "formats" / "gltf" / "external", root / "meshes" / "cube")
    (root / "urdf" / "robot.urdf").write_text(ROBOT)
    return root / "urdf" / "robot.urdf"


def test_collada_unit_and_texture_through_urdf(robot):
    result = import_urdf(robot)
    link = parse(result.mbins["meshes/link_cm_zup.mbin"], "link")
    positions = np.asarray(link.positions, float)
    # the COLLADA unit (cm) is applied, its Z_UP frame kept: 20 x 10 x 5 cm at z 10..15 cm
    np.testing.assert_allclose(positions.max(axis=0) - positions.min(axis=0), [0.2, 0.1, 0.05], atol=1e-6)
    np.testing.assert_allclose(positions.min(axis=0), [0, 0, 0.1], atol=1e-6)
    assert {m["name"] for m in link.materials} == {"red", "paint"} and len(link.textures) == 1


def test_mirrored_gltf_keeps_outward_faces_and_normals(robot):
    result = import_urdf(robot)
    cube = parse(result.mbins["meshes/cube.mbin"], "cube")
    mesh = trimesh.Trimesh(np.asarray(cube.positions, float), np.asarray(cube.indices), process=False)
    assert mesh.volume == pytest.approx(0.125, rel=1e-5)  # counter-clockwise from outside after the mirror
    normals = np.asarray(cube.normals, float)
    centre = mesh.vertices.mean(axis=0)
    assert (np.einsum("ij,ij->i", normals, mesh.vertices - centre) > 0).all()
    assert len(cube.textures) == 1
