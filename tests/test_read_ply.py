"""PLY reader: binary big-endian with vertex colours and uvs, ASCII quads with a texture file."""

from pathlib import Path

import numpy as np
import pytest

from meshtool.errors import FormatError
from meshtool.read.ply import read_ply
from meshtool.repair.normalise import NormaliseOptions, prepare

PLY = Path("formats") / "ply"
CUBE = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)


def test_big_endian_positions_colours_and_uvs(fixtures):
    data = (fixtures / PLY / "colored_big_endian.ply").read_bytes()
    assert b"binary_big_endian" in data[:40]
    mesh = read_ply(data, "scan.ply")
    np.testing.assert_allclose(mesh.positions, CUBE * [0.2, 0.1, 0.05], rtol=1e-7)
    np.testing.assert_array_equal(mesh.colors, CUBE)  # colour = corner position (255 -> 1)
    np.testing.assert_allclose(mesh.texcoords, CUBE[:, :2])
    assert mesh.record["encoding"] == "binary_big_endian" and mesh.face_sizes.size == 12


def test_big_endian_normalises_with_colours(fixtures):
    asset = prepare(fixtures / PLY / "colored_big_endian.ply", NormaliseOptions(up="z"))
    assert asset.stats["vertex_colors"] is True and asset.stats["triangles"] == 12
    assert asset.manifest["sources"][0]["role"] == "ply"


def test_ascii_quads_with_texture_file(fixtures):
    mesh = read_ply((fixtures / PLY / "textured_quads_ascii.ply").read_bytes(), "q.ply")
    assert mesh.face_sizes.size == 12  # six quads
    assert mesh.face_lines.tolist() == sorted(mesh.face_lines.tolist()) and set(mesh.face_lines.tolist()) == set(
        range(1, 7)
    )
    assert mesh.materials[0].maps["map_Kd"].file == "checker.png"
    asset = prepare(fixtures / PLY / "textured_quads_ascii.ply")
    assert asset.stats["textures"] == 1 and list(asset.textures) == ["checker.png"]
    assert {s["role"] for s in asset.manifest["sources"]} == {"ply", "texture"}


def test_not_ply_and_damaged_ply_are_one_error():
    with pytest.raises(FormatError, match="not a PLY file"):
        read_ply(b"solid x", "x.ply")
    with pytest.raises(FormatError, match="no 'end_header'"):
        read_ply(b"ply\nformat ascii 1.0\n", "x.ply")
    bad = b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nend_header\n1\n"
    with pytest.raises(FormatError):
        read_ply(bad, "x.ply")
