"""COLLADA reader: <unit> and <up_axis> honoured, node transforms, materials and textures through the resolver."""

import shutil
from pathlib import Path

import numpy as np
import pytest

from meshtool.errors import FormatError
from meshtool.read.collada import read_collada
from meshtool.repair.normalise import NormaliseOptions, prepare

DAE = Path("formats") / "dae" / "cm_zup" / "link_cm_zup.dae"


def test_unit_up_axis_and_node_matrix(fixtures):
    mesh = read_collada((fixtures / DAE).read_bytes(), "link.dae")
    assert mesh.frame.unit_m == 0.01 and mesh.frame.up == "z"
    # a 20 x 10 x 5 cm box moved +10 cm along z by the node's matrix
    np.testing.assert_allclose(mesh.positions.min(axis=0), [0, 0, 10])
    np.testing.assert_allclose(mesh.positions.max(axis=0), [20, 10, 15])
    assert mesh.positions.shape == (8, 3)  # corners split per attribute are welded back
    assert mesh.part_names == ["block"]


def test_centimetres_z_up_normalise_to_metres_without_rotation(fixtures):
    asset = prepare(fixtures / DAE)
    t = asset.manifest["transform"]
    assert (t["units"], t["up"], t["up_rule"]) == ("cm", "z", "format")
    assert t["up_evidence"] == "COLLADA <up_axis>Z_UP</up_axis>"
    assert t["units_evidence"] == 'cm from COLLADA <unit meter="0.01" name="centimeter"/>'
    np.testing.assert_allclose(asset.mesh.positions.min(axis=0), [0, 0, 0.1])
    np.testing.assert_allclose(asset.mesh.positions.max(axis=0), [0.2, 0.1, 0.15])
    assert not [f for f in asset.findings if f.code == "scale-suspicious"]


def test_materials_colour_and_texture_kept(fixtures):
    asset = prepare(fixtures / DAE)
    by_name = {m.name: m for m in asset.materials}
    assert set(by_name) == {"red", "paint"}
    assert by_name["red"].colors["Kd"] == pytest.approx((0.8, 0.1, 0.1))
    assert by_name["red"].scalars["Ns"] == 20.0
    assert by_name["paint"].maps["map_Kd"].file == "paint.png"
    assert asset.textures["paint.png"][:8] == b"\x89PNG\r\n\x1a\n"
    counts = np.bincount(asset.mesh.face_material)
    assert counts.tolist() == [6, 6]
    assert asset.stats["texcoords"] > 0


def test_user_units_override_the_declared_unit(fixtures):
    asset = prepare(fixtures / DAE, NormaliseOptions(units="mm", up="y"))
    t = asset.manifest["transform"]
    assert (t["units"], t["up"], t["up_rule"]) == ("mm", "y", "forced")


def test_missing_texture_keeps_geometry(fixtures, tmp_path):
    folder = tmp_path / "link"
    shutil.copytree((fixtures / DAE).parent, folder)
    (folder / "textures" / "paint.png").unlink()
    asset = prepare(folder / DAE.name)
    assert asset.stats["triangles"] == 12 and asset.stats["textures"] == 0
    assert "texture-missing" in [f.code for f in asset.findings]


def test_x_up_is_turned_to_y_up(fixtures, tmp_path):
    text = (fixtures / DAE).read_text().replace("<up_axis>Z_UP</up_axis>", "<up_axis>X_UP</up_axis>")
    mesh = read_collada(text.encode(), "x.dae")
    # (x, y, z) -> (-y, x, z): the box's 20 cm x extent becomes the y (up) extent
    np.testing.assert_allclose(mesh.positions.min(axis=0), [-10, 0, 10])
    np.testing.assert_allclose(mesh.positions.max(axis=0), [0, 20, 15])
    assert mesh.frame.up == "y"


def test_damaged_collada_is_one_error():
    with pytest.raises(FormatError, match="COLLADA cannot be read"):
        read_collada(b"<COLLADA><unclosed>", "bad.dae")


def test_entities_are_refused_before_parsing(fixtures, tmp_path):
    secret = tmp_path / "secret.txt"
    secret.write_text("0 0 0 1 1 1")
    text = (fixtures / DAE).read_text()
    text = text.replace(
        '<?xml version="1.0" encoding="utf-8"?>',
        f'<?xml version="1.0" encoding="utf-8"?>\n<!DOCTYPE c [<!ENTITY leak SYSTEM "file://{secret}">]>',
    )
    with pytest.raises(FormatError, match="DOCTYPE or ENTITY"):
        read_collada(text.encode(), "xxe.dae")


def test_index_past_its_source_is_one_error(fixtures):
    text = (fixtures / DAE).read_text().replace("<p>0 0 0", "<p>99 0 0", 1)
    with pytest.raises(FormatError, match="COLLADA"):
        read_collada(text.encode(), "bad.dae")


def test_zipped_collada_is_refused(fixtures):
    import io
    import zipfile

    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as z:
        z.writestr("link.dae", (fixtures / DAE).read_bytes())
    with pytest.raises(FormatError, match="zipped COLLADA"):
        read_collada(buffer.getvalue(), "link.dae")
