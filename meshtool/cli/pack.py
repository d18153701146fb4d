"""The ``.mbin`` pack commands: ``meshtool info``, ``unpack`` and ``export``.

Thin click commands over :mod:`meshtool.packfile`; errors and exit codes as in :mod:`meshtool.cli.command_support`.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import click

from meshtool.cli.command_support import _guard, force_option, output_dir_option
from meshtool.cli.mesh_commands import _hull_summary
from meshtool.cli.output import findings, report, say, wrote
from meshtool.errors import PackFormatError
from meshtool.files.outdir import check_output, write_folder, write_output


@click.command("info")
@click.argument("file", type=click.Path(path_type=Path, dir_okay=False))
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
def info(file: Path, as_json: bool) -> None:
    """Describe an .mbin file: counts, sections, sizes, checksums and metadata."""
    from meshtool.packfile import load
    from meshtool.packfile.export import describe

    with _guard(as_json), load(file, verify=True) as packed:  # every read of the file's content, META too
        summary = describe(packed)
    report(summary)
    say("\n".join(_info_lines(file, summary)))


def _info_lines(file: Path, summary: dict[str, Any]) -> list[str]:
    lines = [
        f"{file}: mbin {summary['version']}{' quantized' if summary['quantized'] else ''}, "
        f"{summary['vertices']} vertices, {summary['triangles']} triangles ({summary['index_type']}), "
        f"{summary['submeshes']} submesh(es), {len(summary['materials'])} material(s), "
        f"{len(summary['textures'])} texture(s), {summary['hulls']} hull(s)"
    ]
    for s in summary["sections"]:
        shape = "x".join(str(d) for d in s["shape"])
        lines.append(
            f"  {s['kind']:<5}{s['index']:>3} {s['dtype']:>5} {shape:>12} at {s['offset']:>10} "
            f"{s['bytes']:>10} bytes {s['encoding']:>11}  {summary['checksum_algorithm']} {s['crc']} {s['checksum']}"
        )
    from meshtool.packfile.meta import PackMeta

    meta = PackMeta(summary["meta"])
    if meta.hull_quality:
        lines.append(f"  hulls: {_hull_summary(meta.hull_quality)}")
    t = meta.transform
    lines.append(
        f"  source units {t.get('units')} (x{t.get('unit_scale')}), scale {t.get('scale')}, up {t.get('up')}; "
        f"tool {meta.tool.get('version')}"
    )
    return lines


@click.command("unpack")
@click.argument("file", type=click.Path(path_type=Path, dir_okay=False))
@output_dir_option("Folder to write NAME/ into.")
@force_option
def unpack(file: Path, out_dir: Path, force: bool) -> None:
    """Turn an .mbin back into OBJ/MTL/PNG in OUTPUT/NAME/."""
    from meshtool.packfile import load
    from meshtool.packfile.export import unpack_files
    from meshtool.repair.normalise import safe_file_stem

    with _guard(False), load(file, verify=True) as packed:
        name = safe_file_stem(file.stem) or "asset"
        files = unpack_files(packed, name)
        files["asset.json"] = (json.dumps(packed.meta, indent=1, ensure_ascii=False) + "\n").encode("utf-8")
        folder = write_folder(out_dir, name, files, force=force, inputs=[file])
    wrote(folder, f"wrote {folder}: {', '.join(sorted(files))}", kind="folder")


@click.command("export")
@click.argument("file", type=click.Path(path_type=Path, dir_okay=False))
@click.option("--glb", type=click.Path(path_type=Path, dir_okay=False), default=None, help="Write glTF binary.")
@click.option("--msh", type=click.Path(path_type=Path, dir_okay=False), default=None, help="Write MuJoCo MSH.")
@click.option(
    "--usd",
    type=click.Path(path_type=Path, dir_okay=False),
    default=None,
    help="Write USD (.usda/.usdc), PNG textures beside it.",
)
@force_option
def export(file: Path, glb: Path | None, msh: Path | None, usd: Path | None, force: bool) -> None:
    """Export an .mbin as GLB, MuJoCo's legacy MSH and/or USD."""
    from meshtool.packfile import load
    from meshtool.packfile.export import to_glb, to_msh
    from meshtool.packfile.usd import export_usd
    from meshtool.repair.normalise import safe_file_stem
    from meshtool.repair.normalmaps import export_findings

    if glb is None and msh is None and usd is None:
        raise click.UsageError("give --glb, --msh and/or --usd")
    targets = [p for p in (glb, msh, usd) if p is not None]
    if len({os.path.normcase(os.path.abspath(p)) for p in targets}) != len(targets):
        raise click.UsageError("--glb, --msh and --usd must name different files")
    with _guard(False), load(file, verify=True) as packed:
        for path, kind, make in ((glb, "glb", to_glb), (msh, "msh", to_msh)):
            if path is not None:
                data = _made(make, packed, file)
                write_output(path, data, kind, force=force, inputs=[file])
                wrote(path, f"wrote {path} ({len(data)} bytes)", kind=kind, bytes=len(data))
                if kind == "glb":
                    findings(export_findings(packed, "glb"))  # maps glTF has no slot for
        if usd is not None:
            check_output(usd, "usd", force=force, inputs=[file])
            names = list(packed.pack_meta.textures)
            for name, texture in zip(names, packed.textures, strict=True):  # the PNGs written beside the USD
                check_output(usd.parent / name, None, force=force, inputs=[file], data=bytes(texture))
            written = export_usd(packed, usd, safe_file_stem(file.stem) or "asset")
            wrote(
                written[0], f"wrote {', '.join(str(p) for p in written)}", kind="usd", files=[str(p) for p in written]
            )
            findings(export_findings(packed, "usd"))


def _made(make: Callable[[Any], bytes], packed: Any, file: Path) -> bytes:
    """``make(packed)``, with a texture Pillow cannot decode reported as an input error (exit 1).

    Loading verifies a texture's PNG signature only; decoding it is the exporter's first touch of the image.
    """
    from PIL import Image, UnidentifiedImageError

    try:
        return make(packed)
    except PackFormatError as exc:  # the exporter's own refusal: name the file when it could not
        if exc.path is not None:
            raise
        raise PackFormatError(exc.message, path=str(file), hint=exc.hint) from None
    except (UnidentifiedImageError, Image.DecompressionBombError, OSError) as exc:
        raise PackFormatError(
            f"a texture cannot be decoded as an image ({type(exc).__name__}: {exc})",
            path=str(file),
            hint="re-pack the asset from a valid image",
        ) from None
