"""Issue 16: real-world assets come out as authored (fixtures in fixtures/realworld/)."""

from __future__ import annotations

import io
import json
import shutil
from pathlib import Path

import mujoco
import numpy as np
import pytest
from click.testing import CliRunner

from meshtool.cli.main import main
from meshtool.errors import StrictModeError
from meshtool.frame.consumers import find_consumers
from meshtool.frame.modelroot import find_model_root
from meshtool.packfile import load
from meshtool.pipeline import ConvertOptions, convert
from meshtool.read.obj.mtl import parse_mtl, texture_colorspace
from meshtool.read.obj.parse import parse_obj
from meshtool.repair.normalise import NormaliseOptions, normalise

RW = Path(__file__).resolve().parent.parent / "fixtures" / "realworld"


def codes(asset: object) -> list[str]:
    return [f.code for f in asset.findings]  # type: ignore[attr-defined]


def transform(asset: object) -> dict[str, object]:
    return asset.manifest["transform"]  # type: ignore[attr-defined,no-any-return]


# -- materials ----------------------------------------------------------------------------------------------


def test_meshlab_tr_1_is_opaque():
    asset = normalise(RW / "meshlab_tr" / "fuze.obj")
    (material,) = asset.materials
    assert material.scalars["d"] == 1.0
    assert "material-invisible" not in codes(asset)
    (note,) = [f for f in asset.findings if f.code == "mtl-tr-converted"]
    assert "MeshLab" in note.message
    assert b"\nd 1\n" in asset.files["fuze.mtl"] and asset.stats["textures"] == 1


def test_spec_tr_still_means_transparency():
    (m,) = parse_mtl(b"newmtl glass\nTr 0.25\n", "glass.mtl").materials
    assert m.scalars["d"] == 0.75


def test_invisible_used_material_becomes_opaque_with_a_warning():
    asset = normalise(RW / "tr_invisible" / "capsule.obj")
    (material,) = asset.materials
    assert material.scalars["d"] == 1.0
    (warn,) = [f for f in asset.findings if f.code == "material-invisible"]
    assert warn.severity.value == "warning" and "material0" in warn.message
    with pytest.raises(StrictModeError):
        normalise(RW / "tr_invisible" / "capsule.obj", NormaliseOptions(strict=True))


def test_normal_bump_and_data_maps_are_kept_in_mtl_and_mbin(tmp_path):
    asset = normalise(RW / "normal_maps" / "tile.obj")
    (material,) = asset.materials
    assert set(material.maps) == {"map_Kd", "bump", "norm", "disp", "map_Pr"}
    assert material.maps["bump"].options == {"-bm": ("0.5",)}
    mtl = asset.files["tile.mtl"].decode()
    for line in ("map_Kd tile_albedo.png", "bump -bm 0.5 tile_bump.png", "norm tile_normal.png", "disp tile_disp.png"):
        assert line in mtl
    assert len(asset.textures) == 5
    convert(RW / "normal_maps" / "tile.obj", tmp_path / "tile.mbin", ConvertOptions())
    with load(tmp_path / "tile.mbin") as packed:
        (record,) = packed.materials
        assert set(record["maps"]) == {"map_Kd", "bump", "norm", "disp", "map_Pr"}
        assert len(packed.textures) == 5


def test_colour_maps_are_srgb_and_data_maps_linear():
    assert [texture_colorspace(k) for k in ("map_Kd", "map_Ka", "map_Ks", "map_Ke")] == ["sRGB"] * 4
    assert [texture_colorspace(k) for k in ("bump", "norm", "disp", "map_d", "map_Pr", "map_Ns")] == ["linear"] * 6


# -- trailing comments --------------------------------------------------------------------------------------


def test_trailing_comments_parse_in_mtl():
    mtl = parse_mtl((RW / "inline_comments" / "commented.mtl").read_bytes(), "commented.mtl")
    white, numbered = mtl.materials
    assert white.name == "white" and numbered.name == "Material #25"
    assert white.colors["Kd"] == (1.0, 1.0, 1.0)
    assert white.scalars == {"d": 1.0, "Ns": 10.0} and white.illum == 2
    assert white.maps["map_Kd"].file == "dots.png"
    assert not [f for f in mtl.findings if f.severity.value == "warning"]


def test_trailing_comments_parse_in_obj():
    obj = parse_obj((RW / "inline_comments" / "commented.obj").read_bytes(), "commented.obj")
    assert [r.name for r in obj.mtllibs] == ["commented.mtl"]
    assert obj.material_names == ["white", "Material #25"]
    assert "thing" in obj.part_names
    asset = normalise(RW / "inline_comments" / "commented.obj")
    assert [m.colors["Kd"] for m in asset.materials] == [(1.0, 1.0, 1.0), (0.2, 0.4, 0.6)]
    assert asset.stats["textures"] == 1 and asset.stats["triangles"] == 4
    assert not [f for f in asset.findings if f.severity.value == "warning" and f.code != "up-axis"]


# -- up axis ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("path", "up", "rule"),
    [
        ("flat_ground/floor.obj", "z", "flat"),
        ("flat_ground/terrain.obj", "z", "ground"),
        ("flat_ground/cloth_z_up.obj", "z", "name"),
        ("gazebo_model/crate/meshes/crate.obj", "z", "consumer"),
        ("ros_package/arm_description/meshes/link.obj", "z", "consumer"),
        ("mjcf_beside/assets/palm.obj", "z", "consumer"),
        ("meshlab_tr/fuze.obj", "y", "default"),
    ],
)
def test_up_auto_decides_from_evidence_and_records_it(path, up, rule):
    asset = normalise(RW / path)
    t = transform(asset)
    assert (t["up"], t["up_rule"]) == (up, rule)
    (finding,) = [f for f in asset.findings if f.code == "up-axis"]
    assert str(t["up_evidence"]) in finding.message
    assert "up-axis" in [f["code"] for f in asset.manifest["findings"]]


def test_a_z_up_floor_stays_a_floor_and_up_y_still_forces():
    auto = normalise(RW / "flat_ground" / "floor.obj").stats["bbox"]["extent"]
    assert auto[2] == 0.0 and auto[0] == auto[1] == pytest.approx(10.9)
    forced = normalise(RW / "flat_ground" / "floor.obj", NormaliseOptions(up="y"))
    assert forced.stats["bbox"]["extent"][1] == 0.0 and transform(forced)["up_rule"] == "forced"
    assert "up-axis" not in codes(forced)


def test_exporter_header_says_y_up():
    asset = normalise(Path(__file__).resolve().parent.parent / "fixtures" / "head" / "Head 1.obj")
    assert (transform(asset)["up"], transform(asset)["up_rule"]) == ("y", "exporter")


# -- units --------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("path", "unit", "consumer", "extent"),
    [
        ("gazebo_model/crate/meshes/crate.obj", "cm", "../model.sdf", [0.5, 0.4, 0.3]),
        ("ros_package/arm_description/meshes/link.obj", "mm", "../urdf/arm.urdf", [0.06, 0.06, 0.24]),
        ("mjcf_beside/assets/palm.obj", "mm", "../hand.xml", [0.09, 0.02, 0.1]),
    ],
)
def test_units_from_consumer_files(path, unit, consumer, extent):
    default = normalise(RW / path)
    (warn,) = [f for f in default.findings if f.code == "units-evidence"]
    assert warn.severity.value == "warning" and consumer in warn.message and f"--units {unit}" in warn.message
    (suspicious,) = [f for f in default.findings if f.code == "scale-suspicious"]
    assert f"pass --units {unit}" in suspicious.message and consumer in suspicious.message
    auto = normalise(RW / path, NormaliseOptions(units="auto"))
    assert transform(auto)["units"] == unit
    np.testing.assert_allclose(auto.stats["bbox"]["extent"], extent, rtol=1e-12)
    assert "scale-suspicious" not in codes(auto)
    (agrees,) = [f for f in auto.findings if f.code == "units-evidence"]
    assert agrees.severity.value == "warning"  # --units auto scaled every vertex (issue 31)


def test_units_auto_without_evidence_is_metres():
    auto = normalise(RW / "meshlab_tr" / "fuze.obj", NormaliseOptions(units="auto"))
    assert transform(auto)["units"] == "m" and "units-evidence" not in codes(auto)


def test_consumer_with_a_non_unit_scale(tmp_path):
    (tmp_path / "assets").mkdir()
    shutil.copy(RW / "mjcf_beside" / "assets" / "palm.obj", tmp_path / "assets" / "palm.obj")
    (tmp_path / "scene.xml").write_text(
        '<mujoco><asset><mesh file="assets/palm.obj" scale="0.1 0.1 0.1"/></asset></mujoco>'
    )
    (ref,) = find_consumers(tmp_path / "assets" / "palm.obj", None)
    assert ref.scale == (0.1, 0.1, 0.1) and ref.format == "mjcf" and ref.file == "../scene.xml"
    auto = normalise(tmp_path / "assets" / "palm.obj", NormaliseOptions(units="auto"))
    assert transform(auto)["units"] == "m" and transform(auto)["scale"] == 0.1


def test_consumer_files_with_entities_are_not_read(tmp_path):
    (tmp_path / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\n")
    (tmp_path / "bomb.urdf").write_text(
        '<?xml version="1.0"?><!DOCTYPE r [<!ENTITY a "aaaa">]><robot><link><visual><geometry>'
        '<mesh filename="m.obj" scale="0.001 0.001 0.001"/></geometry></visual></link></robot>'
    )
    assert find_consumers(tmp_path / "m.obj", find_model_root(tmp_path)) == []


# -- model roots --------------------------------------------------------------------------------------------


def test_gazebo_model_texture_resolves_inside_the_model_root():
    asset = normalise(RW / "gazebo_model" / "crate" / "meshes" / "crate.obj")
    assert asset.stats["textures"] == 1
    (root,) = [f for f in asset.findings if f.code == "model-root"]
    assert "model.config" in root.message
    (res,) = [r for r in asset.manifest["resolutions"] if r["kind"] == "texture"]
    assert res["found"] == "../materials/textures/crate.png" and res["rule"] == "exact"
    assert {"role": "texture", "path": "../materials/textures/crate.png"}.items() <= asset.manifest["sources"][
        -1
    ].items()


def test_without_a_model_root_the_texture_stays_out_of_reach(tmp_path):
    model = tmp_path / "models" / "crate"
    shutil.copytree(RW / "gazebo_model" / "crate", model)
    (model / "model.config").unlink()
    (model / "model.sdf").unlink()
    asset = normalise(model / "meshes" / "crate.obj")
    assert asset.stats["textures"] == 0
    assert "reference-outside-root" in codes(asset) and "model-root" not in codes(asset)


def test_references_never_leave_the_model_root(tmp_path):
    root = tmp_path / "models" / "crate"
    shutil.copytree(RW / "gazebo_model" / "crate", root)
    (tmp_path / "models" / "secret.png").write_bytes((root / "materials" / "textures" / "crate.png").read_bytes())
    (root / "meshes" / "crate.mtl").write_text("newmtl crate\nKd 1 1 1\nmap_Kd ../../secret.png\n")
    asset = normalise(root / "meshes" / "crate.obj")
    assert asset.stats["textures"] == 0 and "reference-outside-root" in codes(asset)
    allowed = normalise(root / "meshes" / "crate.obj", NormaliseOptions(search_paths=(tmp_path / "models",)))
    assert allowed.stats["textures"] == 1


def test_a_marker_in_the_temporary_folder_opens_nothing(tmp_path, monkeypatch):
    monkeypatch.setattr("tempfile.tempdir", str(tmp_path))
    (tmp_path / "package.xml").write_text("<package/>")
    (tmp_path / "asset").mkdir()
    assert find_model_root(tmp_path / "asset") is None


# -- parts MuJoCo refuses -----------------------------------------------------------------------------------


def _compile_submeshes(packed_path: Path) -> int:
    """Compile every visual submesh of an .mbin as its own MuJoCo mesh (as MJCF writes them)."""
    with load(packed_path) as packed:
        spec = mujoco.MjSpec()
        body = spec.worldbody.add_body(name="b")
        positions = np.asarray(packed.positions, dtype=np.float64)
        indices = np.asarray(packed.indices, dtype=np.int64)
        rows = np.asarray(packed.submeshes, dtype=np.int64).tolist()
        for k, (first, count, _material, _part) in enumerate(rows):
            faces = indices[first : first + count]
            used, inverse = np.unique(faces, return_inverse=True)
            mesh = spec.add_mesh(name=f"m{k}")
            mesh.uservert = positions[used].ravel().tolist()
            mesh.userface = inverse.ravel().tolist()
            mesh.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL
            body.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname=f"m{k}", contype=0, conaffinity=0, mass=0)
        spec.compile()
        return len(rows)


def test_one_triangle_parts_are_merged_or_padded_and_load(tmp_path):
    asset = normalise(RW / "one_triangle" / "parts.obj")
    merged = [f for f in asset.findings if f.code == "part-merged"]
    padded = [f for f in asset.findings if f.code == "part-padded"]
    assert len(merged) == 1 and "'fin'" in merged[0].message and "'body'" in merged[0].message
    assert len(padded) == 1 and "'badge'" in padded[0].message
    assert asset.stats["triangles"] == 12 + 1 + 2 and asset.stats["parts"] == 2
    convert(RW / "one_triangle" / "parts.obj", tmp_path / "parts.mbin", ConvertOptions())
    assert _compile_submeshes(tmp_path / "parts.mbin") == 2


def test_a_single_triangle_file_is_padded_and_loads(tmp_path):
    asset = normalise(RW / "one_triangle" / "triangle.obj")
    assert "part-padded" in codes(asset) and asset.stats["vertices"] == 4
    convert(RW / "one_triangle" / "triangle.obj", tmp_path / "t.mbin", ConvertOptions())
    assert _compile_submeshes(tmp_path / "t.mbin") == 1
    again = tmp_path / "again"
    again.mkdir()
    (again / "t.obj").write_bytes(asset.files["triangle.obj"])
    assert normalise(again / "t.obj").files["t.obj"] == asset.files["triangle.obj"]  # padding is stable


# -- CLI ----------------------------------------------------------------------------------------------------


def test_cli_shows_data_changing_notes_and_strict_fails_on_them(tmp_path):
    runner = CliRunner()
    result = runner.invoke(main, ["normalize", str(RW / "meshlab_tr" / "fuze.obj"), "-o", str(tmp_path / "a")])
    assert result.exit_code == 0
    lines = result.stderr.splitlines()
    assert any("[mtl-tr-converted]" in line for line in lines)
    # the guessed rotation changed every vertex: a warning since issue 31, no longer a hidden note
    assert any(line.startswith("warning: ") and "[up-axis]" in line for line in lines)
    strict = runner.invoke(
        main, ["normalize", str(RW / "meshlab_tr" / "fuze.obj"), "-o", str(tmp_path / "b"), "--strict"]
    )
    assert strict.exit_code == 1 and "mtl-tr-converted" in strict.stderr
    assert not (tmp_path / "b").exists()


def test_cli_up_and_units_auto(tmp_path):
    runner = CliRunner()
    src = RW / "gazebo_model" / "crate" / "meshes" / "crate.obj"
    result = runner.invoke(main, ["normalize", str(src), "-o", str(tmp_path), "--units", "auto", "--json"])
    report = json.loads(result.stdout)
    assert report["stats"]["bbox"]["extent"] == pytest.approx([0.5, 0.4, 0.3])
    manifest = json.loads((tmp_path / "crate" / "asset.json").read_text())
    assert manifest["transform"]["up_rule"] == "consumer" and manifest["transform"]["units"] == "cm"


def test_a_changed_consumer_file_makes_the_mbin_stale(tmp_path):
    from meshtool.pipeline import is_unchanged

    model = tmp_path / "crate"
    shutil.copytree(RW / "gazebo_model" / "crate", model)
    options = ConvertOptions(NormaliseOptions(units="auto"))
    src, out = model / "meshes" / "crate.obj", tmp_path / "crate.mbin"
    convert(src, out, options)
    assert is_unchanged(src, out, options)
    sdf = model / "model.sdf"
    sdf.write_text(sdf.read_text().replace("0.01 0.01 0.01", "0.001 0.001 0.001"))
    assert not is_unchanged(src, out, options)
    with load(out) as packed:
        consumers = [(s["role"], s["path"]) for s in packed.meta["sources"] if s["role"] == "consumer"]
        assert consumers == [("consumer", "../model.sdf")]


@pytest.mark.parametrize(
    ("header", "up", "rule"),
    [
        (["Exported with Up axis: Z"], "z", "header"),
        (["+Y up"], "y", "header"),
        (["everybody up"], "y", "default"),
        (["Blender v2.79 (sub 0) OBJ File: ''"], "y", "exporter"),
    ],
)
def test_header_comments_as_evidence(tmp_path, header, up, rule):
    from meshtool.frame.upaxis import decide_up

    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)
    decision = decide_up(tmp_path / "m.obj", points, header, [], None)
    assert (decision.up, decision.rule) == (up, rule)


def test_header_units_are_evidence_but_not_applied():
    from meshtool.frame.units import header_unit, unit_evidence

    header = ["This file uses centimeters as units for non-parametric coordinates."]
    assert header_unit(header) == "cm" and header_unit(["Blender 4.1.1"]) is None
    evidence = unit_evidence([], header)
    assert evidence is not None and evidence.source == "header" and evidence.unit == "cm"


def test_colour_maps_are_tagged_srgb_and_mujoco_reads_them_so(tmp_path):
    from PIL import Image

    from meshtool.mjcf.asset_model import build_mjcf

    asset = normalise(RW / "normal_maps" / "tile.obj")
    tags = {name: Image.open(io.BytesIO(data)).info.get("srgb") for name, data in asset.textures.items()}
    assert tags == {
        "tile_albedo.png": 0,
        "tile_bump.png": None,
        "tile_normal.png": None,
        "tile_disp.png": None,
        "tile_rough.png": None,
    }
    for name, data in asset.textures.items():  # pixels untouched
        source = Image.open(RW / "normal_maps" / name)
        assert Image.open(io.BytesIO(data)).tobytes() == source.tobytes()
    convert(RW / "normal_maps" / "tile.obj", tmp_path / "tile.mbin", ConvertOptions())
    with load(tmp_path / "tile.mbin") as packed:
        files = build_mjcf(packed, "tile")
    folder = tmp_path / "mjcf"
    folder.mkdir()
    for name, data in files.items():
        (folder / name).write_bytes(data)
    model = mujoco.MjModel.from_xml_path(str(folder / "tile.xml"))
    spaces = {model.texture(k).name: int(model.tex_colorspace[k]) for k in range(model.ntex)}
    srgb, linear = int(mujoco.mjtColorSpace.mjCOLORSPACE_SRGB), int(mujoco.mjtColorSpace.mjCOLORSPACE_LINEAR)
    assert {n: s for n, s in spaces.items() if "albedo" in n} == {"tile_tile_albedo": srgb}
    assert all(s == linear for n, s in spaces.items() if "albedo" not in n) and len(spaces) == 5


GROUND = RW / "gazebo_model" / "ground" / "meshes" / "ground.obj"


@pytest.mark.parametrize("units", [[], ["--units", "m"], ["--units", "auto"]])
def test_gazebo_ground_plane_passes_strict(units, tmp_path):
    """model.sdf uses the 10.9 m slab with no scale (metres): the size is vouched for, not suspicious."""
    from meshtool.cli.main import obj2bin

    out = tmp_path / "ground.mbin"
    result = CliRunner().invoke(obj2bin, [str(GROUND), "-o", str(out), "--strict", "--json", *units])
    assert result.exit_code == 0, result.output
    with load(out) as packed:  # the SDF's numbers: 10.9 x 10.9 x 0.1 m
        extent = packed.positions.max(axis=0) - packed.positions.min(axis=0)
    np.testing.assert_allclose(extent, [10.9, 10.9, 0.1], rtol=1e-6)
    asset = normalise(GROUND, NormaliseOptions(units=units[1] if units else None))
    assert "scale-suspicious" not in codes(asset)
    (unusual,) = [f for f in asset.findings if f.code == "scale-unusual"]
    assert unusual.severity.value == "info" and "10.9 m long" in unusual.message
    assert "../model.sdf" in unusual.message


def test_gazebo_ground_plane_read_in_another_unit_still_warns():
    asset = normalise(GROUND, NormaliseOptions(units="cm"))
    (evidence,) = [f for f in asset.findings if f.code == "units-evidence"]
    assert evidence.severity.value == "warning" and "--units m" in evidence.message
    with pytest.raises(StrictModeError):
        normalise(GROUND, NormaliseOptions(units="cm", strict=True))


def test_a_floor_with_no_consumer_file_is_still_suspicious():
    asset = normalise(RW / "flat_ground" / "floor.obj")
    (suspicious,) = [f for f in asset.findings if f.code == "scale-suspicious"]
    assert suspicious.severity.value == "warning"
    explicit = normalise(RW / "flat_ground" / "floor.obj", NormaliseOptions(units="m"))
    assert "scale-suspicious" not in codes(explicit)
    (unusual,) = [f for f in explicit.findings if f.code == "scale-unusual"]
    assert unusual.message == "10.9 m long (along x) read as metres (--units m): kept"
