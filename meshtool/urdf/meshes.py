"""The meshes of a URDF: read, scaled (mirroring included), hulled and packed once per file and scale.

Every mesh goes through the normaliser's readers (:mod:`meshtool.read`): OBJ with its MTL, STL, PLY,
glTF/GLB and COLLADA, in memory (no intermediate files). COLLADA and glTF keep their colours and textures
(their images are read through the resolver, inside the package); a broken image reference keeps the
geometry and drops the texture with a finding. The mesh's own frame: the URDF places meshes as they are
(Z-up, no rotation) except glTF, which is Y-up by its specification and turned to Z-up as ``obj2bin`` turns
it (:func:`meshtool.read.placed_up`); a COLLADA ``<unit>`` is applied before the URDF ``scale``, as ROS
tools do.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from meshtool.files.safeopen import printable
from meshtool.findings import Finding
from meshtool.formats import suffix
from meshtool.hulls.compute import Hull, HullOptions, quality
from meshtool.mjcf.asset_model import MeshParts, mesh_parts
from meshtool.packfile.read import parse
from meshtool.pipeline import asset_hulls, pack_asset, repaired_asset
from meshtool.read import placed_up
from meshtool.repair.mesh import safe_identifier
from meshtool.repair.normalise import NormalisedAsset, NormaliseOptions, safe_file_stem
from meshtool.repair.normalmaps import mujoco_findings
from meshtool.urdf.locate import FoundMesh, UrdfError

Scale = tuple[float, float, float]


@dataclass(slots=True)
class LoadedMesh:
    """One mesh file at one scale, packed.

    Attributes:
        prefix: Name prefix of its model assets.
        parts: Its meshes, materials, textures and geoms.
        mbin: The ``.mbin`` bytes.
        own_materials: Whether the file brought its own materials (else the URDF's colour applies).
    """

    prefix: str
    parts: MeshParts
    mbin: bytes
    own_materials: bool


def parse_scale(scale: Any) -> Scale | None:
    """``(sx, sy, sz)`` of a URDF ``scale`` (one or three numbers), ``None`` when zero or not finite."""
    if scale is None:
        return (1.0, 1.0, 1.0)
    values = np.atleast_1d(np.asarray(scale, dtype=float))
    if values.size == 1:
        values = np.repeat(values, 3)
    if values.size != 3 or not np.all(np.isfinite(values)) or np.any(values == 0):
        return None
    return (float(values[0]), float(values[1]), float(values[2]))


def load_mesh(mesh: FoundMesh, scale: Scale, prefix: str, hulls: HullOptions) -> tuple[LoadedMesh, list[Finding]]:
    """Scale, hull and pack ``mesh`` (read by :class:`meshtool.urdf.locate.MeshLocator`, inside its root).

    A uniform positive scale goes through the normaliser; any other (mirroring or non-uniform) is applied
    to the normalised mesh: positions scaled, normals by the inverse transpose, and the triangle winding
    reversed when the scale mirrors, so faces keep pointing outwards.

    Raises:
        UrdfError: The file cannot be read or has no triangles.
        MeshtoolError: The normaliser's own error.
    """
    found = mesh.path
    s = np.asarray(scale, dtype=float)
    uniform = bool(np.all(s > 0) and np.ptp(s) <= 1e-12 * float(s.max()))
    stem = safe_file_stem(found.stem) or "mesh"
    scale_now = float(s[0]) if uniform else 1.0
    options = NormaliseOptions(
        up=placed_up(found), scale=scale_now, name=stem, search_paths=(mesh.root,), confine=mesh.root
    )
    findings: list[Finding] = []
    try:
        asset = repaired_asset(found, options, data=mesh.data)
    except OSError as exc:  # a folder above the mesh changed while its companions were looked up
        raise UrdfError(
            f"mesh {found.name!r} changed while it was being read ({exc.strerror or type(exc).__name__}); not read",
            path=printable(found),
            hint="do not modify the robot's files while meshtool reads them",
        ) from None
    own = any(m.name != "default" for m in asset.materials)
    if not uniform:
        asset = _scaled(asset, s)
    hull_set = asset_hulls(asset.mesh, hulls, found.name)
    report = quality(asset.mesh, hull_set.hulls) if hull_set.hulls else None
    findings += [*asset.findings, *hull_set.findings, *mujoco_findings(asset.materials, found.name)]
    meta = {"urdf_scale": [float(v) for v in s], "hulls": hulls.fingerprint()}
    data = pack_asset(asset, list(hull_set.hulls), meta, report)
    parts = mesh_parts(parse(data, f"{prefix}{suffix('mbin')}"), prefix, hulls.max_hull_vertices)
    return LoadedMesh(prefix, parts, data, own), findings


def _scaled(asset: NormalisedAsset, s: np.ndarray) -> NormalisedAsset:
    mesh = asset.mesh
    positions = mesh.positions * s
    normals = mesh.normals / s
    lengths = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = np.divide(normals, lengths, out=np.zeros_like(normals), where=lengths > 0)
    faces, face_uv, face_normal = mesh.faces, mesh.face_uv, mesh.face_normal
    if np.prod(np.sign(s)) < 0:  # a mirror: reverse the winding so faces point outwards again
        faces, face_uv, face_normal = faces[:, ::-1].copy(), face_uv[:, ::-1].copy(), face_normal[:, ::-1].copy()
    scaled = dataclasses.replace(
        mesh, positions=positions, normals=normals, faces=faces, face_uv=face_uv, face_normal=face_normal
    )
    manifest = dict(asset.manifest)
    stats = dict(manifest.get("stats", {}))
    if len(positions):
        lo, hi = positions.min(axis=0), positions.max(axis=0)
        stats["bbox"] = {"min": lo.tolist(), "max": hi.tolist(), "extent": (hi - lo).tolist()}
    manifest["stats"] = stats
    return dataclasses.replace(asset, mesh=scaled, manifest=manifest)


def mesh_sources(found: Path, root: Path, mbin: bytes) -> set[Path]:
    """The mesh file and every file its pack's metadata lists as read (MTL, textures), as paths.

    ``root``: the package root, the one search path the mesh was read with (:func:`load_mesh`).
    """
    with parse(mbin, found.name, verify=False) as packed:
        return {found, *packed.pack_meta.source_files([found.parent, root])}


def mesh_prefix(found: Path, taken: set[str]) -> str:
    """A model-asset prefix for a mesh file, unique among ``taken`` (which it joins)."""
    prefix = safe_identifier(safe_file_stem(found.stem) or "mesh", "mesh")
    while prefix in taken:
        prefix += "_"
    taken.add(prefix)
    return prefix


__all__ = ["Hull", "LoadedMesh", "UrdfError", "load_mesh", "mesh_prefix", "mesh_sources", "parse_scale"]
