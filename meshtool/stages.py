"""The stage records: what each of meshtool's stages hands on, in one low module.

The stages (composed in :mod:`meshtool.pipeline`, the only place they run in sequence) pass these between them,
each entry taking the record before it and returning the next, so no stage imports its neighbour's internals to
know what it receives:

1. read (:func:`meshtool.read.source_asset.read_source_asset`): the file's bytes -> :class:`SourceAsset` (the
   :class:`SourceMesh`, every format's in-memory model with :class:`SourceFrame`, what the format declares; its
   polygons as :class:`SourceTriangles`, with the vertices the output keeps; and the materials its MTL files or
   the format itself define);
2. frame (:func:`meshtool.frame.declared.decide_asset_frame`) -> :class:`FramedAsset` (the unit and up-axis
   decision, :class:`meshtool.frame.decide.Frame`, made on the kept vertices; ``Frame`` lives with the
   decision, whose consumer index it reads);
3. repair (:func:`meshtool.repair.convert.convert_asset`) -> :class:`NormalisedAsset` (a clean triangle mesh in
   metres, Z-up, PNG textures, the ``asset.json`` record);
4. hulls: :class:`HullSet`;
5. pack: :class:`PackMeta` (the ``.mbin`` META section, typed; :class:`SourceEntry` per file it was made from).

At run time this module imports only numpy and :mod:`meshtool.findings`; the element types the records hold
(materials, triangle meshes, hulls) are named for type checkers only.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from meshtool.findings import Finding

if TYPE_CHECKING:
    from meshtool.files.resolve import Resolution
    from meshtool.frame.decide import Frame
    from meshtool.frame.modelroot import ModelRootResolver
    from meshtool.hulls.compute import Hull
    from meshtool.read.obj.mtl import Material
    from meshtool.read.obj.parse import MtllibRef
    from meshtool.read.obj.triangulate import Triangulation
    from meshtool.repair.mesh import TriMesh

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]


@dataclass(frozen=True, slots=True)
class SourceFrame:
    """The unit and up axis a format declares.

    Attributes:
        unit_m: Metres per source unit (COLLADA ``<unit meter>``; 1 for glTF), ``None`` when the format has
            no unit (STL, PLY).
        unit_text: Where the unit comes from, for ``asset.json`` (``COLLADA <unit meter="0.01"
            name="centimeter"/>``).
        up: ``y`` or ``z`` (after any ``X_UP`` rotation the reader did), ``None`` when the format says nothing.
        up_text: Where the up axis comes from.
    """

    unit_m: float | None
    unit_text: str
    up: str | None
    up_text: str


@dataclass(slots=True)
class SourceMesh:
    """The read stage's record: one mesh file as read, any format, polygons not yet triangulated.

    Shapes: ``V`` vertices, ``T`` texture coordinates, ``N`` normals, ``F`` polygons, ``C`` polygon corners
    (``C = face_sizes.sum()``). Coordinates are in the file's own units and axes.

    ``face_lines``/``vertex_lines`` hold the source location of each polygon/vertex, counted in
    ``location`` units (1-based): ``line`` for text formats, ``facet`` (STL), ``face`` (PLY), ``triangle``
    (glTF, COLLADA: the running triangle number in the file).

    Attributes:
        path: Name of the file, for messages.
        positions: (V, 3) float64 vertex positions.
        colors: (V, 3) float64 vertex colours in the file's range (usually 0..1), or ``None`` when no vertex
            carries a colour; vertices without one are white.
        texcoords: (T, 2) float64 ``u v`` (a missing ``v`` is 0; ``w`` is dropped).
        normals: (N, 3) float64 normals as written (not renormalised).
        vertex_lines: (V,) source location of each vertex.
        face_sizes: (F,) corner count of each polygon (always >= 3).
        face_lines: (F,) source location of each polygon.
        face_material: (F,) index into ``material_names``, -1 before any ``usemtl``.
        face_part: (F,) index into ``part_names`` (OBJ: the current ``g`` name, else ``o`` name, else
            ``"default"``).
        corner_v: (C,) 0-based vertex index of each corner.
        corner_vt: (C,) 0-based texcoord index, -1 where the corner has none.
        corner_vn: (C,) 0-based normal index, -1 where the corner has none.
        material_names: Material names, in order of first use.
        part_names: Group/object names, in order of first appearance.
        mtllibs: Every file named by OBJ ``mtllib`` statements, in order (empty for other formats).
        header_comments: Comment lines before the first statement (without the ``#``).
        encoding: Text encoding the file was read with.
        line_endings: ``lf``, ``crlf``, ``cr`` or ``mixed``.
        findings: What the reader noticed (skipped statements, dropped attributes, ...).
        format: ``obj``, ``stl``, ``ply``, ``gltf``, ``glb`` or ``collada`` (or a plugin format's name).
        location: What ``face_lines`` count.
        materials: The definitions of ``material_names`` (same order) for formats that hold them (OBJ keeps
            its own in MTL files). Texture maps name their image by a reference the asset's resolver
            resolves: a relative URI for external images, or the name an embedded image was registered
            under (:meth:`meshtool.files.resolve.Resolver.embed`).
        frame: The declared unit and up axis.
        record: Format-specific facts (counts, encoding, generator) for tests and reports.
        sources: ``asset.json`` source entries of other files the reader read (glTF buffers: role
            ``buffer``, path as the resolver shows it, SHA-256).
    """

    path: str
    positions: FloatArray
    colors: FloatArray | None
    texcoords: FloatArray
    normals: FloatArray
    vertex_lines: IntArray
    face_sizes: IntArray
    face_lines: IntArray
    face_material: IntArray
    face_part: IntArray
    corner_v: IntArray
    corner_vt: IntArray
    corner_vn: IntArray
    material_names: list[str]
    part_names: list[str]
    mtllibs: list[MtllibRef]
    header_comments: list[str]
    encoding: str
    line_endings: str
    findings: list[Finding] = field(default_factory=list)
    format: str = "obj"
    location: str = "line"
    materials: list[Material] = field(default_factory=list)
    frame: SourceFrame = SourceFrame(None, "", None, "")
    record: dict[str, Any] = field(default_factory=dict)
    sources: list[dict[str, str]] = field(default_factory=list)


@dataclass(slots=True)
class SourceTriangles:
    """The read stage's triangles: a :class:`SourceMesh`'s polygons triangulated, nothing dropped yet.

    Shapes: ``M`` triangles, ``V`` vertices (:func:`meshtool.read.triangles.read_triangles` makes it).

    Attributes:
        tri: Which polygon corners make each triangle (``corners``, ``face``, ``lost``, ``identity``...).
        faces: (M, 3) vertex indices of every triangle (a view of ``corner_v`` when every polygon was one).
        degenerate: (M,) triangles with a repeated vertex or zero area: repair drops them.
        kept: (V,) the vertices that reach the output (:func:`meshtool.read.triangles.kept_vertices`: used by a
            triangle of non-zero area, else every finite one); the frame decides on ``positions[kept]``.
        findings: What triangulating noticed (``polygon-fanned``, ``polygon-budget``).
    """

    tri: Triangulation
    faces: IntArray
    degenerate: BoolArray
    kept: BoolArray
    findings: list[Finding]


@dataclass(slots=True)
class SourceAsset:
    r"""The read stage's record: one mesh file as read, with the material definitions it names.

    Attributes:
        src: The mesh file (its folder is the asset root).
        name: ``src``'s name as findings show it (printable: ``\xNN`` for bytes that are not UTF-8).
        mesh: The file's model, in its own units and axes.
        library: Material name -> (definition, the file whose folder its texture references resolve in): the
            MTL files' materials (first definition wins), then the format's own (glTF, COLLADA).
        resolver: How every file of the asset is reached (MTLs, textures, the model root the frame reads).
        normalised_before: The file was written by meshtool (its first header comment says so).
        findings: Everything noticed so far, in pipeline order.
        sources: ``asset.json`` source entries of the files read (the mesh, its buffers, its MTLs).
        source_paths: Each source's shown path -> the file actually read (:attr:`NormalisedAsset.source_paths`).
        resolutions: Every MTL lookup, in order.
        triangles: The polygons as triangles, with the vertices the output keeps.
    """

    src: Path
    name: str
    mesh: SourceMesh
    library: dict[str, tuple[Material, Path]]
    resolver: ModelRootResolver
    normalised_before: bool
    findings: list[Finding]
    sources: list[dict[str, str]]
    source_paths: dict[str, Path]
    resolutions: list[Resolution]
    triangles: SourceTriangles


@dataclass(slots=True)
class FramedAsset:
    """The frame stage's record: the read asset with its decided unit, scale and up axis.

    Attributes:
        source: The read stage's record.
        frame: The decision and its evidence (units, scale, up, consumers).
        findings: ``source.findings`` and the decision's findings (``frame.findings``).
    """

    source: SourceAsset
    frame: Frame
    findings: list[Finding]


@dataclass(slots=True)
class NormalisedAsset:
    r"""A normalised asset in memory.

    Attributes:
        name: Folder and file stem.
        files: Output file name to bytes (PNGs; :func:`meshtool.repair.normalise.normalise` adds ``NAME.obj``,
            ``NAME.mtl``, ``asset.json``).
        manifest: The content of ``asset.json``.
        findings: Everything noticed, in pipeline order.
        mesh: The triangle mesh in metres, Z-up, triangles ordered by material.
        materials: Output materials in the order of ``mesh.material_names``, textures renamed.
        textures: PNG file name to bytes.
        source_paths: Each source's path as ``asset.json`` shows it -> the file actually read (absolute,
            symbolic links resolved). Shown names are printable (``\xNN`` for bytes that are not UTF-8) and
            relative to the asset folder; these are the real names, for callers that look at the files again.
    """

    name: str
    files: dict[str, bytes]
    manifest: dict[str, Any]
    findings: list[Finding]
    mesh: TriMesh
    materials: list[Material]
    textures: dict[str, bytes]
    source_paths: dict[str, Path] = field(default_factory=dict)

    @property
    def stats(self) -> dict[str, Any]:
        """Counts and bounding box (see ``asset.json``)."""
        stats: dict[str, Any] = self.manifest["stats"]
        return stats


@dataclass(slots=True)
class HullSet:
    """The hulls of one asset and what was noticed making them."""

    hulls: list[Hull] = field(default_factory=list)
    findings: list[Finding] = field(default_factory=list)
    cache_hits: int = 0


#: ``asset.json`` roles of sources that hold images inside themselves (``crate.glb/name.png``).
_CONTAINERS = ("gltf", "glb")
_SEARCH_PATH = "<search-path "


@dataclass(frozen=True, slots=True)
class SourceEntry:
    """One file a pack (or an asset) was made from, as its metadata records it.

    Attributes:
        role: ``obj``, ``stl``, ``mtl``, ``texture``, ``buffer``, ``gltf``, ``glb``... (``asset.json`` roles).
        path: The path as shown: relative to the source's folder, or ``<search-path K>/REL`` for a file found
            in the K-th search path (1-based).
        sha256: Hex SHA-256 of the bytes read.
    """

    role: str
    path: str
    sha256: str


def source_entries(value: Any) -> tuple[SourceEntry, ...]:
    """The well-formed entries of a ``sources`` list (``asset.json`` or META); others are left out."""
    if not isinstance(value, list):
        return ()
    return tuple(
        SourceEntry(str(s.get("role", "")), str(s.get("path", "")), str(s.get("sha256", "")))
        for s in value
        if isinstance(s, dict) and isinstance(s.get("path"), str) and s.get("path")
    )


def file_entries(entries: Sequence[SourceEntry]) -> list[SourceEntry]:
    """The entries that are files of their own.

    Images embedded in a glTF/GLB (``crate.glb/name.png``) are not: the container's entry covers them.
    """
    containers = {s.path for s in entries if s.role in _CONTAINERS}
    return [s for s in entries if not (s.role == "texture" and s.path.split("/", 1)[0] in containers)]


def source_path(shown: str, roots: Sequence[Path]) -> Path | None:
    """The file a shown source path names.

    Args:
        shown: As :attr:`SourceEntry.path`.
        roots: The source's folder, then the search paths in order (``<search-path K>`` is ``roots[K]``).

    Returns:
        The path, or ``None`` for a search path that ``roots`` does not have.
    """
    if shown.startswith(_SEARCH_PATH):
        number, _, rel = shown[len(_SEARCH_PATH) :].partition(">/")
        k = int(number) if number.isdigit() else -1
        return roots[k] / rel if 0 < k < len(roots) else None
    return roots[0] / shown


def source_files(entries: Sequence[SourceEntry], roots: Sequence[Path]) -> list[Path]:
    """The files ``entries`` name (:func:`file_entries` only: no glTF-embedded images), as paths.

    The one answer to "which files did this pack (or asset) read": ``obj2bin``'s inputs, a URDF's mesh
    dependencies, simrun's pack cache and validate's K003 all use it. Entries in a search path ``roots``
    lacks are left out (see :func:`source_path` for ``roots``).
    """
    found = [source_path(s.path, roots) for s in file_entries(entries)]
    return [p for p in found if p is not None]


def _strings(value: Any) -> tuple[str, ...]:
    return tuple(str(v) for v in value) if isinstance(value, list) else ()


def _mapping(value: Any) -> dict[str, Any]:
    return dict(value) if isinstance(value, dict) else {}


@dataclass(frozen=True, slots=True)
class PackMeta:
    """The metadata of one ``.mbin`` (the META section; docs/mbin-spec.md lists its keys).

    Attributes:
        raw: The JSON object exactly as stored (the writer stores this; ``asset.json``'s keys included).
    """

    raw: Mapping[str, Any]

    @classmethod
    def of_asset(
        cls,
        manifest: Mapping[str, Any],
        *,
        tool: Mapping[str, Any],
        options: Mapping[str, Any] | None,
        quantization: Mapping[str, Any] | None,
        textures: Sequence[str],
        parts: Sequence[str],
        render: Mapping[str, int],
        mass_properties: Mapping[str, Any],
        hull_parts: Sequence[int],
        hull_quality: Mapping[str, Any] | None,
    ) -> PackMeta:
        """The META of a pack made from the asset with ``asset.json`` content ``manifest``.

        ``manifest``'s keys are kept but ``files``, ``format``, ``format_version`` and ``tool`` (the pack's
        own replace them); ``options`` is what made the pack (``{}`` when not given), compared by staleness
        checks; ``quantization`` is ``None`` for a lossless pack.
        """
        kept = {k: v for k, v in manifest.items() if k not in ("files", "format", "format_version", "tool")}
        return cls(
            {
                **kept,
                "format": "mbin",
                "tool": dict(tool),
                "options": dict(options or {}),
                "quantization": dict(quantization) if quantization else None,
                "textures": list(textures),
                "parts": list(parts),
                "render": dict(render),
                "mass_properties": dict(mass_properties),
                "hull_parts": list(hull_parts),
                "hull_quality": dict(hull_quality) if hull_quality is not None else None,
            }
        )

    @property
    def name(self) -> str:
        """The asset's name (file stem of ``obj2bin``'s outputs); ``""`` when not recorded."""
        value = self.raw.get("name")
        return value if isinstance(value, str) else ""

    @property
    def tool(self) -> dict[str, Any]:
        """``{"name": "meshtool", "version": ...}`` of the writer; ``{}`` when not recorded."""
        return _mapping(self.raw.get("tool"))

    @property
    def tool_version(self) -> str | None:
        """The writer's version."""
        value = self.tool.get("version")
        return value if isinstance(value, str) else None

    @property
    def options(self) -> dict[str, Any]:
        """The options that made the pack (:meth:`meshtool.pipeline.ConvertOptions.fingerprint`)."""
        return _mapping(self.raw.get("options"))

    @property
    def has_options(self) -> bool:
        """Whether ``options`` is present (an empty record still counts; a missing one never matches)."""
        return isinstance(self.raw.get("options"), dict)

    @property
    def sources(self) -> tuple[SourceEntry, ...]:
        """Every file read to make the pack, the source first (glTF-embedded images included)."""
        return source_entries(self.raw.get("sources"))

    @property
    def transform(self) -> dict[str, Any]:
        """Units, scale, up axis, rotation and the frame's evidence (``asset.json``'s ``transform``)."""
        return _mapping(self.raw.get("transform"))

    @property
    def stats(self) -> dict[str, Any]:
        """Counts and bounding box of the asset (``asset.json``'s ``stats``)."""
        return _mapping(self.raw.get("stats"))

    @property
    def textures(self) -> tuple[str, ...]:
        """PNG names in texture-section order."""
        return _strings(self.raw.get("textures"))

    @property
    def parts(self) -> tuple[str, ...]:
        """Part (group/object) names, indexed by the submesh rows' part column."""
        return _strings(self.raw.get("parts"))

    @property
    def hull_parts(self) -> tuple[int, ...]:
        """The part (index into :attr:`parts`) each hull was made from (empty: hulls of the whole mesh)."""
        value = self.raw.get("hull_parts")
        return tuple(int(v) for v in value if isinstance(v, int)) if isinstance(value, list) else ()

    @property
    def hull_quality(self) -> dict[str, Any] | None:
        """The hulls' quality report (:func:`meshtool.hulls.compute.quality`), ``None`` when not recorded."""
        value = self.raw.get("hull_quality")
        return dict(value) if isinstance(value, dict) and value else None

    @property
    def quantization(self) -> dict[str, Any]:
        """The quantisation boxes and errors; ``{}`` for a lossless pack."""
        return _mapping(self.raw.get("quantization"))

    def file_sources(self) -> list[SourceEntry]:
        """The sources that are files of their own (:func:`file_entries`)."""
        return file_entries(self.sources)

    def source_files(self, roots: Sequence[Path]) -> list[Path]:
        """The files the pack was made from, as paths (:func:`source_files`)."""
        return source_files(self.sources, roots)

    def sources_well_formed(self) -> bool:
        """Whether ``sources`` is a list of entries that each have a string path and digest."""
        value = self.raw.get("sources")
        return isinstance(value, list) and all(
            isinstance(s, dict) and isinstance(s.get("path"), str) and isinstance(s.get("sha256"), str) for s in value
        )


__all__ = [
    "HullSet",
    "NormalisedAsset",
    "PackMeta",
    "SourceEntry",
    "SourceFrame",
    "SourceMesh",
    "file_entries",
    "source_entries",
    "source_files",
    "source_path",
]
