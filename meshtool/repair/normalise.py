"""``meshtool normalize``'s public functions: one mesh file (with its MTLs and textures) in, one asset folder out.

:func:`normalise` runs the stages read -> repair (mesh) -> frame -> repair (conversion) through the composer
(:func:`meshtool.pipeline.repaired_asset`) and formats the result as ``NAME.obj``, ``NAME.mtl``, the PNGs and
``asset.json``, in memory; :func:`write_asset` writes them atomically. Nothing here prints.

This module sits above the composer (it imports :mod:`meshtool.pipeline`, which imports none of it): the stages
themselves are :mod:`meshtool.read.source_asset`, :mod:`meshtool.repair.convert` and :mod:`meshtool.frame.declared`.
The options, limits and checks are re-exported here under the names callers have always imported.
"""

from __future__ import annotations

import json
from pathlib import Path

from meshtool import __version__
from meshtool.errors import OutputError
from meshtool.export.obj_write import format_obj
from meshtool.files.outdir import write_folder
from meshtool.formats import MTL_SUFFIX, suffix
from meshtool.pipeline import repaired_asset
from meshtool.read.obj.mtl import format_mtl
from meshtool.repair.convert import MAX_COORDINATE_M as MAX_COORDINATE_M
from meshtool.repair.convert import MIN_EXTENT_M as MIN_EXTENT_M
from meshtool.repair.convert import check_coordinate_range as check_coordinate_range
from meshtool.repair.convert import check_extent as check_extent
from meshtool.repair.options import NormaliseOptions as NormaliseOptions
from meshtool.repair.options import safe_file_stem as safe_file_stem
from meshtool.stages import NormalisedAsset as NormalisedAsset
from meshtool.work.progress import report as report_progress


def normalise(src: Path, options: NormaliseOptions | None = None) -> NormalisedAsset:
    """Normalise one mesh file and everything it references, in memory.

    :func:`prepare`, then the OBJ, MTL and ``asset.json`` files are added to ``files``.

    Args:
        src: The mesh file (see :func:`prepare`).
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
    """Read, repair and convert one mesh file and everything it references, in memory, without formatting it.

    The composer's :func:`meshtool.pipeline.repaired_asset` under its old name: the result holds the triangle
    mesh (metres, Z-up), the output materials, the PNG textures (also in ``files``) and the manifest;
    :func:`normalise` and the ``.mbin`` packer format it.

    Args:
        src: The mesh file. Its folder is the asset root: references never resolve outside it except into
            ``options.search_paths`` (or the model root).
        options: See :class:`NormaliseOptions`.
        data: The bytes of ``src`` when the caller has already read them race-free (the URDF importer reads
            each mesh beneath its package with :meth:`meshtool.files.resolve.Resolver.read_real`); else read here.

    Returns:
        The output files and findings.

    Raises:
        MeshtoolError: The file cannot be read or converted (the message names file and line), or
            ``strict`` is set and there are warnings.
    """
    return repaired_asset(src, options or NormaliseOptions(), data=data)


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
