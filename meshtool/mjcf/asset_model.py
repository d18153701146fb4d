"""MJCF output: a MuJoCo model per ``.mbin`` asset, following MuJoCo Menagerie's conventions.

Default classes ``visual`` (group 2, no contacts, massless) and ``collision`` (group 3); one visual geom
per submesh with its material; one collision geom per stored hull with ``inertia="convex"``; textures as
PNG files; mesh data as MuJoCo's binary ``.msh`` files beside the XML. The body's mass comes from the
collision geoms only: from ``density``, or split by hull volume so the body weighs exactly ``mass``.

meshtool does not import MuJoCo: this module describes the model (:class:`meshtool.mjcf.model_desc.ModelDesc`) and
the installed MJCF builder (simrun's) builds it on ``MjSpec``, writes it and compiles the written folder.
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from meshtool.errors import OptionsError
from meshtool.files.outdir import write_folder
from meshtool.findings import Finding
from meshtool.formats import suffix
from meshtool.hulls import surface
from meshtool.mjcf.model_desc import (
    BodyDesc,
    GeomDesc,
    IntArray,
    MaterialDesc,
    MeshDesc,
    ModelDesc,
    TextureDesc,
)
from meshtool.packfile.read import PackedMesh
from meshtool.packfile.view import asset_view, unique_names
from meshtool.plugins import mjcf_files
from meshtool.repair.mesh import safe_identifier
from meshtool.repair.normalmaps import mujoco_findings


@dataclass(frozen=True, slots=True)
class MjcfOptions:
    """Options of ``meshtool mjcf``.

    Attributes:
        free_joint: Give the body a free joint (it falls and can be pushed); else it is fixed to the world.
        density: Density of the collision geometry, kg/m^3 (ignored when ``mass`` is given).
        mass: Total body mass in kg, split over the collision hulls by volume.
        max_hull_vertices: ``maxhullvert`` written on every mesh.
    """

    free_joint: bool = False
    density: float = 1000.0
    mass: float | None = None
    max_hull_vertices: int = 64

    def __post_init__(self) -> None:
        if not self.density > 0 or (self.mass is not None and not self.mass > 0) or self.max_hull_vertices < 4:
            raise OptionsError("density and mass must be positive, max hull vertices at least 4")


@dataclass(slots=True)
class MeshParts:
    """The model pieces of one packed mesh, for a model that places them somewhere.

    Attributes:
        meshes, textures, materials: Assets, every name starting with the prefix.
        visual: One visual geom per submesh (at the origin).
        collision: One collision geom per hull (at the origin).
        volumes: Volume of each hull, m^3.
    """

    meshes: list[MeshDesc] = field(default_factory=list)
    textures: list[TextureDesc] = field(default_factory=list)
    materials: list[MaterialDesc] = field(default_factory=list)
    visual: list[GeomDesc] = field(default_factory=list)
    collision: list[GeomDesc] = field(default_factory=list)
    volumes: list[float] = field(default_factory=list)


def mesh_parts(packed: PackedMesh, prefix: str, max_hull_vertices: int = 64, keep_small: bool = False) -> MeshParts:
    """Meshes, materials, textures and geoms of ``packed``, every name starting with ``prefix``.

    Submeshes with fewer than 4 vertices (which MuJoCo refuses) are left out unless ``keep_small``.
    """
    parts = MeshParts()
    view = asset_view(packed)
    texture_names = unique_names(f"{prefix}_{safe_identifier(t.stem, f'tex{k}')}" for k, t in enumerate(view.textures))
    parts.textures = [TextureDesc(name, t.data) for name, t in zip(texture_names, view.textures, strict=True)]
    names = unique_names(f"{prefix}_{safe_identifier(m.name, f'material{k}')}" for k, m in enumerate(view.materials))
    for name, m in zip(names, view.materials, strict=True):
        texture = texture_names[m.colour_map] if m.colour_map is not None else None
        parts.materials.append(MaterialDesc(name, m.rgba, texture))
    for part in view.parts:
        if len(part.positions) < 4 and not keep_small:
            continue  # MuJoCo needs 4 vertices for a mesh; a lone triangle is not worth a geom
        name = f"{prefix}_visual_{part.index}"
        tris: IntArray = part.faces.astype(np.int32)
        parts.meshes.append(MeshDesc(name, part.positions, tris, part.normals, part.uvs, "shell"))
        mat = parts.materials[part.material].name if parts.materials else None
        parts.visual.append(GeomDesc("visual", "mesh", mesh=name, material=mat))
    for k, (hull_vertices, hull_faces) in enumerate(packed.hulls):
        name = f"{prefix}_collision_{k}"
        vertices = np.asarray(hull_vertices, np.float64)
        hull_tris: IntArray = np.asarray(hull_faces, np.int32)
        parts.meshes.append(MeshDesc(name, vertices, hull_tris, inertia="convex", max_hull_vertices=max_hull_vertices))
        parts.collision.append(GeomDesc("collision", "mesh", mesh=name))
        parts.volumes.append(surface.volume(vertices, hull_tris))  # trimesh's formula, bit-identical
    return parts


def asset_model(packed: PackedMesh, name: str, options: MjcfOptions | None = None) -> ModelDesc:
    """The model of one asset: a body (free or fixed) with visual geoms and collision hulls.

    Raises:
        OptionsError: The file has no collision hulls (pack it with ``--hulls`` other than ``none``).
    """
    options = options or MjcfOptions()
    if not packed.hulls:
        raise OptionsError("the .mbin has no collision hulls", hint="convert it with obj2bin --hulls convex")
    model_name = safe_identifier(name, "asset")
    parts = mesh_parts(packed, model_name, options.max_hull_vertices)
    total = sum(parts.volumes)
    for k, geom in enumerate(parts.collision):
        if options.mass is not None:
            geom.mass = options.mass * parts.volumes[k] / total
        else:
            geom.density = options.density
    body = BodyDesc(model_name, free=options.free_joint, geoms=[*parts.visual, *parts.collision])
    return ModelDesc(model_name, parts.meshes, parts.textures, parts.materials, bodies=[body])


def build_mjcf(packed: PackedMesh, name: str, options: MjcfOptions | None = None) -> dict[str, bytes]:
    """The files of a MuJoCo model for one asset: ``NAME.xml``, meshes (``.msh``) and PNG textures.

    The installed MJCF builder writes and compiles them before they are returned.

    Raises:
        OptionsError: The file has no collision hulls.
        ModelError: No MJCF builder is installed, or MuJoCo refuses the model.
    """
    return mjcf_files(asset_model(packed, name, options))


def write_mjcf(
    packed: PackedMesh,
    out_dir: Path,
    name: str,
    source: Path,
    options: MjcfOptions | None = None,
    *,
    force: bool | None = None,
    inputs: Iterable[Path] = (),
) -> tuple[Path, list[Finding]]:
    """Write the MuJoCo model of one packed asset as ``out_dir/NAME/`` (atomically) and return its XML file.

    The one path from a pack to an MJCF folder: ``meshtool mjcf`` (an ``.mbin`` or a mesh file) and
    ``obj2bin --mjcf`` both call it. The folder holds ``NAME.xml``, the meshes (``.msh``), the PNG textures
    and ``asset.json`` naming ``source``; MuJoCo loads it from the folder alone.

    Args:
        packed: The asset.
        out_dir: Folder to write ``NAME/`` into (created when missing).
        name: Folder and model name (``[a-z0-9_.-]+``).
        source: The file the pack came from (recorded in ``asset.json``).
        options: Body options.
        force: See :func:`meshtool.files.outdir.write_folder`.
        inputs: Files this run read: the folder may not replace one.

    Returns:
        The written ``NAME.xml`` and the findings about MuJoCo's use of the asset (``mujoco-ignores-map``).

    Raises:
        OptionsError: The pack has no collision hulls.
        ModelError: No MJCF builder is installed, or MuJoCo refuses the model.
        OutputError: The folder cannot be written or would replace something meshtool did not write.
    """
    files = build_mjcf(packed, name, options)
    told = mujoco_findings(packed.materials, source.name)
    manifest = json.dumps({"source": str(source)}).encode()
    folder = write_folder(out_dir, name, {**files, "asset.json": manifest}, force=force, inputs=[source, *inputs])
    return folder / (safe_identifier(name, "asset") + suffix("mjcf")), told
