"""Normal maps in glTF and USD exports (issue 16 item 1), read back by pygltflib, trimesh, Khronos validator, pxr.

Ground truth comes from the fixture files: the PNG pixels on disk, the OBJ's positions and texture
coordinates (the tangent must point along increasing u, the bitangent along increasing v).
"""

from __future__ import annotations

import io
import json
import shutil
import struct
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from meshtool.cli.main import main
from meshtool.packfile import load
from meshtool.packfile.export import Z_UP_TO_Y_UP, to_glb
from meshtool.pipeline import convert
from meshtool.repair.normalmaps import export_findings, looks_like_normal_map, normal_map

ROOT = Path(__file__).resolve().parent.parent
TILE = ROOT / "fixtures" / "realworld" / "normal_maps"
PANEL = ROOT / "fixtures" / "followups" / "blender_normal"
VALIDATOR = ROOT / "tools" / "gltf-validator" / "node_modules" / "gltf-validator"


def _pack(obj: Path, tmp_path: Path) -> Path:
    out = tmp_path / f"{obj.stem}.mbin"
    convert(obj, out)
    return out


def _pixels(data: bytes) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(data)).convert("RGB"))


def _glb_parts(glb: bytes) -> tuple[dict[str, Any], bytes]:
    length = struct.unpack_from("<I", glb, 12)[0]
    return json.loads(glb[20 : 20 + length]), glb[20 + length + 8 :]


def _image_bytes(document: dict[str, Any], binary: bytes, texture: int) -> bytes:
    image = document["images"][document["textures"][texture]["source"]]
    view = document["bufferViews"][image["bufferView"]]
    start = view.get("byteOffset", 0)
    return binary[start : start + view["byteLength"]]


def _accessor(document: dict[str, Any], binary: bytes, index: int) -> np.ndarray:
    accessor = document["accessors"][index]
    view = document["bufferViews"][accessor["bufferView"]]
    width = {"VEC2": 2, "VEC3": 3, "VEC4": 4}[accessor["type"]]
    start = view.get("byteOffset", 0) + accessor.get("byteOffset", 0)
    data = np.frombuffer(binary, dtype="<f4", count=accessor["count"] * width, offset=start)
    return data.reshape(-1, width).astype(np.float64)


def _validate(path: Path) -> dict[str, Any]:
    node = shutil.which("node")
    if node is None:
        pytest.skip("node is not installed (the Khronos glTF validator runs on Node.js)")
    if not VALIDATOR.is_dir():
        pytest.skip("gltf-validator is not installed: run scripts/install_gltf_validator.sh")
    run = subprocess.run([node, str(ROOT / "scripts" / "gltf_validate.cjs"), str(path)], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    report: dict[str, Any] = json.loads(run.stdout)
    return report


# -- which map is the normal map ---------------------------------------------------------------------


def test_a_normal_map_is_told_from_height_and_colour_maps_by_its_pixels() -> None:
    assert looks_like_normal_map((PANEL / "panel_normal.png").read_bytes())
    for name in ("tile_bump.png", "tile_disp.png", "tile_albedo.png", "tile_rough.png"):
        assert not looks_like_normal_map((TILE / name).read_bytes()), name
    assert not looks_like_normal_map((PANEL / "panel_color.png").read_bytes())
    assert not looks_like_normal_map(b"\x89PNG\r\n\x1a\n broken")
    flat = io.BytesIO()
    Image.new("RGB", (4, 4), (128, 128, 255)).save(flat, format="PNG")
    assert looks_like_normal_map(flat.getvalue())
    grey = io.BytesIO()
    Image.new("L", (4, 4), 128).save(grey, format="PNG")
    assert not looks_like_normal_map(grey.getvalue())


def test_norm_wins_and_a_grey_bump_is_no_normal_map(tmp_path: Path) -> None:
    with load(_pack(TILE / "tile.obj", tmp_path)) as packed:
        (material,) = packed.materials
        found = normal_map(material, packed.textures)
        assert found is not None and found.key == "norm" and found.scale == 1.0
        assert packed.meta["textures"][found.texture] == "tile_normal.png"
        without_norm = {**material, "maps": {k: v for k, v in material["maps"].items() if k != "norm"}}
        assert normal_map(without_norm, packed.textures) is None  # tile_bump.png is a grey height map


# -- glTF --------------------------------------------------------------------------------------------


def test_glb_normal_texture_is_the_norm_map_and_the_file_is_valid(tmp_path: Path) -> None:
    mbin = _pack(TILE / "tile.obj", tmp_path)
    out = tmp_path / "tile.glb"
    result = CliRunner().invoke(main, ["export", str(mbin), "--glb", str(out)])
    assert result.exit_code == 0, result.output
    assert "export-map-dropped" in result.output
    for dropped in ("bump (height map: tile_bump.png)", "disp (displacement map", "map_Pr (roughness map"):
        assert dropped in result.output
    glb = out.read_bytes()
    document, binary = _glb_parts(glb)
    (material,) = document["materials"]
    normal = _image_bytes(document, binary, material["normalTexture"]["index"])
    base = _image_bytes(document, binary, material["pbrMetallicRoughness"]["baseColorTexture"]["index"])
    assert np.array_equal(_pixels(normal), _pixels((TILE / "tile_normal.png").read_bytes()))
    assert np.array_equal(_pixels(base), _pixels((TILE / "tile_albedo.png").read_bytes()))
    assert "scale" not in material["normalTexture"]  # no -bm on the norm statement: glTF's default 1
    issues = _validate(out)["issues"]
    shown = [(m["code"], m["message"]) for m in issues["messages"] if m["severity"] <= 1]
    assert (issues["numErrors"], issues["numWarnings"], issues["numInfos"], issues["numHints"]) == (0, 0, 0, 0), shown


def test_glb_reads_back_in_pygltflib_and_trimesh(tmp_path: Path) -> None:
    import pygltflib
    import trimesh

    with load(_pack(TILE / "tile.obj", tmp_path)) as packed:
        glb = to_glb(packed)
    out = tmp_path / "tile.glb"
    out.write_bytes(glb)
    gltf = pygltflib.GLTF2().load_binary(str(out))
    (material,) = gltf.materials
    assert material.normalTexture is not None
    texture = gltf.textures[material.normalTexture.index]
    view = gltf.bufferViews[gltf.images[texture.source].bufferView]
    blob = gltf.binary_blob()
    png = blob[view.byteOffset or 0 : (view.byteOffset or 0) + view.byteLength]
    assert np.array_equal(_pixels(png), _pixels((TILE / "tile_normal.png").read_bytes()))
    assert all("TANGENT" in json.loads(p.attributes.to_json()) for m in gltf.meshes for p in m.primitives)
    scene = trimesh.load(str(out), file_type="glb")
    (geometry,) = scene.geometry.values()
    loaded = geometry.visual.material.normalTexture
    assert loaded is not None
    assert np.array_equal(np.asarray(loaded.convert("RGB")), _pixels((TILE / "tile_normal.png").read_bytes()))


def test_blender_map_bump_normal_map_with_strength_and_tangents_along_uv(tmp_path: Path) -> None:
    mbin = _pack(PANEL / "panel.obj", tmp_path)
    with load(mbin) as packed:
        assert export_findings(packed, "glb") == []  # colour and normal map: nothing left out
        glb = to_glb(packed)
        positions = np.asarray(packed.positions, np.float64)
        uvs = np.asarray(packed.uvs, np.float64)
    out = tmp_path / "panel.glb"
    out.write_bytes(glb)
    document, binary = _glb_parts(glb)
    (material,) = document["materials"]
    assert material["normalTexture"]["scale"] == pytest.approx(0.8)
    normal = _image_bytes(document, binary, material["normalTexture"]["index"])
    assert np.array_equal(_pixels(normal), _pixels((PANEL / "panel_normal.png").read_bytes()))
    # the source quad: u grows along p(1, 0) - p(0, 0), v along p(0, 1) - p(0, 0), in the pack's frame
    corner = {tuple(np.round(t).astype(int)): positions[k] for k, t in enumerate(uvs)}
    u_dir = corner[(1, 0)] - corner[(0, 0)]
    v_dir = corner[(0, 1)] - corner[(0, 0)]
    u_dir, v_dir = u_dir / np.linalg.norm(u_dir), v_dir / np.linalg.norm(v_dir)
    (mesh,) = document["meshes"]
    (primitive,) = mesh["primitives"]
    tangents = _accessor(document, binary, primitive["attributes"]["TANGENT"])
    normals = _accessor(document, binary, primitive["attributes"]["NORMAL"])
    assert np.allclose(tangents[:, :3], u_dir, atol=1e-6)
    bitangents = np.cross(normals, tangents[:, :3]) * tangents[:, 3:4]
    assert np.allclose(bitangents, v_dir, atol=1e-6)
    node_matrix = np.asarray(document["nodes"][-1]["matrix"]).reshape(4, 4).T
    assert np.allclose(node_matrix, Z_UP_TO_Y_UP)  # tangents are in the mesh frame, like positions
    issues = _validate(out)["issues"]
    assert (issues["numErrors"], issues["numWarnings"], issues["numInfos"], issues["numHints"]) == (0, 0, 0, 0), issues[
        "messages"
    ]


def test_glb_export_is_deterministic(tmp_path: Path) -> None:
    with load(_pack(PANEL / "panel.obj", tmp_path)) as packed:
        assert to_glb(packed) == to_glb(packed)


# -- USD ---------------------------------------------------------------------------------------------


def _usd_material(out: Path) -> tuple[Any, Any]:
    from pxr import Usd, UsdShade, UsdValidation

    stage = Usd.Stage.Open(str(out))
    found = UsdValidation.ValidationContext(UsdValidation.ValidationRegistry().GetOrLoadAllValidators()).Validate(stage)
    assert [e.GetMessage() for e in found if e.GetType() == UsdValidation.ValidationErrorType.Error] == []
    (material,) = [UsdShade.Material(p) for p in stage.Traverse() if p.IsA(UsdShade.Material)]
    surface = material.ComputeSurfaceSource()[0]
    return stage, surface


def _source(shader_input: Any) -> Any:
    from pxr import UsdShade

    connected = shader_input.GetConnectedSources()[0]
    assert len(connected) == 1
    return UsdShade.Shader(connected[0].source.GetPrim()), connected[0].sourceName


def test_usd_normal_input_is_connected_to_a_raw_texture(tmp_path: Path) -> None:
    mbin = _pack(TILE / "tile.obj", tmp_path)
    out = tmp_path / "usd" / "tile.usda"
    out.parent.mkdir()
    result = CliRunner().invoke(main, ["export", str(mbin), "--usd", str(out)])
    assert result.exit_code == 0, result.output
    assert "not exported to USD" in result.output
    _stage, surface = _usd_material(out)  # the stage must outlive its prims
    texture, output = _source(surface.GetInput("normal"))
    assert output == "rgb"
    assert texture.GetIdAttr().Get() == "UsdUVTexture"
    assert texture.GetInput("file").Get().path == "tile_normal.png"
    assert texture.GetInput("sourceColorSpace").Get() == "raw"
    assert tuple(texture.GetInput("scale").Get()) == (2.0, 2.0, 2.0, 1.0)
    assert tuple(texture.GetInput("bias").Get()) == (-1.0, -1.0, -1.0, 0.0)
    reader, _ = _source(texture.GetInput("st"))
    assert reader.GetInput("varname").Get() == "st"
    colour, _ = _source(surface.GetInput("diffuseColor"))
    assert colour.GetInput("file").Get().path == "tile_albedo.png"
    assert colour.GetInput("sourceColorSpace").Get() == "sRGB"
    written = (out.parent / "tile_normal.png").read_bytes()
    assert np.array_equal(_pixels(written), _pixels((TILE / "tile_normal.png").read_bytes()))


def test_usd_blender_normal_map_strength(tmp_path: Path) -> None:
    from meshtool.packfile.usd import export_usd

    with load(_pack(PANEL / "panel.obj", tmp_path)) as packed:
        out = tmp_path / "panel.usda"
        export_usd(packed, out, "panel")
    _stage, surface = _usd_material(out)  # the stage must outlive its prims
    texture, _ = _source(surface.GetInput("normal"))
    assert texture.GetInput("file").Get().path == "panel_normal.png"
    assert texture.GetInput("scale").Get() == pytest.approx((1.6, 1.6, 2.0, 1.0))
    assert texture.GetInput("bias").Get() == pytest.approx((-0.8, -0.8, -1.0, 0.0))
