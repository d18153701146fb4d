"""The read stage's entry: a mesh file's bytes and the MTL files it names -> :class:`~meshtool.stages.SourceAsset`.

:func:`read_source_asset` reads the file with the reader of its format (:func:`meshtool.read.read_mesh`), then
resolves and parses every ``mtllib`` through the asset's resolver, and collects the material definitions the
later stages use (an OBJ's from its MTL files, other formats' from the file itself), then refuses absurd
coordinates and triangulates the polygons as read (:func:`meshtool.read.triangles.read_triangles`: the triangles,
which have zero area, the vertices the output keeps). Nothing is dropped, scaled or turned here; the composer
(:mod:`meshtool.pipeline`) hands the record to the frame stage, which decides on the kept vertices.
"""

from __future__ import annotations

import hashlib
import os
import re
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from meshtool.errors import ObjParseError
from meshtool.files.resolve import Resolution, printable
from meshtool.findings import Finding, info
from meshtool.frame.units import UNIT_FACTORS
from meshtool.read import material_library, read_mesh, source_entries
from meshtool.read.obj.mtl import Material, parse_mtl
from meshtool.read.triangles import check_coordinate_range, read_triangles
from meshtool.stages import SourceAsset

if TYPE_CHECKING:
    from meshtool.frame.modelroot import ModelRootResolver

#: The first header comment of an OBJ meshtool wrote (``meshtool normalize``): metres, Z-up.
NORMALISED_MARKER = re.compile(r"^meshtool \S+ normalized OBJ: units=m up=z\b")


def read_source_asset(
    src: Path,
    resolver: ModelRootResolver,
    *,
    data: bytes | None = None,
    up: str | None = None,
    units: str | None = None,
    scale: float = 1.0,
    notes: Sequence[Finding] = (),
) -> SourceAsset:
    """Read ``src`` (OBJ, STL, PLY, glTF/GLB, COLLADA) and the MTL files it names.

    Args:
        src: The mesh file. References resolve relative to its folder (and where ``resolver`` allows).
        resolver: The asset's resolver (:func:`meshtool.frame.modelroot.model_root_resolver`).
        data: The bytes of ``src`` when the caller has already read them race-free (the URDF importer); else
            read here through ``resolver``.
        up: ``--up``: a file meshtool wrote is noted (``already-normalized``) as read in metres, Z-up unless
            ``up`` names an axis.
        units: ``--units``: a named unit bounds the coordinates (:func:`meshtool.read.triangles.check_coordinate_range`;
            ``auto`` or ``None`` refuses only coordinates beyond the limit in every unit).
        scale: ``--scale``, for the same bound.
        notes: Findings about the asset made before reading (the ``model-root`` finding), recorded after the
            reader's own.

    Returns:
        The record: the mesh in the file's units and axes, its triangles, material library, sources and findings.

    Raises:
        MeshtoolError: The file cannot be read (``ObjParseError``/``FormatError`` naming file and line or
            offset; ``ResolveError`` for a file that cannot be opened), a coordinate is out of range or a face
            uses a non-finite vertex, or no vertex is usable (``ObjParseError``).
    """
    name = printable(src.name)
    data = resolver.read_source(src) if data is None else data
    obj = read_mesh(src, data, name, resolver)
    findings = [*obj.findings, *notes]
    sources: list[dict[str, str]] = source_entries(obj, name, _sha256(data))  # the file, glTF buffers
    source_paths = {name: _real(src)}
    resolutions: list[Resolution] = []

    normalised_before = any(NORMALISED_MARKER.match(c) for c in obj.header_comments[:1])
    if normalised_before and up in (None, "auto"):
        findings.append(info("already-normalized", "file was written by meshtool: read as metres, Z-up", name))

    library: dict[str, tuple[Material, Path]] = {}
    for ref in obj.mtllibs:
        res = resolver.resolve(ref.name, src.parent, "mtl", name, ref.line)
        resolutions.append(res)
        findings.extend(res.findings)
        if res.found is None:
            continue
        mtl_bytes = resolver.read_resolution(res, "mtl")  # res.found: the file actually read
        assert res.found is not None
        shown = resolver.display(res.found, resolved=True)
        sources.append({"role": "mtl", "path": shown, "sha256": _sha256(mtl_bytes)})
        source_paths[shown] = res.found
        mtl = parse_mtl(mtl_bytes, shown)
        findings.extend(mtl.findings)
        for material in mtl.materials:
            library.setdefault(material.name, (material, res.found))
    library.update(material_library(obj, src))  # materials of formats other than OBJ
    check_coordinate_range(obj, units if units in UNIT_FACTORS else None, scale)  # before any arithmetic on them
    triangles = read_triangles(obj)
    findings.extend(triangles.findings)
    if not triangles.kept.any():
        raise ObjParseError("no geometry: the file defines no usable vertices", path=name, hint="export the mesh again")
    return SourceAsset(
        src, name, obj, library, resolver, normalised_before, findings, sources, source_paths, resolutions, triangles
    )


def _real(path: Path) -> Path:
    """``path`` with symbolic links resolved; as it is (absolute) when a link changes under the lookup."""
    try:
        return Path(os.path.realpath(path))
    except (OSError, ValueError):
        return Path(os.path.abspath(path))


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()
