"""USD export of ``.mbin`` assets with usd-core: UsdGeom meshes, UsdPreviewSurface materials, PNG textures.

The stage is Z-up with ``metersPerUnit = 1`` (meshtool's conventions). Each submesh becomes a
``UsdGeom.Mesh`` under ``/NAME/Geom`` with normals and ``primvars:st``, bound to a material whose
``UsdPreviewSurface`` reads its PNG through ``UsdUVTexture`` (the PNGs are written beside the USD file).
Collision hulls become ``UsdGeom.Mesh`` prims under ``/NAME/Collision`` with ``UsdPhysics.CollisionAPI``
and ``UsdPhysics.MeshCollisionAPI`` (approximation ``convexHull``).
"""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from meshtool.errors import OutputError
from meshtool.formats import check_suffix
from meshtool.mesh import safe_identifier
from meshtool.outdir import stamp_usd, write_file
from meshtool.packfile.read import PackedMesh
from meshtool.packfile.view import PartMaterial, Texture, asset_view, unique_names
from meshtool.resolve import read_cache


def export_usd(packed: PackedMesh, out: Path, name: str) -> list[Path]:
    """Write ``out`` (``.usda``, ``.usdc`` or ``.usd``) and the PNG textures it references beside it.

    Returns:
        Every file written.

    Raises:
        OutputError: An unsupported extension or a write failure.
    """
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdPhysics, UsdShade, Vt

    wrong = check_suffix(out, "usd")
    if wrong is not None:
        raise OutputError(wrong, path=str(out))
    root = "/" + _prim_name(name, "asset")
    written: list[Path] = []
    view = asset_view(packed)
    for texture in view.textures:
        target = out.parent / texture.file
        write_file(target, texture.data)
        written.append(target)
    with tempfile.TemporaryDirectory(prefix=".usd-", dir=out.parent if out.parent.exists() else None) as tmp:
        scratch = Path(tmp) / out.name
        stage = Usd.Stage.CreateNew(str(scratch))
        UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
        UsdGeom.SetStageMetersPerUnit(stage, 1.0)
        xform = UsdGeom.Xform.Define(stage, root)
        stage.SetDefaultPrim(xform.GetPrim())
        prims = unique_names(_prim_name(m.name, "material") for m in view.materials)
        materials = [
            _material(stage, f"{root}/Materials/{prim}", m, view.textures)
            for prim, m in zip(prims, view.materials, strict=True)
        ]
        for part in view.parts:
            mesh = UsdGeom.Mesh.Define(stage, f"{root}/Geom/submesh_{part.index}")
            mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(part.positions.astype(np.float32)))
            mesh.CreateFaceVertexCountsAttr(Vt.IntArray([3] * len(part.faces)))
            mesh.CreateFaceVertexIndicesAttr(Vt.IntArray(part.faces.astype(np.int32).ravel().tolist()))
            mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
            if part.normals is not None:
                mesh.CreateNormalsAttr(Vt.Vec3fArray.FromNumpy(part.normals.astype(np.float32)))
                mesh.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
            if part.uvs is not None:
                st = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar(
                    "st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.vertex
                )
                st.Set(Vt.Vec2fArray.FromNumpy(part.uvs.astype(np.float32)))
            lo, hi = part.positions.min(axis=0), part.positions.max(axis=0)
            mesh.CreateExtentAttr([Gf.Vec3f(*lo.tolist()), Gf.Vec3f(*hi.tolist())])
            if materials:
                UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(materials[part.material])
        for k, (hull_vertices, hull_faces) in enumerate(view.hulls):
            hull = UsdGeom.Mesh.Define(stage, f"{root}/Collision/hull_{k}")
            hull.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(hull_vertices.astype(np.float32)))
            hull.CreateFaceVertexCountsAttr(Vt.IntArray([3] * len(hull_faces)))
            hull.CreateFaceVertexIndicesAttr(Vt.IntArray(hull_faces.astype(np.int32).ravel().tolist()))
            hull.CreatePurposeAttr(UsdGeom.Tokens.guide)
            UsdPhysics.CollisionAPI.Apply(hull.GetPrim())
            UsdPhysics.MeshCollisionAPI.Apply(hull.GetPrim()).CreateApproximationAttr(UsdPhysics.Tokens.convexHull)
        stamp_usd(stage.GetRootLayer())  # how a later export knows this file is meshtool's to replace
        stage.GetRootLayer().Save()
        saved = read_cache(scratch)
        if saved is None:
            raise OutputError("usd-core did not write the stage", path=str(out))
        write_file(out, saved)
    written.append(out)
    return written


def _material(stage: Any, path: str, spec: PartMaterial, textures: list[Texture]) -> Any:
    """A UsdPreviewSurface material at prim ``path``: diffuse colour or texture, normal map, opacity, Ns roughness.

    The colour map is read with ``sourceColorSpace = sRGB``, the normal map with ``raw`` and mapped from
    0..1 to -1..1 (``scale (2s, 2s, 2, 1)``, ``bias (-s, -s, -1, 0)``, ``s`` its ``-bm`` strength) into the
    surface's ``normal`` input, as the UsdPreviewSurface specification asks for tangent-space normal maps.
    Maps are read only when the mesh has texture coordinates (the view leaves them out otherwise).
    """
    from pxr import Sdf, UsdShade

    material = UsdShade.Material.Define(stage, path)
    shader = UsdShade.Shader.Define(stage, f"{path}/PreviewSurface")
    shader.CreateIdAttr("UsdPreviewSurface")
    diffuse = shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f)
    diffuse.Set(spec.diffuse)
    shader.CreateInput("opacity", Sdf.ValueTypeNames.Float).Set(spec.alpha)
    shininess = float(spec.record.get("scalars", {}).get("Ns", 10.0))
    shader.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(float(1.0 - min(shininess, 1000.0) / 1000.0))
    reader = None
    if spec.colour_map is not None or spec.normal_map is not None:
        reader = UsdShade.Shader.Define(stage, f"{path}/stReader")
        reader.CreateIdAttr("UsdPrimvarReader_float2")
        reader.CreateInput("varname", Sdf.ValueTypeNames.String).Set("st")  # UsdPreviewSurface: a string
    if reader is not None and spec.colour_map is not None:
        image = _uv_texture(stage, f"{path}/DiffuseTexture", textures[spec.colour_map].file, "sRGB", reader)
        diffuse.ConnectToSource(image.ConnectableAPI(), "rgb")
    if reader is not None and spec.normal_map is not None:
        image = _uv_texture(stage, f"{path}/NormalTexture", textures[spec.normal_map].file, "raw", reader)
        s = spec.normal_scale
        image.CreateInput("scale", Sdf.ValueTypeNames.Float4).Set((2.0 * s, 2.0 * s, 2.0, 1.0))
        image.CreateInput("bias", Sdf.ValueTypeNames.Float4).Set((-s, -s, -1.0, 0.0))
        shader.CreateInput("normal", Sdf.ValueTypeNames.Normal3f).ConnectToSource(image.ConnectableAPI(), "rgb")
    material.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")
    return material


def _uv_texture(stage: Any, path: str, file: str, colorspace: str, reader: Any) -> Any:
    """A ``UsdUVTexture`` reading ``file`` at the primvar ``st`` with ``sourceColorSpace = colorspace``."""
    from pxr import Sdf, UsdShade

    image = UsdShade.Shader.Define(stage, path)
    image.CreateIdAttr("UsdUVTexture")
    image.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(file)
    image.CreateInput("sourceColorSpace", Sdf.ValueTypeNames.Token).Set(colorspace)
    image.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(reader.ConnectableAPI(), "result")
    image.CreateOutput("rgb", Sdf.ValueTypeNames.Float3)
    return image


def _prim_name(name: str, fallback: str) -> str:
    """A valid USD prim name: ``[A-Za-z0-9_]``, not starting with a digit."""
    text = safe_identifier(name, fallback).replace(".", "_").replace("-", "_")
    return f"_{text}" if text[:1].isdigit() else text
