"""The meshes of a URDF: read, scaled (mirroring included), hulled and packed once per file and scale.

OBJ files are read with their MTL; STL/PLY/OFF/GLB/COLLADA through trimesh.

COLLADA and other scene files keep their colours and textures: trimesh reads them, writes them as an OBJ
with its MTL and PNGs into a scratch folder, and the normaliser reads that like any OBJ. A COLLADA file
whose image reference is broken keeps its geometry (the texture is dropped with a finding).
"""

from __future__ import annotations

import dataclasses
import io
import tempfile
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import trimesh

from meshtool.errors import MeshtoolError
from meshtool.findings import Finding, warning
from meshtool.hulls import Hull, HullOptions, compute_hulls, quality
from meshtool.mesh import safe_identifier
from meshtool.mjcf import MeshParts, mesh_parts
from meshtool.normalise import NormalisedAsset, NormaliseOptions, prepare, safe_file_stem
from meshtool.outdir import write_file
from meshtool.packfile import pack
from meshtool.packfile.read import parse
from meshtool.resolve import Resolver

MESH_TYPES = (".obj", ".stl", ".ply", ".dae", ".off", ".glb")
Scale = tuple[float, float, float]


class UrdfError(MeshtoolError, ValueError):
    """The URDF cannot be imported (bad XML, a missing or escaping mesh, an unsupported construct)."""


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


def load_mesh(
    found: Path, root: Path, scale: Scale, prefix: str, hulls: HullOptions
) -> tuple[LoadedMesh, list[Finding]]:
    """Read, scale, hull and pack ``found`` (a file inside ``root``).

    A uniform positive scale goes through the normaliser; any other (mirroring or non-uniform) is applied
    to the normalised mesh: positions scaled, normals by the inverse transpose, and the triangle winding
    reversed when the scale mirrors, so faces keep pointing outwards.

    Raises:
        UrdfError: The file cannot be read or has no triangles.
        MeshtoolError: The normaliser's own error.
    """
    s = np.asarray(scale, dtype=float)
    uniform = bool(np.all(s > 0) and np.ptp(s) <= 1e-12 * float(s.max()))
    stem = safe_file_stem(found.stem) or "mesh"
    options = NormaliseOptions(up="z", scale=float(s[0]) if uniform else 1.0, name=stem, search_paths=(root,))
    findings: list[Finding] = []
    if found.suffix.lower() == ".obj":
        asset = prepare(found, options)
        own = any(m.name != "default" for m in asset.materials)
    else:
        asset, own, notes = _foreign(found, root, options)
        findings += notes
    if not uniform:
        asset = _scaled(asset, s)
    hull_set = compute_hulls(asset.mesh, hulls, found.name)
    report = quality(asset.mesh, hull_set.hulls) if hull_set.hulls else None
    findings += [*asset.findings, *hull_set.findings]
    meta = {"urdf_scale": [float(v) for v in s], "hulls": hulls.fingerprint()}
    data = pack(asset, False, meta, list(hull_set.hulls), report)
    parts = mesh_parts(parse(data, f"{prefix}.mbin"), prefix, hulls.max_hull_vertices)
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


def _foreign(found: Path, root: Path, options: NormaliseOptions) -> tuple[NormalisedAsset, bool, list[Finding]]:
    """STL/PLY/OFF/GLB/COLLADA through trimesh, written as OBJ + MTL + PNGs and normalised like an OBJ."""
    data = Resolver(root).read(found)
    kind = found.suffix.lower()[1:]
    findings: list[Finding] = []
    missing: list[str] = []

    def resolve(name: str) -> bytes:
        target = (found.parent / name.replace("\\", "/")).resolve()
        if not Resolver(root).inside(target) or not target.is_file():
            missing.append(name)
            raise FileNotFoundError(name)
        return Resolver(root).read(target)

    resolver = _CallbackResolver(resolve)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            loaded = trimesh.load(io.BytesIO(data), file_type=kind, resolver=resolver, process=False)
    except Exception as exc:  # trimesh and pycollada raise many types for unreadable files
        raise UrdfError(
            f"trimesh cannot read it: {str(exc).splitlines()[0] if str(exc) else type(exc).__name__}", path=str(found)
        ) from None
    meshes = _meshes_of(loaded)
    if not meshes:
        raise UrdfError("has no triangles", path=str(found))
    for name in sorted(set(missing)):
        findings.append(
            warning("texture-missing", f"image {name!r} is missing; the texture is dropped, geometry kept", str(found))
        )
    own = any(_has_material(m) for m in meshes)
    if not own:
        for m in meshes:
            m.visual = trimesh.visual.ColorVisuals(m)
    scene = trimesh.Scene(meshes)
    text, extra = trimesh.exchange.obj.export_obj(  # type: ignore[no-untyped-call]
        scene, include_normals=True, include_texture=own, return_texture=True, mtl_name=f"{options.name}.mtl"
    )
    with tempfile.TemporaryDirectory(prefix="meshtool-urdf-") as tmp:
        scratch = Path(tmp) / f"{options.name}.obj"
        write_file(scratch, str(text).encode("utf-8"))
        for name, blob in (extra or {}).items():
            write_file(Path(tmp) / name, bytes(blob))
        asset = prepare(scratch, dataclasses.replace(options, search_paths=()))
    return asset, own, findings


class _CallbackResolver(trimesh.resolvers.Resolver):
    """A trimesh resolver that reads through meshtool's :class:`Resolver` (never outside the root)."""

    def __init__(self, read: Any) -> None:
        self._read = read

    def get(self, name: str) -> bytes:
        data: bytes = self._read(name)
        return data

    def write(self, name: str, data: bytes) -> None:
        raise OSError("read-only")

    def namespaced(self, namespace: str) -> _CallbackResolver:
        return _CallbackResolver(lambda name: self._read(f"{namespace}/{name}"))

    def keys(self) -> Any:
        return iter(())


def _meshes_of(loaded: Any) -> list[trimesh.Trimesh]:
    """Every triangle mesh of a loaded file, placed by its scene graph."""
    if isinstance(loaded, trimesh.Trimesh):
        return [loaded] if len(loaded.faces) else []
    if isinstance(loaded, trimesh.Scene):
        out = []
        for node in loaded.graph.nodes_geometry:
            transform, name = loaded.graph[node]
            geometry = loaded.geometry.get(name)
            if isinstance(geometry, trimesh.Trimesh) and len(geometry.faces):
                placed = geometry.copy()
                placed.apply_transform(transform)
                out.append(placed)
        return out
    return []


def _has_material(mesh: trimesh.Trimesh) -> bool:
    visual = mesh.visual
    if isinstance(visual, trimesh.visual.TextureVisuals):
        return visual.material is not None
    return False


def mesh_prefix(found: Path, taken: set[str]) -> str:
    """A model-asset prefix for a mesh file, unique among ``taken`` (which it joins)."""
    prefix = safe_identifier(safe_file_stem(found.stem) or "mesh", "mesh")
    while prefix in taken:
        prefix += "_"
    taken.add(prefix)
    return prefix


__all__ = ["MESH_TYPES", "Hull", "LoadedMesh", "UrdfError", "load_mesh", "mesh_prefix", "parse_scale"]
