"""Mesh readers: OBJ/MTL, STL, PLY, glTF/GLB and COLLADA into one in-memory model.

:func:`read_mesh` picks the reader by the file's suffix and returns an
:class:`~meshtool.read.source_mesh.SourceMesh` (every format alike), which the later stages consume the same way.
The stage's entry, :func:`meshtool.read.source_asset.read_source_asset`, reads a file with it and resolves the
MTL files it names (:class:`~meshtool.stages.SourceAsset`). What a format declares about its unit and up axis
(``SourceMesh.frame``) is weighed by the frame stage (:func:`meshtool.frame.declared.source_frame`).

What each format keeps is listed in ``docs/formats.md``.
"""

from __future__ import annotations

from pathlib import Path

from meshtool.files.resolve import Resolver
from meshtool.formats import MESH_FORMATS, mesh_format, mesh_format_named, mesh_suffixes
from meshtool.read.obj.mtl import Material
from meshtool.read.source_mesh import SourceFrame, SourceMesh

#: File suffix (lower case) -> format name (derived from :data:`meshtool.formats.MESH_FORMATS`).
FORMATS: dict[str, str] = {suffix: row.name for row in MESH_FORMATS for suffix in row.suffixes}
#: Every suffix meshtool reads as a mesh (the built-in rows; :func:`meshtool.formats.mesh_suffixes` also
#: counts formats registered later).
MESH_SUFFIXES = mesh_suffixes()

__all__ = [
    "FORMATS",
    "MESH_SUFFIXES",
    "SourceFrame",
    "SourceMesh",
    "format_of",
    "material_library",
    "placed_up",
    "read_mesh",
    "source_entries",
    "source_role",
]


def format_of(path: Path) -> str:
    """The format name of ``path`` by its suffix (``obj`` for unknown suffixes: the OBJ reader says so)."""
    row = mesh_format(path)
    return row.name if row is not None else "obj"


def placed_up(src: Path) -> str:
    """The up axis a robot description (URDF) places a mesh file of ``src``'s format with: ``y`` or ``z``.

    See :meth:`meshtool.formats.MeshFormat.placed_up`: glTF is turned Y-up to Z-up exactly as ``obj2bin`` turns
    the same file; every other format is placed as it is, in the link's Z-up frame.
    """
    row = mesh_format(src)
    return row.placed_up() if row is not None else "z"


def read_mesh(src: Path, data: bytes, path: str, resolver: Resolver) -> SourceMesh:
    """Read the mesh in ``data`` with the reader for ``src``'s suffix.

    Args:
        src: The file (its folder is the base of relative references).
        data: Its bytes, read by the resolver.
        path: Its name for findings and errors.
        resolver: The asset's resolver (glTF buffers and embedded images go through it).

    Returns:
        The :class:`SourceMesh` (``format`` names the format).

    Raises:
        MeshtoolError: ``ObjParseError`` or ``FormatError`` naming the file and line or byte offset.
    """
    row = mesh_format(src) or mesh_format_named("obj")
    result: SourceMesh = row.read()(data, path, src, resolver)
    return result


def source_role(obj: SourceMesh) -> str:
    """The ``role`` of the mesh file in ``asset.json``'s ``sources`` (``obj``, ``stl``, ``gltf``...)."""
    return obj.format


def source_entries(obj: SourceMesh, path: str, sha256: str) -> list[dict[str, str]]:
    """``asset.json`` source entries of the mesh file (role: its format) and the files it read (glTF buffers).

    Args:
        obj: The mesh as read.
        path: The mesh file as shown.
        sha256: Its SHA-256.
    """
    extra = obj.sources if obj.format != "obj" else []
    return [{"role": source_role(obj), "path": path, "sha256": sha256}, *extra]


def material_library(obj: SourceMesh, src: Path) -> dict[str, tuple[Material, Path]]:
    """The materials a non-OBJ format defines, keyed by name, as the normaliser's MTL library holds them.

    Texture references resolve relative to ``src``'s folder (the second element).
    """
    if obj.format == "obj":
        return {}
    library: dict[str, tuple[Material, Path]] = {}
    for material in obj.materials:
        library.setdefault(material.name, (material, src))
    return library
