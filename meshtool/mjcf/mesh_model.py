"""A mesh file straight to a MuJoCo model (``obj2bin SRC --mjcf OUT/``, ``meshtool mjcf SRC``).

The one path: the mesh is packed in memory as ``obj2bin`` packs it (:func:`meshtool.pipeline.pack_file`), and
the pack's MJCF folder written as every pack's is (:func:`meshtool.mjcf.asset_model.write_mjcf`).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from meshtool.files.outdir import check_output, refuse_inputs, write_file
from meshtool.findings import Finding
from meshtool.mjcf.asset_model import MjcfOptions, write_mjcf
from meshtool.packfile import parse
from meshtool.pipeline import ConvertOptions, Packed, pack_file
from meshtool.repair.normalise import safe_file_stem


def mesh_mjcf(
    src: Path,
    out_dir: Path,
    convert_options: ConvertOptions | None = None,
    options: MjcfOptions | None = None,
    *,
    force: bool | None = None,
    mbin: Path | None = None,
) -> tuple[Path, Packed, list[Finding]]:
    """A mesh file straight to a MuJoCo model: ``obj2bin SRC --mjcf OUT/`` and ``meshtool mjcf SRC``.

    ``src`` is packed in memory as ``obj2bin`` packs it (:func:`meshtool.pipeline.pack_file`) and its MJCF
    folder written by :func:`write_mjcf` as ``out_dir/STEM/``; with ``mbin`` the same pack is also written
    there. The pack is not compiled in MuJoCo on its own: the MJCF builder compiles the written folder.

    Returns:
        The written ``STEM.xml``, the pack, and every finding (the conversion's, then MuJoCo's use of it).

    Raises:
        MeshtoolError: The input cannot be converted, MuJoCo refuses the model, or an output is refused.
    """
    if mbin is not None:
        refuse_inputs(mbin, [src])  # before any work
    made = pack_file(src, replace(convert_options or ConvertOptions(), check=False))
    name = safe_file_stem(src.stem) or "asset"
    xml, told = write_mjcf(parse(made.data, src.name), out_dir, name, src, options, force=force, inputs=made.inputs)
    if mbin is not None:
        check_output(mbin, "mbin", force=force, inputs=[src, *made.inputs], data=made.data)
        write_file(mbin, made.data)
    return xml, made, [*made.findings, *told]
