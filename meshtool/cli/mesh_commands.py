"""The ``meshtool`` commands over one mesh or a folder of them: ``normalize``, ``obj2bin`` and ``hulls``.

Each command turns its options into the library's frozen options dataclass (:mod:`meshtool.cli.command_support`),
calls the library, and maps the outcome to output and an exit code (see :mod:`meshtool.cli.main`; the group and
its lazy loading live there). Modules only one command needs are imported by that command.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from meshtool import __version__
from meshtool.cli.command_support import (
    _check_cache,
    _guard,
    _hull_options,
    _is_folder,
    _normalise_options,
    _report,
    _summary,
    force_option,
    hull_options,
    normalise_options,
    output_dir_option,
)
from meshtool.cli.common import VocabularyCommand, batch_progress, progress_enabled, progress_option
from meshtool.cli.output import (
    EXIT_INPUT,
    failed_item,
    findings,
    findings_of,
    report,
    say,
    wrote,
)
from meshtool.errors import OptionsError
from meshtool.files.outdir import overwrite_allowed
from meshtool.findings import Severity
from meshtool.formats import suffix

if TYPE_CHECKING:
    from meshtool.pipeline import ConvertOptions, ConvertResult
    from meshtool.work.batch import Executor
    from meshtool.work.progress import TickSink


@click.command("normalize")
@click.argument("src", type=click.Path(path_type=Path, dir_okay=False))
@output_dir_option("Folder to write NAME/ into (created when missing).")
@click.option("--name", default=None, help="Output folder and file stem (default: the source stem made safe).")
@force_option
@normalise_options
def normalize(
    src: Path,
    out_dir: Path,
    name: str | None,
    force: bool,
    as_json: bool,
    **normalise_kw: Any,
) -> None:
    """Normalise SRC (OBJ, STL, PLY, glTF/GLB or COLLADA) into OUTPUT/NAME/: metres, Z-up, PNG textures."""
    from meshtool.repair.normalise import normalise_to
    from meshtool.work.progress import subject

    with _guard(as_json), overwrite_allowed(force), subject(src.name):
        options = _normalise_options(normalise_kw, name=name)
        folder, asset = normalise_to(src, out_dir, options)
    report(_report("ok", folder, asset.findings, asset.stats))
    wrote(folder, f"wrote {folder}: {_summary(asset.stats)}", kind="folder")
    findings(asset.findings)


@click.command("obj2bin", cls=VocabularyCommand, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="obj2bin")
@click.argument("src", type=click.Path(path_type=Path))  # a missing file: exit 1 (docs/cli.md)
@click.option(
    "-o",
    "--output",
    "out",
    type=click.Path(path_type=Path),
    default=None,
    help="OUT.mbin for a file (default ./STEM.mbin); the output folder for a folder (required).",
)
@click.option("--quantize", is_flag=True, help="u16 positions/uvs in their bounding box, octahedral normals.")
@click.option(
    "-j", "--jobs", type=click.IntRange(1, 64), default=1, show_default=True, help="Worker processes for a folder."
)
@click.option(
    "--executor",
    type=click.Choice(["local", "dask"]),
    default="local",
    show_default=True,
    help="Where a folder's files are converted: worker processes here, or a Dask cluster (needs dask).",
)
@click.option(
    "--scheduler", default=None, metavar="ADDRESS", help="Dask scheduler (tcp://host:8786); default: a local cluster."
)
@click.option(
    "--scheduler-timeout",
    type=click.FloatRange(0, min_open=True),
    default=30.0,
    show_default=True,
    metavar="SECONDS",
    help="How long to try reaching --scheduler.",
)
@click.option(
    "--timeout",
    type=click.FloatRange(0, min_open=True),
    default=None,
    metavar="SECONDS",
    help="Per-file limit for a folder: a file past it fails with the reason (its worker is stopped).",
)
@click.option(
    "--no-check",
    is_flag=True,
    help="Do not compile the packed asset in MuJoCo before writing it (the check needs simrun installed).",
)
@click.option(
    "--mjcf",
    "mjcf_dir",
    type=click.Path(path_type=Path, file_okay=False),
    default=None,
    help="Also (without -o: only) write a MuJoCo model as MJCF_DIR/STEM/ (STEM.xml, meshes, textures), "
    "as meshtool mjcf does.",
)
@progress_option
@force_option
@normalise_options
@hull_options
def obj2bin(
    src: Path,
    out: Path | None,
    quantize: bool,
    jobs: int,
    executor: str,
    scheduler: str | None,
    scheduler_timeout: float,
    timeout: float | None,
    no_check: bool,
    mjcf_dir: Path | None,
    show_progress: bool | None,
    force: bool,
    as_json: bool,
    **kw: Any,
) -> None:
    """Convert SRC (OBJ, STL, PLY, glTF/GLB, COLLADA; or a folder of them) to .mbin: normalised, hulls, packed."""
    from meshtool.pipeline import ConvertOptions, convert
    from meshtool.repair.normalise import safe_file_stem
    from meshtool.work.batch import Executor

    if out is None and _is_folder(src):  # a usage error (exit 2), as a missing argument is
        raise click.UsageError("a folder needs -o OUTDIR")
    if mjcf_dir is not None and _is_folder(src):
        raise click.UsageError("--mjcf takes one mesh file; for a folder: obj2bin DIR -o OUT, then meshtool mjcf OUT")
    if scheduler and executor != "dask":
        raise click.UsageError("--scheduler needs --executor dask")
    with _guard(as_json):
        hulls = _hull_options(kw)
        options = ConvertOptions(
            _normalise_options(kw), quantize, hulls, check=not no_check, check_cache=_check_cache(hulls.cache_dir)
        )
        if mjcf_dir is not None:
            _obj2bin_mjcf(src, out, mjcf_dir, options, force, as_json)
            return
        if _is_folder(src) and out is not None:
            where = Executor(executor, jobs, timeout, scheduler, scheduler_timeout)
            with batch_progress(show_progress) as progress:
                _convert_folder(src, out, options, where, as_json, force, progress)
            return
        default_name = f"{safe_file_stem(src.stem) or 'asset'}{suffix('mbin')}"
        target = out / default_name if out is not None and _is_folder(out) else out or Path(default_name)
        result = convert(src, target, options, force=force)
    report(_report("ok", result.output, result.findings, result.stats))
    wrote(result.output, f"wrote {result.output}: {_summary(result.stats)}, {result.stats['bytes']} bytes", kind="mbin")
    findings(result.findings)


def _obj2bin_mjcf(
    src: Path, out: Path | None, mjcf_dir: Path, options: ConvertOptions, force: bool, as_json: bool
) -> None:
    """``obj2bin SRC --mjcf DIR [-o OUT.mbin]``: one pack in memory, its MJCF folder, and the .mbin when asked."""
    from meshtool.mjcf.mesh_model import mesh_mjcf
    from meshtool.repair.normalise import safe_file_stem

    target = None
    if out is not None:
        target = out / f"{safe_file_stem(src.stem) or 'asset'}{suffix('mbin')}" if _is_folder(out) else out
    xml, packed, found = mesh_mjcf(src, mjcf_dir, options, force=force, mbin=target)
    shown = {"status": "ok", "output": str(xml), "mbin": str(target) if target else None}
    report({**shown, "findings": [f.to_dict() for f in found], "stats": packed.stats})
    if target is not None:
        wrote(target, f"wrote {target}: {_summary(packed.stats)}, {packed.stats['bytes']} bytes", kind="mbin")
    wrote(xml, kind="mjcf")
    findings(found)


def _convert_folder(
    src: Path,
    out: Path,
    options: ConvertOptions,
    executor: Executor,
    as_json: bool,
    force: bool,
    progress: TickSink | None = None,
) -> None:
    from meshtool.files.safeopen import printable
    from meshtool.pipeline import convert_tree, tree_jobs
    from meshtool.work.progress import Meter

    results: list[ConvertResult] = []
    total = len(tree_jobs(src, out))
    meter = Meter(total, progress)  # the batch line: files done of all, files/s, time left, the last file
    stream = convert_tree(src, out, options, force=force, executor=executor)
    quiet_lines = progress_enabled() and not as_json  # on a terminal the progress line names each file and stage
    for k, result in enumerate(stream, start=1):
        results.append(result)
        meter.advance(printable(result.source.name), computed=result.status != "unchanged")
        if not quiet_lines:
            detail = result.error if result.error else str(result.output)
            say(f"[{k}/{total}] {result.status}: {result.source} -> {detail}")
    results.sort(key=lambda r: str(r.source))
    counts = {s: sum(r.status == s for r in results) for s in ("written", "unchanged", "failed")}
    report(
        {
            "status": "error" if counts["failed"] else "ok",
            "counts": counts,
            "assets": [
                {
                    "source": str(r.source),
                    "output": str(r.output),
                    "status": r.status,
                    "error": r.error,
                    "findings": [f.to_dict() for f in r.findings],
                    "stats": r.stats,
                }
                for r in results
            ],
        }
    )
    for r in results:
        if r.status == "failed":
            failed_item(str(r.error))
    findings_of([(str(r.source), r.findings) for r in results])  # each asset's warnings under its name
    say(f"{counts['written']} written, {counts['unchanged']} unchanged, {counts['failed']} failed")
    if counts["failed"]:
        sys.exit(EXIT_INPUT)


@click.command("hulls")
@click.argument("src", type=click.Path(path_type=Path, dir_okay=False))
@normalise_options
@hull_options
def hulls(src: Path, as_json: bool, **kw: Any) -> None:
    """Compute the collision hulls of SRC (a mesh file) and report their quality; writes nothing."""
    from meshtool.hulls.compute import quality
    from meshtool.pipeline import asset_hulls, repaired_asset
    from meshtool.work.progress import subject

    with _guard(as_json), subject(src.name):
        strict = bool(kw["strict"])  # here strict judges the hulls, not the normaliser
        options = _hull_options(kw)
        asset = repaired_asset(src, _normalise_options(kw, strict=False))
        result = asset_hulls(asset.mesh, options, src.name)
        summary = quality(asset.mesh, result.hulls)
        summary["cache_hits"] = result.cache_hits
        if strict and any(f.severity is not Severity.INFO for f in result.findings):
            raise OptionsError("hull warnings in strict mode", hint="see the findings")
    report({"status": "ok", "hulls": summary, "findings": [f.to_dict() for f in result.findings]})
    say(f"{src}: {_hull_summary(summary)}")
    findings(result.findings)


def _hull_summary(report: dict[str, Any]) -> str:
    text = f"{report.get('hulls')} hull(s), vertices {report.get('vertices_per_hull')}"
    if report.get("volume_ratio") is not None:
        text += f", hull/mesh volume {report['volume_ratio']:.2f}"
    if report.get("surface_to_hulls_max_m") is not None:
        text += f", surface gap max {report['surface_to_hulls_max_m'] * 1000:.2f} mm"
    return text
