"""USD export of ``.mbin`` assets: UsdGeom meshes, UsdPreviewSurface materials, PNG textures, collision hulls.

Built with the project's one USD writer (:class:`meshtool.export.usd_write.UsdBuilder`), as the world and recording
exports are. The stage is Z-up with ``metersPerUnit = 1`` (the pack's frame, written as it is). Each submesh
becomes a ``UsdGeom.Mesh`` ``/NAME/Geom/submesh_K`` with normals and ``primvars:st``, bound to a material
(``/NAME/Materials/MATERIAL``, names made valid and unique) whose ``UsdPreviewSurface`` reads its PNG
through ``UsdUVTexture`` (the PNGs are written beside the USD file). Collision hulls become ``UsdGeom.Mesh``
prims ``/NAME/Collision/hull_K`` with purpose ``guide``, ``UsdPhysics.CollisionAPI`` and
``UsdPhysics.MeshCollisionAPI`` (approximation ``convexHull``).
"""

from __future__ import annotations

from pathlib import Path

from meshtool.export.usd_write import UsdBuilder, prim_name
from meshtool.files.outdir import write_file
from meshtool.packfile.read import PackedMesh
from meshtool.packfile.view import PartMaterial, asset_view


def export_usd(packed: PackedMesh, out: Path, name: str) -> list[Path]:
    """Write ``out`` (``.usda``, ``.usdc`` or ``.usd``) and the PNG textures it references beside it.

    Args:
        packed: The asset.
        out: The stage file.
        name: The root prim's name (sanitised; ``asset`` when nothing valid is left).

    Returns:
        Every file written.

    Raises:
        OutputError: An unsupported extension or a write failure.
    """
    with UsdBuilder(out, prim_name(name, "asset")) as usd:
        view = asset_view(packed)
        written: list[Path] = []
        for texture in view.textures:
            target = out.parent / texture.file
            write_file(target, texture.data)
            written.append(target)
        materials = []
        for spec in view.materials:
            path = usd.child(usd.group(usd.root, "Materials"), spec.name, "material")
            materials.append(
                usd.material(
                    path,
                    spec.diffuse,
                    spec.alpha,
                    _roughness(spec),
                    view.textures[spec.colour_map].file if spec.colour_map is not None else None,
                    view.textures[spec.normal_map].file if spec.normal_map is not None else None,
                    spec.normal_scale,
                )
            )
        for part in view.parts:
            mesh = usd.mesh(
                usd.child(usd.group(usd.root, "Geom"), f"submesh_{part.index}"),
                part.positions,
                part.faces,
                part.normals,
                part.uvs,
            )
            if materials:
                usd.bind(mesh, materials[part.material])
        for k, (vertices, faces) in enumerate(view.hulls):
            hull = usd.mesh(usd.child(usd.group(usd.root, "Collision"), f"hull_{k}"), vertices, faces)
            usd.purpose(hull, guide=True)
            usd.collider(hull, convex_hull=True)
        usd.save()
    written.append(out)
    return written


def _roughness(spec: PartMaterial) -> float:
    """UsdPreviewSurface roughness from the MTL shininess ``Ns`` (0..1000; 10 when unstated): ``1 - Ns / 1000``."""
    shininess = float(spec.record.get("scalars", {}).get("Ns", 10.0))
    return float(1.0 - min(shininess, 1000.0) / 1000.0)
