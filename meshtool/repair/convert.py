"""Repair's entry: a framed asset as a clean triangle mesh in metres, Z-up, with PNG textures and its record.

:func:`convert_asset`: :class:`~meshtool.stages.FramedAsset` -> :class:`~meshtool.stages.NormalisedAsset`: the
triangles as read cleaned (:func:`meshtool.repair.mesh.build_mesh`), the decided unit, scale and up axis applied,
small parts fixed, materials made safe, textures converted to PNG, the ``asset.json`` manifest. Nothing here
prints or writes.
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Any

import numpy as np

from meshtool import __version__
from meshtool.changes import changes_data
from meshtool.errors import MeshtoolError, OptionsError, StrictModeError
from meshtool.files.resolve import Resolution, Resolver
from meshtool.findings import Finding, info, warning
from meshtool.formats import suffix
from meshtool.frame.units import UNIT_FACTORS, apply_scale, rotation_matrix, scale_findings, to_z_up, unit_scale
from meshtool.read.obj.mtl import Material, TextureMap, opaque_if_invisible
from meshtool.read.triangles import MAX_COORDINATE_M as MAX_COORDINATE_M
from meshtool.read.triangles import check_coordinate_range as check_coordinate_range
from meshtool.repair.mesh import DEFAULT_MATERIAL, TriMesh, build_mesh, unique_names
from meshtool.repair.options import NormaliseOptions, safe_file_stem
from meshtool.repair.smallparts import fix_small_parts
from meshtool.repair.texroles import tag_textures
from meshtool.repair.textures import to_png
from meshtool.stages import FramedAsset, NormalisedAsset

#: Smallest extent (largest bounding-box side) a mesh may have after --units and --scale, metres.
MIN_EXTENT_M = 1e-9


def convert_asset(framed: FramedAsset, options: NormaliseOptions) -> NormalisedAsset:
    """Repair's conversion: the framed asset in metres, Z-up, with safe materials, PNG textures and its record.

    Args:
        framed: The frame stage's record: the read asset (its triangles are cleaned here, as
            :func:`meshtool.repair.mesh.build_mesh` does) and the decision.
        options: ``units`` (whether a unit was given, for the size findings), ``name`` (the output stem;
            ``None``: the source's) and ``strict`` (warnings refuse the asset).

    Returns:
        The normalised asset: mesh, materials, PNG textures (also in ``files``), manifest and every finding.

    Raises:
        MeshtoolError: A coordinate beyond the limit in the decided unit (``ObjParseError``,
            :func:`meshtool.read.triangles.check_coordinate_range`), units or scale
            that collapse the mesh (``OptionsError``), or warnings in strict mode (``StrictModeError``).
    """
    source = framed.source
    obj, src, resolver, source_name = source.mesh, source.src, source.resolver, source.name
    frame, library = framed.frame, source.library
    mesh, mesh_findings = build_mesh(obj, source.triangles)
    if mesh.faces.shape[0] == 0:
        mesh_findings.append(
            warning(
                "no-faces",
                f"no faces: {mesh.positions.shape[0]} points kept (usable for a convex hull only)",
                source_name,
            )
        )
    # the file's findings, the mesh's, then the frame's: the order ``asset.json`` has always recorded
    findings = [*source.findings, *mesh_findings, *frame.findings]
    units, up = frame.units, frame.up
    check_coordinate_range(obj, units, frame.scale)
    sources = [*source.sources, *frame.sources(src.parent)]
    source_paths = dict(source.source_paths)
    resolutions = list(source.resolutions)
    source_extent = float(np.ptp(mesh.positions, axis=0).max())
    mesh.positions = to_z_up(apply_scale(mesh.positions, units, frame.scale), up) + 0.0  # no -0.0
    check_extent(source_extent, float(np.ptp(mesh.positions, axis=0).max()), units, frame.scale, source_name)
    mesh.normals = to_z_up(mesh.normals, up) + 0.0
    findings.extend(fix_small_parts(mesh, source_name))

    name = (options.name and safe_file_stem(options.name)) or safe_file_stem(src.stem) or "asset"
    files: dict[str, bytes] = {}
    used = set(mesh.material_names) & set(library)
    unused = [m for m in library if m not in used]
    if unused:
        findings.append(
            info(
                "materials-unused",
                f"{len(unused)} material(s) defined but not used: not written",
                source_name,
            )
        )
    if library or obj.material_names:
        out_materials, textures = _materials(
            mesh, library, resolver, source_name, findings, resolutions, (sources, source_paths), files
        )
        findings.extend(f for m in out_materials if (f := opaque_if_invisible(m, source_name)) is not None)
        tag_textures(out_materials, files)  # colour maps sRGB, data maps linear, in the PNG itself
    else:  # no mtllib and no usemtl: a plain mesh, no MTL written
        out_materials, textures = [], []
    stats = _stats(mesh, len(out_materials), len(textures))
    unit_given = options.units not in (None, "auto") or frame.units != "m"
    explicit = options.units if options.units in UNIT_FACTORS else None
    applied = unit_scale(units) * frame.scale
    extent = np.asarray(stats["bbox"]["extent"])
    findings.extend(scale_findings(extent, source_name, unit_given, frame.evidence, applied, explicit))
    manifest = {
        "format": "meshtool-asset",
        "format_version": 1,
        "tool": {"name": "meshtool", "version": __version__},
        "name": name,
        "sources": sources,
        "transform": {
            "units": units,
            "unit_scale": unit_scale(units),
            "scale": frame.scale,
            "up": up,
            "rotation": rotation_matrix(up),
            **frame.record(),
            "note": "x_out = rotation @ (x_src * unit_scale * scale); output is metres, Z-up, right-handed",
        },
        "stats": stats,
        "materials": [{"name": m.name, "textures": {k: t.file for k, t in m.maps.items()}} for m in out_materials],
        "resolutions": [
            {
                "ref": r.ref,
                "kind": r.kind,
                "from": f"{r.origin}:{r.line}",
                "found": resolver.display(r.found, resolved=True) if r.found else None,
                "rule": r.rule,
            }
            for r in resolutions
        ],
        "findings": [f.to_dict() for f in findings],
    }
    warnings = [f for f in findings if changes_data(f)]
    if options.strict and warnings:
        raise StrictModeError(
            f"{len(warnings)} warning(s) in strict mode, first: {warnings[0].one_line()}",
            path=source_name,
            hint="fix the input or drop --strict",
        )
    textures_out = {n: files[n] for n in textures}
    return NormalisedAsset(name, files, manifest, findings, mesh, out_materials, textures_out, source_paths)


def check_extent(source: float, scaled: float, units: str, scale: float, path: str) -> None:
    """Refuse units/scale that shrink a mesh with some size to under :data:`MIN_EXTENT_M` across.

    ``.mbin`` positions are float32 and every consumer works in metres: ``--scale 1e-300`` would collapse
    every vertex to 0 (a mesh whose source has no size at all is left to the geometry findings).

    Args:
        source: Largest bounding-box side of the mesh as read, in source units.
        scaled: The same in metres, after ``units`` and ``scale``.
        units: The unit applied.
        scale: The extra scale applied.
        path: The file, for the message.

    Raises:
        OptionsError: ``scaled`` is under :data:`MIN_EXTENT_M` while ``source`` is not 0.
    """
    if source > 0.0 and scaled < MIN_EXTENT_M:
        raise OptionsError(
            f"the mesh is {scaled:.3g} m across after units {units} and scale {scale:g}, under the "
            f"{MIN_EXTENT_M:g} m minimum: float32 positions would collapse its vertices",
            path=path,
            hint="pass a larger --scale or the right --units",
        )


def _materials(
    mesh: TriMesh,
    library: dict[str, tuple[Material, Path]],
    resolver: Resolver,
    source_name: str,
    findings: list[Finding],
    resolutions: list[Resolution],
    sources: tuple[list[dict[str, str]], dict[str, Path]],
    files: dict[str, bytes],
) -> tuple[list[Material], list[str]]:
    """Output materials (safe names, textures converted and renamed) in first-use order.

    ``sources``: the ``asset.json`` source entries and :attr:`NormalisedAsset.source_paths`, both extended.
    """
    out_names = unique_names(mesh.material_names, "material")
    converted: dict[Path, tuple[str | None, Path | None, str | None]] = {}
    texture_names: set[str] = set()
    out: list[Material] = []
    for source_material, out_name in zip(mesh.material_names, out_names, strict=True):
        entry = library.get(source_material)
        if entry is None:
            if library or source_material != DEFAULT_MATERIAL:
                findings.append(
                    warning(
                        "material-undefined",
                        f"material {source_material!r} is not defined in any MTL: grey default used",
                        source_name,
                    )
                )
            out.append(Material(out_name, 0, colors={"Kd": (0.8, 0.8, 0.8)}, illum=1))
            continue
        material, mtl_file = entry
        clean = Material(out_name, material.line, dict(material.colors), dict(material.scalars), material.illum)
        origin = resolver.display(mtl_file, resolved=True)
        for key, rgb in material.colors.items():  # colours are 0..1 (MuJoCo, glTF, the .mbin spec)
            if not all(0.0 <= c <= 1.0 for c in rgb):
                clean.colors[key] = (min(max(rgb[0], 0.0), 1.0), min(max(rgb[1], 0.0), 1.0), min(max(rgb[2], 0.0), 1.0))
                findings.append(
                    warning(
                        "material-color-clamped",
                        f"material {source_material!r}: {key} {' '.join(f'{c:g}' for c in rgb)} is outside 0..1; "
                        f"clamped to {' '.join(f'{c:g}' for c in clean.colors[key])}",
                        origin,
                        material.line or None,
                    )
                )
        for key, tex in material.maps.items():
            res = resolver.resolve(tex.file, mtl_file.parent, "texture", origin, tex.line)
            resolutions.append(res)
            findings.extend(res.findings)
            if res.found is None:
                continue
            looked_up = res.found
            if looked_up not in converted:
                name = _convert_texture(res, resolver, findings, sources, files, texture_names)
                converted[looked_up] = (name, res.found, res.refused)
            written, res.found, res.refused = converted[looked_up]  # one file, read once, recorded alike
            if res.refused is not None:
                res.rule = "refused"
            if written is not None:
                clean.maps[key] = TextureMap(written, dict(tex.options), tex.line)
        out.append(clean)
    return out, sorted(texture_names)


def _convert_texture(
    res: Resolution,
    resolver: Resolver,
    findings: list[Finding],
    sources: tuple[list[dict[str, str]], dict[str, Path]],
    files: dict[str, bytes],
    taken: set[str],
) -> str | None:
    """Read and convert the texture ``res`` found; ``res`` then records the file read, or the refusal."""
    assert res.found is not None
    shown = resolver.display(res.found, resolved=True)
    try:
        data = resolver.read_resolution(res, "texture")
    except MeshtoolError as exc:
        findings.append(warning("texture-unreadable", f"{exc.message}: map dropped", shown))
        return None
    assert res.found is not None
    found = res.found
    shown = resolver.display(found, resolved=True)
    sources[0].append({"role": "texture", "path": shown, "sha256": _sha256(data)})
    sources[1][shown] = found
    try:
        png = to_png(data, shown)
    except MeshtoolError as exc:
        findings.append(warning("texture-unreadable", f"{exc.message}: map dropped", shown))
        return None
    findings.extend(png.findings)
    stem = safe_file_stem(found.stem) or "texture"
    out_name, n = f"{stem}{suffix('png')}", 2
    while out_name in taken:
        out_name, n = f"{stem}_{n}{suffix('png')}", n + 1
    taken.add(out_name)
    files[out_name] = png.data
    if png.converted:
        findings.append(
            info(
                "texture-converted",
                f"{png.source_format} {png.source_mode} {png.size[0]}x{png.size[1]} converted to 8-bit {png.mode} PNG "
                f"{out_name}",
                shown,
            )
        )
    return out_name


def _stats(mesh: TriMesh, materials: int, textures: int) -> dict[str, Any]:
    p = mesh.positions
    lo = p.min(axis=0) if p.size else np.zeros(3)
    hi = p.max(axis=0) if p.size else np.zeros(3)
    return {
        "vertices": int(p.shape[0]),
        "triangles": int(mesh.faces.shape[0]),
        "texcoords": int(mesh.texcoords.shape[0]),
        "normals": int(mesh.normals.shape[0]),
        "vertex_colors": mesh.colors is not None,
        "materials": materials,
        "textures": textures,
        "parts": len(set(mesh.face_part.tolist())),
        "source_polygons": mesh.source_polygons,
        "degenerate_dropped": mesh.degenerate,
        "bbox": {"min": (lo + 0.0).tolist(), "max": (hi + 0.0).tolist(), "extent": (hi - lo + 0.0).tolist()},
    }


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()
