"""``PackMeta``: the pack stage's record, the typed view of an ``.mbin``'s META section.

The writer builds one (:meth:`PackMeta.of_asset`) and stores :attr:`PackMeta.raw` as canonical JSON, so the
bytes are exactly those of the dictionary; readers get one from :attr:`meshtool.packfile.read.PackedMesh.pack_meta`
and read its typed fields instead of ``meta["..."]`` keys. A foreign or hostile META (wrong types, missing
keys) reads as empty fields, never as an exception: :mod:`meshtool.packfile.verify` is what judges it.

Which files a pack was made from is answered here once (:meth:`PackMeta.file_sources`,
:meth:`PackMeta.source_files`); whether they are still the same is :func:`meshtool.pipeline.source_states`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

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


__all__ = ["PackMeta", "SourceEntry", "file_entries", "source_entries", "source_files", "source_path"]
