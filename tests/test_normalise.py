import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from meshtool import NormaliseOptions, normalise, normalise_to
from meshtool.errors import ObjParseError, OptionsError, OutputError, StrictModeError
from meshtool.read.obj.mtl import parse_mtl
from meshtool.read.obj.parse import parse_obj

SAFE = re.compile(r"^[a-z0-9_.-]+$")
HEAD = Path("head") / "Head 1.obj"


def codes(asset):
    return [f.code for f in asset.findings]


def check_self_contained(folder: Path) -> None:
    """Every file name is safe and every reference inside the output is a bare name that exists."""
    names = sorted(p.name for p in folder.iterdir())
    assert all(SAFE.match(n) for n in names), names
    for obj_file in folder.glob("*.obj"):
        obj = parse_obj(obj_file.read_bytes(), obj_file.name)
        for ref in obj.mtllibs:
            assert "/" not in ref.name and (folder / ref.name).is_file()
    for mtl_file in folder.glob("*.mtl"):
        for material in parse_mtl(mtl_file.read_bytes()).materials:
            for tex in material.maps.values():
                assert "/" not in tex.file and "\\" not in tex.file and (folder / tex.file).is_file()


def test_seed_head_case(fixtures, tmp_path):
    src = fixtures / HEAD
    before = {p.name: p.read_bytes() for p in src.parent.iterdir()}
    folder, asset = normalise_to(src, tmp_path / "out", NormaliseOptions(units="cm"))
    assert folder == tmp_path / "out" / "head_1"
    assert sorted(p.name for p in folder.iterdir()) == ["asset.json", "head_1.mtl", "head_1.obj", "head_1.png"]
    check_self_contained(folder)
    # the BMP became a PNG with identical pixels
    png = Image.open(folder / "head_1.png")
    assert png.format == "PNG" and png.mode == "RGB"
    np.testing.assert_array_equal(np.asarray(png), np.asarray(Image.open(src.parent / "Head 1.bmp").convert("RGB")))
    # 24 cm tall, Y-up source -> 0.24 m along Z; x keeps its 16 cm width, depth 20 cm along y
    out = parse_obj((folder / "head_1.obj").read_bytes())
    extent = out.positions.max(axis=0) - out.positions.min(axis=0)
    assert extent.tolist() == [0.16, 0.2, 0.24]
    assert out.positions[:, 2].min() == 0.0 and out.positions[:, 2].max() == 0.24
    assert asset.stats["triangles"] == 80 and asset.stats["vertices"] == 61
    mtl = parse_mtl((folder / "head_1.mtl").read_bytes()).materials
    assert [(m.name, m.maps["map_Kd"].file) for m in mtl] == [("Head_Material", "head_1.png")]
    assert mtl[0].colors["Kd"] == (0.5882, 0.5882, 0.5882)
    manifest = json.loads((folder / "asset.json").read_text())
    assert manifest["transform"]["units"] == "cm" and manifest["transform"]["up"] == "y"
    assert [s["path"] for s in manifest["sources"]] == ["Head 1.obj", "Head 1.mtl", "Head 1.bmp"]
    assert {r["rule"] for r in manifest["resolutions"]} == {"exact", "trailing-components"}
    assert "scale-suspicious" not in codes(asset)
    assert "texture-converted" in codes(asset)
    # inputs untouched
    assert {p.name: p.read_bytes() for p in src.parent.iterdir()} == before


def test_head_without_units_is_flagged_with_a_suggestion(fixtures):
    asset = normalise(fixtures / HEAD)
    (finding,) = [f for f in asset.findings if f.code == "scale-suspicious"]
    assert finding.message == "24.0 m tall: if it was modelled in centimetres, pass --units cm (0.24 m)"


def test_winding_survives_the_axis_change(fixtures):
    """Face normals of the closed head still point outwards after the Y-up to Z-up rotation."""
    asset = normalise(fixtures / HEAD, NormaliseOptions(units="cm"))
    out = parse_obj(asset.files["head_1.obj"])
    p = out.positions[out.corner_v.reshape(-1, 3)]
    normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    outward = p.mean(axis=1) - out.positions.mean(axis=0)
    signs = np.sign(np.einsum("ij,ij->i", normal, outward))
    assert abs(signs.sum()) == len(signs)  # all one orientation


def test_idempotent_and_deterministic(fixtures, tmp_path):
    first, _ = normalise_to(fixtures / HEAD, tmp_path / "a", NormaliseOptions(units="cm"))
    again, _ = normalise_to(fixtures / HEAD, tmp_path / "b", NormaliseOptions(units="cm"))
    for p in first.iterdir():
        assert p.read_bytes() == (again / p.name).read_bytes(), p.name
    second, asset2 = normalise_to(first / "head_1.obj", tmp_path / "c")
    assert "already-normalized" in codes(asset2)
    for name in ["head_1.obj", "head_1.mtl", "head_1.png"]:
        assert (second / name).read_bytes() == (first / name).read_bytes(), name
    stats = [json.loads((f / "asset.json").read_text())["stats"] for f in (first, second)]
    assert stats[0].pop("source_polygons") == 48 and stats[1].pop("source_polygons") == 80
    assert stats[0] == stats[1]


@pytest.mark.parametrize(
    "case",
    ["multi_material/crate.obj", "crlf_ngon/shapes.obj", "features/features.obj", "latin1/piece.obj", "utf16/part.obj"],
)
def test_every_fixture_is_idempotent(fixtures, tmp_path, case):
    first, _ = normalise_to(fixtures / case, tmp_path / "a")
    name = first.name
    second, _ = normalise_to(first / f"{name}.obj", tmp_path / "b")
    for p in first.iterdir():
        if p.name != "asset.json":
            assert (second / p.name).read_bytes() == p.read_bytes(), p.name
    check_self_contained(first)


def test_multi_material_one_run_per_material(fixtures):
    asset = normalise(fixtures / "multi_material" / "crate.obj")
    text = asset.files["crate.obj"].decode()
    assert re.findall(r"^usemtl (\S+)$", text, re.M) == ["painted", "wood", "checker"]
    assert re.findall(r"^g (\S+)$", text, re.M) == ["Body", "Body", "Lid", "Lid"]
    assert sorted(asset.files) == ["asset.json", "checker.png", "crate.mtl", "crate.obj", "wood_grain.png"]
    mtl = {m.name: m for m in parse_mtl(asset.files["crate.mtl"]).materials}
    assert list(mtl) == ["painted", "wood", "checker"]  # 'unused' dropped
    assert mtl["wood"].maps["map_Kd"].file == "wood_grain.png"
    assert mtl["wood"].maps["map_Kd"].options == {"-s": ("2.0", "2.0", "1.0")}
    assert mtl["checker"].maps["map_Kd"].options == {"-clamp": ("on",)}
    assert mtl["painted"].colors["Kd"] == (0.8, 0.1, 0.1) and "map_Kd" not in mtl["painted"].maps
    assert asset.stats["triangles"] == 12 and asset.stats["materials"] == 3 and asset.stats["textures"] == 2
    assert "materials-unused" in codes(asset)


def test_case_mismatch_is_repaired(fixtures):
    asset = normalise(fixtures / "case_mismatch" / "model.obj")
    rules = [(r["ref"], r["rule"], r["found"]) for r in asset.manifest["resolutions"]]
    assert rules == [
        ("MODEL.MTL", "case-insensitive", "model.mtl"),
        ("Textures\\Wood.PNG", "case-insensitive", "textures/wood.png"),
    ]
    assert "model.png" not in asset.files and "wood.png" in asset.files
    assert not any(f.severity.value == "warning" for f in asset.findings if f.code != "up-axis")


def test_missing_texture_keeps_the_colour(fixtures):
    asset = normalise(fixtures / "missing_texture" / "panel.obj")
    (m,) = parse_mtl(asset.files["panel.mtl"]).materials
    assert m.colors["Kd"] == (0.7, 0.7, 0.75) and m.maps == {}
    (f,) = [f for f in asset.findings if f.code == "texture-missing"]
    assert (f.path, f.line, f.severity.value) == ("panel.mtl", 3, "warning")


def test_missing_mtl_gives_default_material(fixtures):
    asset = normalise(fixtures / "missing_mtl" / "box.obj")
    assert codes(asset).count("mtl-missing") == 1 and "material-undefined" in codes(asset)
    (m,) = parse_mtl(asset.files["box.mtl"]).materials
    assert m.name == "steel" and m.colors["Kd"] == (0.8, 0.8, 0.8)
    assert asset.stats["triangles"] == 4


def test_path_traversal_is_a_finding_not_a_read(fixtures):
    asset = normalise(fixtures / "traversal" / "evil.obj")
    found = [r["found"] for r in asset.manifest["resolutions"]]
    assert found == [None, "evil.mtl", None, None]
    assert codes(asset).count("reference-outside-root") == 2  # ../../ passwd and ../../secret.png
    assert sorted(asset.files) == ["asset.json", "evil.mtl", "evil.obj"]
    assert all(s["path"] in ("evil.obj", "evil.mtl") for s in asset.manifest["sources"])


def test_strict_turns_warnings_into_failure(fixtures, tmp_path):
    with pytest.raises(StrictModeError, match="warning"):
        normalise_to(fixtures / "missing_texture" / "panel.obj", tmp_path / "out", NormaliseOptions(strict=True))
    assert not (tmp_path / "out").exists()
    # with the up axis said (no guessed rotation, issue 31) a repaired asset passes --strict
    ok = NormaliseOptions(strict=True, up="y")
    folder, _ = normalise_to(fixtures / "case_mismatch" / "model.obj", tmp_path / "ok", ok)
    assert folder.is_dir()
    with pytest.raises(StrictModeError, match=r"\[up-axis\]"):  # the guessed rotation is a warning
        normalise_to(fixtures / "case_mismatch" / "model.obj", tmp_path / "guess", NormaliseOptions(strict=True))


@pytest.mark.parametrize(
    ("case", "line", "words"),
    [
        ("bad_index/bad.obj", 5, "face refers to vertex 7"),
        ("nan/nan.obj", 2, "non-finite coordinate"),
        ("empty/empty.obj", None, "empty OBJ file"),
        ("garbage/garbage.obj", None, "binary data"),
    ],
)
def test_bad_input_raises_and_writes_nothing(fixtures, tmp_path, case, line, words):
    with pytest.raises(ObjParseError, match=words) as info:
        normalise_to(fixtures / case, tmp_path / "out")
    assert info.value.line == line
    assert not (tmp_path / "out").exists()


def test_points_only_pass_through(fixtures):
    asset = normalise(fixtures / "points" / "cloud.obj", NormaliseOptions(up="z"))
    assert asset.stats["vertices"] == 4 and asset.stats["triangles"] == 0
    assert "no-faces" in codes(asset)


def test_units_scale_and_up(fixtures):
    base = normalise(fixtures / "crlf_ngon" / "shapes.obj", NormaliseOptions(up="z")).stats["bbox"]
    mm = normalise(fixtures / "crlf_ngon" / "shapes.obj", NormaliseOptions(units="mm", scale=2.0, up="z")).stats["bbox"]
    np.testing.assert_allclose(np.asarray(mm["extent"]), np.asarray(base["extent"]) * 0.002)
    yup = normalise(fixtures / "crlf_ngon" / "shapes.obj", NormaliseOptions(up="y")).stats["bbox"]
    assert yup["extent"] == [base["extent"][0], base["extent"][2], base["extent"][1]]


def test_features_fixture(fixtures):
    asset = normalise(fixtures / "features" / "features.obj")
    out = parse_obj(asset.files["features.obj"])
    assert out.colors is not None and out.positions.shape == (5, 3)
    assert asset.stats["triangles"] == 4 and asset.stats["materials"] == 2
    assert {"lines-skipped", "points-skipped", "line-continuation", "vertex-colors-partial"} <= set(codes(asset))


def test_output_safety(fixtures, tmp_path):
    (tmp_path / "out" / "head_1").mkdir(parents=True)
    (tmp_path / "out" / "head_1" / "precious.txt").write_text("mine")
    with pytest.raises(OutputError, match="not written by meshtool"):
        normalise_to(fixtures / HEAD, tmp_path / "out")
    assert (tmp_path / "out" / "head_1" / "precious.txt").read_text() == "mine"
    copy = tmp_path / "src" / "head_1"
    shutil.copytree(fixtures / "head", copy)
    (copy / "asset.json").write_text("{}")
    with pytest.raises(OutputError, match="would contain the source"):
        normalise_to(copy / "Head 1.obj", tmp_path / "src")
    assert (copy / "Head 1.obj").exists()
    assert not [p for p in (tmp_path / "out").iterdir() if p.name.startswith(".")]


def test_rewriting_replaces_a_meshtool_folder(fixtures, tmp_path):
    normalise_to(fixtures / HEAD, tmp_path, NormaliseOptions(units="cm"))
    folder, _ = normalise_to(fixtures / HEAD, tmp_path, NormaliseOptions(units="mm"))
    assert json.loads((folder / "asset.json").read_text())["transform"]["units"] == "mm"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["head_1"]


@pytest.mark.parametrize(
    "kwargs", [{"units": "furlong"}, {"up": "x"}, {"scale": 0.0}, {"scale": float("nan")}, {"name": "///"}]
)
def test_bad_options(kwargs):
    with pytest.raises(OptionsError):
        NormaliseOptions(**kwargs)


def test_plain_mesh_gets_no_mtl(fixtures):
    asset = normalise(fixtures / "crlf_ngon" / "shapes.obj")
    assert sorted(asset.files) == ["asset.json", "shapes.obj"]
    assert asset.stats["materials"] == 0
    text = asset.files["shapes.obj"].decode()
    assert "mtllib" not in text and "usemtl" not in text
    assert text.count("\nf ") == 14


def test_mixed_texcoords_are_filled_so_mujoco_keeps_them(tmp_path):
    src = tmp_path / "mixed.obj"
    src.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0.5 0.5\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\nf 2 4 3\n")
    asset = normalise(src, NormaliseOptions(up="z"))
    out = parse_obj(asset.files["mixed.obj"])
    np.testing.assert_array_equal(out.texcoords, [[0.5, 0.5], [1, 0], [0, 1], [0, 0]])
    assert out.corner_vt.tolist() == [0, 1, 2, 3, 3, 3]
    assert "texcoords-filled" in codes(asset)
