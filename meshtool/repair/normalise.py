"""The normaliser: one OBJ (with its MTLs and textures) in, one clean, self-contained asset folder out.

Stages: read the OBJ through the resolver -> parse -> resolve and parse MTLs -> build a clean triangle mesh
-> convert to metres and Z-up -> resolve textures and convert them to PNG -> write ``NAME.obj``,
``NAME.mtl``, the PNGs and ``asset.json``. :func:`normalise` does everything but the writing and returns
the files in memory; :func:`write_asset` writes them atomically. Nothing here prints.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import re
import unicodedata
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from meshtool import __version__
from meshtool.changes import changes_data
from meshtool.errors import MeshtoolError, ObjParseError, OptionsError, OutputError, StrictModeError
from meshtool.export.obj_write import format_obj
from meshtool.files.outdir import write_folder
from meshtool.files.resolve import Resolution, Resolver, printable
from meshtool.findings import Finding, info, warning
from meshtool.formats import MTL_SUFFIX, suffix
from meshtool.frame.modelroot import model_root_resolver
from meshtool.frame.units import UNIT_FACTORS, apply_scale, rotation_matrix, scale_findings, to_z_up, unit_scale
from meshtool.read import material_library, read_mesh, source_entries, source_frame
from meshtool.read.obj.mtl import Material, TextureMap, format_mtl, opaque_if_invisible, parse_mtl
from meshtool.read.source_mesh import SourceMesh
from meshtool.repair.mesh import DEFAULT_MATERIAL, TriMesh, build_mesh, unique_names
from meshtool.repair.smallparts import fix_small_parts
from meshtool.repair.texroles import tag_textures
from meshtool.repair.textures import to_png
from meshtool.stages import NormalisedAsset as NormalisedAsset
from meshtool.work.progress import report as report_progress

_MARKER = re.compile(r"^meshtool \S+ normalized OBJ: units=m up=z\b")
#: Largest vertex coordinate magnitude, metres, after ``--units`` and ``--scale`` (1000 km). Beyond it the
#: file is refused: such coordinates are a wrong unit or corrupt data, qhull cannot hull them, and float32
#: (the ``.mbin`` positions) keeps less than a decimetre of precision there and overflows past 3.4e38.
MAX_COORDINATE_M = 1e6
#: Smallest extent (largest bounding-box side) a mesh may have after --units and --scale, metres.
MIN_EXTENT_M = 1e-9
_SAFE_FILE_CHARS = re.compile(r"[^a-z0-9_.-]+")


@dataclass(frozen=True, slots=True)
class NormaliseOptions:
    """Options of :func:`normalise` (the fields of ``meshtool normalize``).

    Attributes:
        units: Unit of the source coordinates; ``None`` means metres (or, for a file meshtool wrote,
            what its header says).
        scale: Extra uniform scale applied after the unit conversion.
        up: Up axis of the source; ``None`` means ``y`` (the OBJ convention), or ``z`` for a file meshtool
            wrote.
        name: Output folder and file stem; ``None`` derives it from the source file name.
        search_paths: Extra folders references may resolve into.
        strict: Fail instead of writing when there are warnings.
        confine: Read every file the source references from beneath this folder, without following links
            (see :class:`meshtool.files.resolve.Resolver`); ``None``: the asset folder and search paths are roots.
        model_root: ``--model-root``: the folder at or above the source that is its model root (references
            may resolve inside it; its description files are searched for the source's consumers); ``None``:
            found (:func:`meshtool.frame.modelroot.find_model_root`, :func:`meshtool.frame.consumers.find_index_root`).
    """

    units: str | None = None
    scale: float = 1.0
    up: str | None = None
    name: str | None = None
    search_paths: tuple[Path, ...] = ()
    strict: bool = False
    confine: Path | None = None
    model_root: Path | None = None

    def __post_init__(self) -> None:
        if self.units is not None and self.units not in UNIT_FACTORS and self.units != "auto":
            raise OptionsError(f"unknown unit {self.units!r}", hint=f"use one of {', '.join(UNIT_FACTORS)} or auto")
        if self.up is not None and self.up not in ("y", "z", "auto"):
            raise OptionsError(f"unknown up axis {self.up!r}", hint="use y, z or auto")
        if not (math.isfinite(self.scale) and self.scale > 0):
            raise OptionsError(f"scale must be a positive finite number, got {self.scale!r}")
        if self.name is not None and not safe_file_stem(self.name):
            raise OptionsError(f"name {self.name!r} has no usable characters", hint="use letters, digits, _ . -")


def safe_file_stem(text: str) -> str:
    """A file stem made of ``[a-z0-9_.-]``: accents stripped, lower case, other runs become ``_``."""
    ascii_text = unicodedata.normalize("NFKD", text).encode("ascii", "ignore").decode("ascii").lower()
    return _SAFE_FILE_CHARS.sub("_", ascii_text).strip("_.-")


def normalise(src: Path, options: NormaliseOptions | None = None) -> NormalisedAsset:
    """Normalise one OBJ file and everything it references, in memory.

    :func:`prepare`, then the OBJ, MTL and ``asset.json`` files are added to ``files``.

    Args:
        src: The OBJ file (see :func:`prepare`).
        options: See :class:`NormaliseOptions`.

    Returns:
        The output files and findings.

    Raises:
        MeshtoolError: See :func:`prepare`.
    """
    asset = prepare(src, options)
    name = asset.name
    material_file = f"{name}{MTL_SUFFIX}" if asset.materials else None
    header = f"meshtool {__version__} normalized OBJ: units=m up=z"
    obj_text = format_obj(asset.mesh, [m.name for m in asset.materials], material_file, header)
    asset.files[f"{name}{suffix('obj')}"] = obj_text.encode("utf-8")
    if material_file:
        mtl_text = format_mtl(asset.materials, f"meshtool {__version__} materials for {name}{suffix('obj')}")
        asset.files[material_file] = mtl_text.encode("utf-8")
    manifest = {
        **{k: v for k, v in asset.manifest.items() if k != "findings"},
        "files": {"obj": f"{name}{suffix('obj')}", "mtl": material_file, "textures": sorted(asset.textures)},
        "findings": asset.manifest["findings"],
    }
    asset.files["asset.json"] = (json.dumps(manifest, indent=1, ensure_ascii=False) + "\n").encode("utf-8")
    asset.manifest = manifest
    return asset


def prepare(src: Path, options: NormaliseOptions | None = None, *, data: bytes | None = None) -> NormalisedAsset:
    """Read, repair and convert one OBJ and everything it references, in memory, without formatting it.

    The result holds the triangle mesh (metres, Z-up), the output materials, the PNG textures (also in
    ``files``) and the manifest; :func:`normalise` and the ``.mbin`` packer format it.

    Args:
        src: The OBJ file. Its folder is the asset root: references never resolve outside it except into
            ``options.search_paths``.
        options: See :class:`NormaliseOptions`.
        data: The bytes of ``src`` when the caller has already read them race-free (the URDF importer reads
            each mesh beneath its package with :meth:`meshtool.files.resolve.Resolver.read_real`); else read here.

    Returns:
        The output files and findings.

    Raises:
        MeshtoolError: The OBJ cannot be read or converted (the message names file and line), or
            ``strict`` is set and there are warnings.
    """
    options = options or NormaliseOptions()
    resolver, root_findings = model_root_resolver(
        src, options.search_paths, confine=options.confine, model_root=options.model_root
    )
    source_name = printable(src.name)
    data = resolver.read_source(src) if data is None else data
    obj = read_mesh(src, data, source_name, resolver)  # OBJ, STL, PLY, glTF/GLB or COLLADA
    findings = [*obj.findings, *root_findings]
    sources: list[dict[str, str]] = source_entries(obj, source_name, _sha256(data))  # the file, glTF buffers
    source_paths = {source_name: _real(src)}
    resolutions: list[Resolution] = []

    normalised_before = any(_MARKER.match(c) for c in obj.header_comments[:1])
    if normalised_before and options.up in (None, "auto"):
        findings.append(info("already-normalized", "file was written by meshtool: read as metres, Z-up", source_name))

    library: dict[str, tuple[Material, Path]] = {}
    for ref in obj.mtllibs:
        res = resolver.resolve(ref.name, src.parent, "mtl", source_name, ref.line)
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
    given = options.units if options.units in UNIT_FACTORS else None
    check_coordinate_range(obj, given, options.scale)  # before any arithmetic on absurd values
    mesh, mesh_findings = build_mesh(obj)
    findings.extend(mesh_findings)
    if mesh.positions.shape[0] == 0:
        raise ObjParseError(
            "no geometry: the file defines no usable vertices", path=source_name, hint="export the mesh again"
        )
    if mesh.faces.shape[0] == 0:
        findings.append(
            warning(
                "no-faces",
                f"no faces: {mesh.positions.shape[0]} points kept (usable for a convex hull only)",
                source_name,
            )
        )
    frame = source_frame(
        obj,
        src,
        mesh.positions,
        options.units,
        options.scale,
        options.up,
        resolver.model_root,
        normalised_before,
    )
    units, up = frame.units, frame.up
    check_coordinate_range(obj, units, frame.scale)
    findings.extend(frame.findings)
    sources.extend(frame.sources(src.parent))
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


def check_coordinate_range(obj: SourceMesh, units: str | None, scale: float) -> None:
    """Refuse vertex coordinates beyond :data:`MAX_COORDINATE_M` once converted to metres.

    Only vertices that reach the output are checked (those faces use, or all of them when there are no
    faces); non-finite ones are left to :func:`meshtool.repair.mesh.build_mesh`, which names them.

    Args:
        obj: The parsed OBJ (coordinates in ``units``).
        units: Unit of the coordinates (a key of :data:`meshtool.frame.units.UNIT_FACTORS`), or ``None`` when it
            is not decided yet: then only coordinates beyond the limit in every unit are refused.
        scale: The extra uniform scale.

    Raises:
        ObjParseError: Naming the line of the first vertex out of range.
    """
    positions = obj.positions
    if positions.shape[0] == 0:
        return
    factor = (unit_scale(units) if units else min(unit_scale(u) for u in UNIT_FACTORS)) * scale
    with np.errstate(over="ignore", invalid="ignore"):
        metres = np.abs(positions) * factor
        beyond = (metres > MAX_COORDINATE_M) & np.isfinite(positions)
    rows = beyond.any(axis=1)
    if obj.corner_v.size:
        used = np.zeros(positions.shape[0], dtype=bool)
        used[obj.corner_v] = True
        rows &= used
    if not rows.any():
        return
    k = int(np.flatnonzero(rows)[0])
    value = float(positions[k][beyond[k]][0])
    if units is None:
        shown = " in any unit"
    elif units != "m" or scale != 1.0:
        shown = f" ({float(metres[k][beyond[k]][0]):.4g} m in {units}, scale {scale:g})"
    else:
        shown = ""
    raise ObjParseError(
        f"vertex {k + 1} has the coordinate {value:.6g}{shown}, beyond the limit of +-{MAX_COORDINATE_M:g} m",
        path=obj.path,
        line=int(obj.vertex_lines[k]),
        hint="pass the right --units or a smaller --scale, or fix the coordinate; recentre georeferenced models",
        code="coordinate-range",
    )


def write_asset(asset: NormalisedAsset, out_dir: Path, src: Path | None = None) -> Path:
    """Write a normalised asset to ``out_dir/NAME/`` atomically.

    Args:
        asset: From :func:`normalise`.
        out_dir: Parent folder (created when missing).
        src: The source OBJ; writing is refused when the target folder would contain it.

    Returns:
        The asset folder.

    Raises:
        OutputError: See :func:`meshtool.files.outdir.write_folder`; also when the target holds the source.
    """
    target = (out_dir / asset.name).resolve()
    if src is not None:
        source_dir = src.resolve().parent
        if target == source_dir or target in source_dir.parents:
            raise OutputError(
                "the output folder would contain the source files",
                path=str(out_dir / asset.name),
                hint="write to a folder outside the source asset",
            )
    return write_folder(out_dir, asset.name, asset.files)


def normalise_to(src: Path, out_dir: Path, options: NormaliseOptions | None = None) -> tuple[Path, NormalisedAsset]:
    """:func:`normalise` then :func:`write_asset`; returns the folder and the asset."""
    report_progress("reading and normalising")
    asset = normalise(src, options)
    report_progress("writing")
    return write_asset(asset, out_dir, src), asset


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


def _real(path: Path) -> Path:
    """``path`` with symbolic links resolved; as it is (absolute) when a link changes under the lookup."""
    try:
        return Path(os.path.realpath(path))
    except (OSError, ValueError):
        return Path(os.path.abspath(path))


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()
