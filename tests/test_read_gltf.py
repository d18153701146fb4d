"""glTF/GLB reader: node transforms baked, embedded and external files through the resolver, containment,
KHR_texture_transform, compression refused, damaged files."""

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from meshtool.cli.main import main
from meshtool.errors import FormatError
from meshtool.files.resolve import Resolver
from meshtool.read.gltf import read_gltf
from meshtool.repair.normalise import NormaliseOptions, prepare

GLTF = Path("formats") / "gltf"


def read(path: Path):
    return read_gltf(path.read_bytes(), path.name, path, Resolver(path.parent))


def signed_volume(positions, faces):
    p = positions[faces]
    return float(np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6.0)


def test_glb_node_transforms_are_baked(fixtures):
    mesh = read(fixtures / GLTF / "embedded_texture.glb")
    # box [0,0.4]x[0,0.2]x[0,0.1], rotated 90 degrees about +Y ((x,y,z) -> (z,y,-x)), then moved by (1, 0.5, 0)
    np.testing.assert_allclose(mesh.positions.min(axis=0), [1.0, 0.5, -0.4], atol=1e-6)
    np.testing.assert_allclose(mesh.positions.max(axis=0), [1.1, 0.7, 0.0], atol=1e-6)
    faces = mesh.corner_v.reshape(-1, 3)
    assert signed_volume(mesh.positions, faces) == pytest.approx(0.4 * 0.2 * 0.1, rel=1e-5)
    assert mesh.part_names == ["crate"] and mesh.location == "triangle"
    # normals rotated with the node: the +x side of the box now faces -z
    assert np.isclose(mesh.normals, [0, 0, -1], atol=1e-6).all(axis=1).any()


def test_glb_texture_transform_baked_and_v_flipped(fixtures):
    mesh = read(fixtures / GLTF / "embedded_texture.glb")
    # glTF uvs in {0, 1}; KHR_texture_transform offset (0.5, 0), scale (2, 2): u' = 2u + 0.5, v' = 2v; OBJ v = 1 - v'
    assert set(np.round(mesh.texcoords[:, 0], 6)) == {0.5, 2.5}
    assert set(np.round(mesh.texcoords[:, 1], 6)) == {1.0, -1.0}
    assert "gltf-texture-transform" in [f.code for f in mesh.findings]


def test_glb_embedded_texture_becomes_a_png_with_provenance(fixtures):
    asset = prepare(fixtures / GLTF / "embedded_texture.glb")
    assert list(asset.textures) == ["checker.png"]
    assert asset.textures["checker.png"][:8] == b"\x89PNG\r\n\x1a\n"
    sources = {s["role"]: s["path"] for s in asset.manifest["sources"]}
    assert sources == {"glb": "embedded_texture.glb", "texture": "embedded_texture.glb/checker.png"}
    rules = [r["rule"] for r in asset.manifest["resolutions"]]
    assert rules == ["embedded"]
    t = asset.manifest["transform"]
    assert (t["units"], t["up"], t["up_rule"]) == ("m", "y", "format")
    # Y-up to Z-up: (x, y, z) -> (x, -z, y)
    np.testing.assert_allclose(asset.mesh.positions.min(axis=0), [1.0, 0.0, 0.5], atol=1e-6)
    np.testing.assert_allclose(asset.mesh.positions.max(axis=0), [1.1, 0.4, 0.7], atol=1e-6)
    material = asset.materials[0]
    assert material.name == "red_checker" and material.scalars["Pr"] == 0.5 and material.scalars["Pm"] == 0.0


def test_external_buffer_and_image_are_read_through_the_resolver(fixtures):
    asset = prepare(fixtures / GLTF / "external" / "cube.gltf")
    roles = {s["role"]: s["path"] for s in asset.manifest["sources"]}
    assert roles == {"gltf": "cube.gltf", "buffer": "cube.bin", "texture": "textures/wood grain.png"}
    assert asset.stats["triangles"] == 12 and list(asset.textures) == ["wood_grain.png"]


def test_buffer_outside_the_folder_is_refused(fixtures, tmp_path):
    src = fixtures / GLTF / "escape" / "model" / "escape.gltf"
    with pytest.raises(FormatError) as err:
        prepare(src)
    assert err.value.code == "gltf-buffer-missing" and "outside the asset folder" in err.value.message
    result = CliRunner().invoke(main, ["normalize", str(src), "-o", str(tmp_path)])
    assert result.exit_code == 1
    assert result.stderr.strip().splitlines() == [
        "error: escape.gltf: buffer 0 '../outside.bin' is outside the asset folder; the geometry cannot be read "
        "without it (add its folder with --search-path)"
    ]
    # allowed explicitly, it is read
    asset = prepare(src, NormaliseOptions(search_paths=(src.parent.parent,)))
    assert asset.stats["triangles"] == 12


def test_missing_buffer_is_one_error(fixtures, tmp_path):
    folder = tmp_path / "m"
    shutil.copytree(fixtures / GLTF / "external", folder)
    (folder / "cube.bin").unlink()
    with pytest.raises(FormatError, match=r"buffer 0 'cube\.bin' was not found") as err:
        prepare(folder / "cube.gltf")
    assert err.value.code == "gltf-buffer-missing"


def test_draco_is_refused_with_a_clear_error(fixtures, tmp_path):
    src = fixtures / GLTF / "draco_required.gltf"
    with pytest.raises(FormatError) as err:
        prepare(src)
    assert err.value.code == "gltf-compressed" and "Draco" in err.value.message
    result = CliRunner().invoke(main, ["normalize", str(src), "-o", str(tmp_path)])
    assert result.exit_code == 1 and len(result.stderr.strip().splitlines()) == 1


def test_mirroring_node_keeps_faces_outward(fixtures, tmp_path):
    folder = tmp_path / "mirror"
    shutil.copytree(fixtures / GLTF / "external", folder)
    doc = json.loads((folder / "cube.gltf").read_text())
    doc["nodes"][0]["scale"] = [-1.0, 1.0, 1.0]
    (folder / "cube.gltf").write_text(json.dumps(doc))
    mesh = read(folder / "cube.gltf")
    np.testing.assert_allclose(mesh.positions.min(axis=0), [-0.5, 0, 0], atol=1e-6)
    assert signed_volume(mesh.positions, mesh.corner_v.reshape(-1, 3)) == pytest.approx(0.125, rel=1e-5)


def test_strips_fans_and_points(fixtures, tmp_path):
    folder = tmp_path / "modes"
    shutil.copytree(fixtures / GLTF / "external", folder)
    doc = json.loads((folder / "cube.gltf").read_text())
    prim = doc["meshes"][0]["primitives"][0]
    strip = dict(prim, mode=5)
    points = dict(prim, mode=0)
    doc["meshes"][0]["primitives"] = [strip, points]
    (folder / "cube.gltf").write_text(json.dumps(doc))
    mesh = read(folder / "cube.gltf")
    assert mesh.face_sizes.size == 36 - 2  # a strip of 36 indices makes 34 triangles
    assert "points-skipped" in [f.code for f in mesh.findings]


@pytest.mark.parametrize(
    ("data", "message"),
    [
        (b"glTF\x01\x00\x00\x00" + bytes(12), "GLB version 1"),
        (b'{"asset": {"version": "1.0"}}', "only glTF 2.0"),
        (b"{not json", "glTF JSON cannot be read"),
        (b'{"asset": {"version": "2.0"}, "scenes": [{"nodes": [5]}], "nodes": []}', "node 5 is missing"),
    ],
)
def test_damaged_files_are_one_error(tmp_path, data, message):
    path = tmp_path / "bad.gltf"
    path.write_bytes(data)
    with pytest.raises(FormatError, match=message):
        read(path)


def test_accessor_past_its_view_is_an_error(fixtures, tmp_path):
    folder = tmp_path / "acc"
    shutil.copytree(fixtures / GLTF / "external", folder)
    doc = json.loads((folder / "cube.gltf").read_text())
    doc["accessors"][0]["count"] = 10_000
    (folder / "cube.gltf").write_text(json.dumps(doc))
    with pytest.raises(FormatError, match="runs past its bufferView"):
        read(folder / "cube.gltf")


@pytest.mark.parametrize(
    "change",
    [
        lambda doc: doc["accessors"][0].update(count="many"),
        lambda doc: doc["nodes"][0].update(mesh="zero"),
        lambda doc: doc["meshes"][0]["primitives"][0].update(indices=99),
        lambda doc: doc["accessors"][0].update(componentType=1),
        lambda doc: doc["accessors"].__setitem__(0, {"componentType": 5126, "count": 10**12, "type": "VEC3"}),
        lambda doc: doc.update(nodes={"0": {}}),
    ],
)
def test_hostile_json_values_are_one_error(fixtures, tmp_path, change):
    folder = tmp_path / "h"
    shutil.copytree(fixtures / GLTF / "external", folder)
    doc = json.loads((folder / "cube.gltf").read_text())
    change(doc)
    (folder / "cube.gltf").write_text(json.dumps(doc))
    with pytest.raises(FormatError):
        read(folder / "cube.gltf")


def test_deeply_nested_json_is_one_error(tmp_path):
    path = tmp_path / "deep.gltf"
    path.write_text('{"asset": ' + "[" * 100_000 + "]" * 100_000 + "}")
    with pytest.raises(FormatError, match="glTF JSON cannot be read"):
        read(path)
