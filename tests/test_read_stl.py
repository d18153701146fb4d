"""STL reader: binary with a 'solid' header, multi-solid ASCII, facet normals against the winding, damage."""

import struct
from pathlib import Path

import numpy as np
import pytest

from meshtool.errors import FormatError
from meshtool.read.stl import read_stl
from meshtool.repair.normalise import NormaliseOptions, prepare

STL = Path("formats") / "stl"
CUBE = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)


def signed_volume(positions, faces):
    p = positions[faces]
    return float(np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6.0)


def test_binary_with_solid_header_is_read_as_binary(fixtures):
    data = (fixtures / STL / "solid_header_binary.stl").read_bytes()
    assert data.startswith(b"solid")
    mesh = read_stl(data, "part.stl")
    assert mesh.record["encoding"] == "binary" and mesh.record["facets"] == 12
    assert mesh.positions.shape == (8, 3)  # 36 corners merged into the 8 box corners
    assert {tuple(p) for p in mesh.positions} == {tuple(p) for p in CUBE * [40, 30, 20]}
    assert mesh.location == "facet" and mesh.face_lines.tolist() == list(range(1, 13))
    assert "stl-binary-solid-header" in [f.code for f in mesh.findings]
    faces = mesh.corner_v.reshape(-1, 3)
    assert signed_volume(mesh.positions, faces) == pytest.approx(40 * 30 * 20)


def test_binary_stl_normalised_in_mm_stays_z_up(fixtures):
    asset = prepare(fixtures / STL / "solid_header_binary.stl", NormaliseOptions(units="mm"))
    lo, hi = asset.mesh.positions.min(axis=0), asset.mesh.positions.max(axis=0)
    np.testing.assert_allclose(hi - lo, [0.04, 0.03, 0.02])
    assert asset.manifest["transform"]["up"] == "z" and asset.manifest["transform"]["up_rule"] == "format"
    assert asset.manifest["sources"][0]["role"] == "stl"


def test_stl_without_unit_suggests_millimetres(fixtures):
    asset = prepare(fixtures / STL / "solid_header_binary.stl")
    codes = {f.code: f for f in asset.findings}
    assert "pass --units mm (0.04 m)" in codes["stl-units"].message
    assert "--units mm" in codes["scale-suspicious"].message
    assert asset.manifest["transform"]["units_evidence"].startswith("mm from STL without unit")


def test_ascii_with_two_solids_gives_two_parts(fixtures):
    mesh = read_stl((fixtures / STL / "two_solids_ascii.stl").read_bytes(), "two.stl")
    assert mesh.part_names == ["base", "post"]
    assert mesh.face_part.tolist() == [0] * 12 + [1] * 12
    assert mesh.positions.shape == (16, 3)
    assert mesh.location == "line" and mesh.face_lines[0] == 2 and mesh.face_lines[12] == 2 + 7 * 12 + 2
    asset = prepare(fixtures / STL / "two_solids_ascii.stl", NormaliseOptions(units="mm"))
    np.testing.assert_allclose(asset.mesh.positions.max(axis=0), [0.1, 0.1, 0.06])
    assert asset.stats["parts"] == 2


def test_facet_normals_against_the_winding_are_reported(fixtures):
    mesh = read_stl((fixtures / STL / "flipped_normals.stl").read_bytes(), "flip.stl")
    found = [f for f in mesh.findings if f.code == "stl-normals-disagree"]
    assert len(found) == 1 and found[0].message.startswith("2 facet normal(s)")
    assert found[0].line == 2 + 7 * 2  # the third facet's line
    faces = mesh.corner_v.reshape(-1, 3)
    assert signed_volume(mesh.positions, faces) == pytest.approx(20**3)  # the winding is kept


def test_truncated_binary_is_one_error_with_offset():
    data = b"binary header".ljust(80) + struct.pack("<I", 3) + bytes(50 * 2)
    with pytest.raises(FormatError) as err:
        read_stl(data, "cut.stl")
    assert (
        err.value.offset == 84 + 100 and "truncated" in err.value.message and "2 complete facets" in err.value.message
    )


def test_trailing_bytes_after_binary_facets_are_a_warning():
    tri = struct.pack("<12fH", 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0)
    data = b"x".ljust(80) + struct.pack("<I", 1) + tri + b"garbage"
    mesh = read_stl(data, "t.stl")
    assert mesh.positions.shape == (3, 3) and "stl-trailing-data" in [f.code for f in mesh.findings]


def test_ascii_errors_name_the_line():
    text = b"solid a\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 1 x 0\n   vertex 0 1 0\n"
    with pytest.raises(FormatError) as err:
        read_stl(text, "bad.stl")
    assert err.value.line == 5 and "'x' is not a number" in err.value.message
    with pytest.raises(FormatError) as err:
        read_stl(b"solid a\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n  endloop\n", "short.stl")
    assert err.value.line == 3 and "1 vertices" in err.value.message
    with pytest.raises(FormatError, match="not an STL file"):
        read_stl(b"hello", "tiny.stl")


def test_ascii_without_endsolid_keeps_the_geometry():
    text = b"solid a\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n"
    mesh = read_stl(text, "open.stl")
    assert mesh.corner_v.size == 3 and "stl-endsolid-missing" in [f.code for f in mesh.findings]


def _binary_box_stl(path: Path, size: tuple[float, float, float]) -> None:
    """A binary STL box of ``size`` (no unit, as STL never has one): 80-byte header, count, 12 facets."""
    corners = CUBE * size
    quads = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (2, 3, 7, 6), (1, 2, 6, 5), (0, 4, 7, 3)]
    tris = [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))]
    body = b"".join(struct.pack("<12fH", 0, 0, 0, *corners[list(t)].ravel(), 0) for t in tris)
    path.write_bytes(b"\0" * 80 + struct.pack("<I", len(tris)) + body)


def test_cad_sized_stl_gets_the_same_millimetre_suggestion_with_units_auto(tmp_path):
    """100 x 200 x 300 with no unit: millimetres (0.3 m), whether --units is left out or auto."""
    src = tmp_path / "bracket.stl"
    _binary_box_stl(src, (100, 200, 300))
    messages = {}
    for units in (None, "auto"):
        asset = prepare(src, NormaliseOptions(units=units))
        found = {f.code: f.message for f in asset.findings}
        assert "pass --units mm (0.3 m)" in found["stl-units"]
        assert asset.manifest["transform"]["units_evidence"].startswith("mm from STL without unit")
        messages[units] = found["scale-suspicious"]
    assert messages[None] == messages["auto"]
    assert messages[None].endswith("(0.3 m): pass --units mm") and "--units cm" not in messages[None]
