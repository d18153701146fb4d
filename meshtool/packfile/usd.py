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
from meshtool.mesh import safe_identifier
from meshtool.outdir import stamp_usd, write_file
from meshtool.packfile.read import PackedMesh
from meshtool.resolve import read_cache


def export_usd(packed: PackedMesh, out: Path, name: str) -> list[Path]:
    """Write ``out`` (``.usda``, ``.usdc`` or ``.usd``) and the PNG textures it references beside it.

    Returns:
        Every file written.

    Raises:
        OutputError: An unsupported extension or a write failure.
    """
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdPhysics, UsdShade, Vt

    if out.suffix.lower() not in (".usda", ".usdc", ".usd"):
        raise OutputError("USD output must end in .usda, .usdc or .usd", path=str(out))
    root = "/" + _prim_name(name, "asset")
    written: list[Path] = []
    textures = list(packed.meta.get("textures", []))
    for k, data in enumerate(packed.textures):
        target = out.parent / textures[k]
        write_file(target, bytes(data))
        written.append(target)
    with tempfile.TemporaryDirectory(prefix=".usd-", dir=out.parent if out.parent.exists() else None) as tmp:
        scratch = Path(tmp) / out.name
        stage = Usd.Stage.CreateNew(str(scratch))
        UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
        UsdGeom.SetStageMetersPerUnit(stage, 1.0)
        xform = UsdGeom.Xform.Define(stage, root)
        stage.SetDefaultPrim(xform.GetPrim())
        images = packed.textures if packed.uvs is not None else None
        prims = _unique_prim_names([str(m.get("name", "material")) for m in packed.materials], "material")
        materials = [
            _material(stage, f"{root}/Materials/{prim}", m, textures, images)
            for prim, m in zip(prims, packed.materials, strict=True)
        ]
        positions = np.asarray(packed.positions, dtype=np.float64)
        indices = np.asarray(packed.indices, dtype=np.int64)
        for k, (first, count, material, _) in enumerate(np.asarray(packed.submeshes, dtype=np.int64).tolist()):
            faces = indices[first : first + count]
            used, inverse = np.unique(faces, return_inverse=True)
            mesh = UsdGeom.Mesh.Define(stage, f"{root}/Geom/submesh_{k}")
            mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(positions[used].astype(np.float32)))
            mesh.CreateFaceVertexCountsAttr(Vt.IntArray([3] * count))
            mesh.CreateFaceVertexIndicesAttr(Vt.IntArray(inverse.astype(np.int32).ravel().tolist()))
            mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
            if packed.normals is not None:
                mesh.CreateNormalsAttr(Vt.Vec3fArray.FromNumpy(np.asarray(packed.normals, np.float32)[used]))
                mesh.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
            if packed.uvs is not None:
                st = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar(
                    "st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.vertex
                )
                st.Set(Vt.Vec2fArray.FromNumpy(np.asarray(packed.uvs, np.float32)[used]))
            lo, hi = positions[used].min(axis=0), positions[used].max(axis=0)
            mesh.CreateExtentAttr([Gf.Vec3f(*lo.tolist()), Gf.Vec3f(*hi.tolist())])
            if materials:
                UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(materials[material])
        for k, (hull_vertices, hull_faces) in enumerate(packed.hulls):
            hull = UsdGeom.Mesh.Define(stage, f"{root}/Collision/hull_{k}")
            hull.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(np.asarray(hull_vertices, np.float32)))
            hull.CreateFaceVertexCountsAttr(Vt.IntArray([3] * len(hull_faces)))
            hull.CreateFaceVertexIndicesAttr(Vt.IntArray(np.asarray(hull_faces, np.int32).ravel().tolist()))
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


def _material(stage: Any, path: str, spec: dict[str, Any], files: list[str], images: list[Any] | None) -> Any:
    """A UsdPreviewSurface material at prim ``path``: diffuse colour or texture, normal map, opacity, Ns roughness.

    The colour map is read with ``sourceColorSpace = sRGB``, the normal map with ``raw`` and mapped from
    0..1 to -1..1 (``scale (2s, 2s, 2, 1)``, ``bias (-s, -s, -1, 0)``, ``s`` its ``-bm`` strength) into the
    surface's ``normal`` input, as the UsdPreviewSurface specification asks for tangent-space normal maps.
    ``images`` (the pack's texture bytes) is ``None`` when the mesh has no texture coordinates: then no
    texture is read at all.
    """
    from pxr import Sdf, UsdShade

    from meshtool.normalmaps import normal_map

    material = UsdShade.Material.Define(stage, path)
    shader = UsdShade.Shader.Define(stage, f"{path}/PreviewSurface")
    shader.CreateIdAttr("UsdPreviewSurface")
    kd = spec.get("colors", {}).get("Kd", [0.8, 0.8, 0.8])
    diffuse = shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f)
    diffuse.Set(tuple(float(c) for c in kd[:3]))
    shader.CreateInput("opacity", Sdf.ValueTypeNames.Float).Set(float(spec.get("scalars", {}).get("d", 1.0)))
    shininess = float(spec.get("scalars", {}).get("Ns", 10.0))
    shader.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(float(1.0 - min(shininess, 1000.0) / 1000.0))
    texture = spec.get("maps", {}).get("map_Kd")
    normal = normal_map(spec, images) if images is not None else None
    reader = None
    if images is not None and (texture is not None or normal is not None):
        reader = UsdShade.Shader.Define(stage, f"{path}/stReader")
        reader.CreateIdAttr("UsdPrimvarReader_float2")
        reader.CreateInput("varname", Sdf.ValueTypeNames.String).Set("st")  # UsdPreviewSurface: a string
    if reader is not None and texture is not None:
        image = _uv_texture(stage, f"{path}/DiffuseTexture", files[int(texture["texture"])], "sRGB", reader)
        diffuse.ConnectToSource(image.ConnectableAPI(), "rgb")
    if reader is not None and normal is not None:
        image = _uv_texture(stage, f"{path}/NormalTexture", files[normal.texture], "raw", reader)
        s = normal.scale
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


def _unique_prim_names(names: list[str], fallback: str) -> list[str]:
    """Valid and pairwise distinct prim names, in order: ``a-b`` and ``a_b`` become ``a_b`` and ``a_b_2``."""
    out: list[str] = []
    taken: set[str] = set()
    for name in names:
        base = _prim_name(name, fallback)
        candidate, n = base, 2
        while candidate in taken:
            candidate, n = f"{base}_{n}", n + 1
        taken.add(candidate)
        out.append(candidate)
    return out


def _prim_name(name: str, fallback: str) -> str:
    """A valid USD prim name: ``[A-Za-z0-9_]``, not starting with a digit."""
    text = safe_identifier(name, fallback).replace(".", "_").replace("-", "_")
    return f"_{text}" if text[:1].isdigit() else text
