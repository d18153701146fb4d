"""USD export read back with pxr."""

from pathlib import Path

import numpy as np
from click.testing import CliRunner
from pxr import Usd, UsdGeom, UsdPhysics, UsdShade

from meshtool.cli.main import main
from meshtool.packfile import load

SCENES = Path(__file__).resolve().parent.parent / "fixtures" / "scenes"


def test_mbin_to_usd_keeps_points_faces_texture_and_hulls(tmp_path):
    source = SCENES / "head.mbin"
    for suffix in (".usda", ".usdc"):
        out = tmp_path / f"head{suffix}"
        result = CliRunner().invoke(main, ["export", str(source), "--usd", str(out)])
        assert result.exit_code == 0, result.output
        stage = Usd.Stage.Open(str(out))
        assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z and UsdGeom.GetStageMetersPerUnit(stage) == 1.0
        meshes = [UsdGeom.Mesh(p) for p in stage.Traverse() if p.IsA(UsdGeom.Mesh)]
        visual = [m for m in meshes if "/Geom/" in str(m.GetPath())]
        hulls = [m for m in meshes if "/Collision/" in str(m.GetPath())]
        with load(source) as packed:
            assert sum(len(m.GetPointsAttr().Get()) for m in visual) == packed.positions.shape[0]
            assert sum(len(m.GetFaceVertexCountsAttr().Get()) for m in visual) == packed.indices.shape[0]
            assert len(hulls) == len(packed.hulls)
            np.testing.assert_allclose(np.array(hulls[0].GetPointsAttr().Get()), packed.hulls[0][0], atol=1e-7)
            st = UsdGeom.PrimvarsAPI(visual[0]).GetPrimvar("st").Get()
            assert len(st) == packed.positions.shape[0]
        assert all(h.GetPrim().HasAPI(UsdPhysics.CollisionAPI) for h in hulls)
        material, _ = UsdShade.MaterialBindingAPI(visual[0].GetPrim()).ComputeBoundMaterial()
        textures = [p for p in stage.Traverse() if p.GetName() == "DiffuseTexture"]
        assert material and len(textures) == 1
        png = textures[0].GetAttribute("inputs:file").Get().path
        assert (tmp_path / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert CliRunner().invoke(main, ["export", str(source), "--usd", str(tmp_path / "x.obj")]).exit_code == 1


def test_name_starting_with_a_digit_exports_and_validates(tmp_path):
    from pxr import Sdf, UsdValidation

    source = tmp_path / "3d head.mbin"
    source.write_bytes((SCENES / "head.mbin").read_bytes())
    out = tmp_path / "head.usda"
    result = CliRunner().invoke(main, ["export", str(source), "--usd", str(out)])
    assert result.exit_code == 0, result.output
    stage = Usd.Stage.Open(str(out))
    assert str(stage.GetDefaultPrim().GetPath()) == "/_3d_head"
    found = UsdValidation.ValidationContext(UsdValidation.ValidationRegistry().GetOrLoadAllValidators()).Validate(stage)
    assert [e.GetMessage() for e in found if e.GetType() == UsdValidation.ValidationErrorType.Error] == []
    (reader,) = [p for p in stage.Traverse() if p.GetName() == "stReader"]
    assert reader.GetAttribute("inputs:varname").GetTypeName() == Sdf.ValueTypeNames.String


def _two_clashing_materials(tmp_path: Path) -> Path:
    """An .mbin with materials ``a-b`` (red) and ``a_b`` (green): one sanitised prim name for both."""
    from meshtool.cli.main import obj2bin

    tetra = ["v 0 0 0", "v 1 0 0", "v 0 1 0", "v 0 0 1", "v 2 0 0", "v 3 0 0", "v 2 1 0", "v 2 0 1"]
    faces = ["f {} {} {}", "f {} {} {}", "f {} {} {}", "f {} {} {}"]
    corners = [(1, 2, 3), (1, 2, 4), (1, 3, 4), (2, 3, 4)]
    lines = ["mtllib m.mtl", *tetra, "usemtl a-b"]
    lines += [f.format(*c) for f, c in zip(faces, corners, strict=True)]
    lines += ["usemtl a_b"] + [f.format(*(i + 4 for i in c)) for f, c in zip(faces, corners, strict=True)]
    (tmp_path / "m.obj").write_text("\n".join(lines) + "\n")
    (tmp_path / "m.mtl").write_text("newmtl a-b\nKd 1 0 0\nnewmtl a_b\nKd 0 1 0\n")
    out = tmp_path / "m.mbin"
    result = CliRunner().invoke(obj2bin, [str(tmp_path / "m.obj"), "-o", str(out), "--no-check"])
    assert result.exit_code == 0, result.output
    return out


def test_materials_whose_names_sanitise_alike_stay_distinct_and_bound_right(tmp_path):
    source = _two_clashing_materials(tmp_path)
    out = tmp_path / "m.usda"
    result = CliRunner().invoke(main, ["export", str(source), "--usd", str(out)])
    assert result.exit_code == 0, result.output
    stage = Usd.Stage.Open(str(out))
    materials = sorted(str(p.GetPath()) for p in stage.Traverse() if p.IsA(UsdShade.Material))
    assert materials == ["/m/Materials/a_b", "/m/Materials/a_b_2"]
    # the colour each part shows is its own material's Kd (the MTL's numbers), read through the binding
    colours = {}
    for prim in stage.Traverse():
        if prim.IsA(UsdGeom.Mesh) and "/Geom/" in str(prim.GetPath()):
            material, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
            shader = UsdShade.Shader(stage.GetPrimAtPath(material.GetPath().AppendChild("PreviewSurface")))
            x = min(p[0] for p in UsdGeom.Mesh(prim).GetPointsAttr().Get())
            colours[x] = tuple(shader.GetInput("diffuseColor").Get())
    assert colours == {0.0: (1.0, 0.0, 0.0), 2.0: (0.0, 1.0, 0.0)}
