"""The ``meshtool`` commands (the group and its lazy loading live in :mod:`meshtool.cli.main`).

Each command turns its options into the library's frozen options dataclass, calls the library, and maps
the outcome to output and an exit code (see :mod:`meshtool.cli.main`). Modules only one command needs (MJCF,
URDF, GLB/USD export) are imported by that command.
"""

from __future__ import annotations

import contextlib
import os
import stat
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from meshtool import __version__
from meshtool.cli.common import VocabularyCommand, batch_progress, progress_enabled, progress_option
from meshtool.cli.output import (
    EXIT_INPUT,
    exit_on_bug,
    fail,
    failed_item,
    findings,
    findings_of,
    report,
    say,
    told_once,
    wrote,
)
from meshtool.errors import MeshtoolError, OptionsError
from meshtool.files.outdir import overwrite_allowed
from meshtool.files.resolve import find_files
from meshtool.findings import Finding, Severity
from meshtool.formats import mesh_suffixes, suffix
from meshtool.hulls.options import MODES, PRESETS, HullOptions

#: The --units names (meshtool.frame.units.UNIT_FACTORS, which imports numpy; tests/test_perf_startup.py checks
#: they agree). Start-up (issue 28): the library is imported inside each command, so ``--help`` stays light.
UNITS = ("m", "cm", "mm", "in", "ft")

if TYPE_CHECKING:
    from meshtool.pipeline import ConvertOptions, ConvertResult
    from meshtool.repair.normalise import NormaliseOptions
    from meshtool.work.batch import Executor
    from meshtool.work.progress import TickSink

force_option = click.option(
    "--force",
    is_flag=True,
    help="Replace an existing output that meshtool did not write (an input is never replaced).",
)


def output_dir_option(help_text: str) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """The required ``-o/--output`` folder option (``out_dir``), with the command's own help."""
    return click.option(
        "-o",
        "--output",
        "out_dir",
        required=True,
        type=click.Path(path_type=Path, file_okay=False),
        help=help_text,
    )


def normalise_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """The normaliser's options, shared by ``meshtool normalize`` and ``obj2bin``."""
    decorators = [
        click.option(
            "--units",
            type=click.Choice([*UNITS, "auto"]),
            default=None,
            help="Unit the source was modelled in (default m); auto: what a URDF/SDF/MJCF using the mesh says.",
        ),
        click.option("--scale", type=float, default=1.0, show_default=True, help="Extra uniform scale after --units."),
        click.option(
            "--up",
            type=click.Choice(["auto", "y", "z"]),
            default="auto",
            show_default=True,
            help="Up axis of the source: y (rotated to Z-up), z (kept) or auto (from evidence; see docs/findings.md).",
        ),
        click.option(
            "--search-path",
            "search_paths",
            multiple=True,
            type=click.Path(path_type=Path, file_okay=False),
            help="Extra folder where MTL and texture references may resolve (repeatable).",
        ),
        click.option(
            "--model-root",
            type=click.Path(path_type=Path, file_okay=False, exists=True),
            default=None,
            help="Folder at or above the mesh holding its models: references resolve inside it, and its "
            "URDF/SDF/MJCF files are searched for the mesh's consumers (default: found; docs/findings.md).",
        ),
        click.option("--strict", is_flag=True, help="Fail (exit 1) instead of writing when there are warnings."),
        click.option("--json", "as_json", is_flag=True, help="Print one JSON object on stdout instead of text."),
    ]
    for decorator in reversed(decorators):
        func = decorator(func)
    return func


def hull_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """Collision-hull options of ``obj2bin``."""
    decorators = [
        click.option(
            "--hulls",
            "hull_mode",
            type=click.Choice(list(MODES)),
            default="convex",
            show_default=True,
            help="none; convex (one hull); decompose (CoACD per part); objects (one hull per o/g part).",
        ),
        click.option(
            "--preset",
            type=click.Choice(list(PRESETS)),
            default=None,
            help="Budgets for an engine: mujoco (32 hulls x 64 vertices), mjx (8 x 32), physx-gpu (16 x 64).",
        ),
        click.option("--max-hulls", type=click.IntRange(1, 4096), default=None, help="Most hulls per part."),
        click.option(
            "--max-hull-vertices",
            type=click.IntRange(4, 100000),
            default=None,
            help="Most vertices per hull (default 64).",
        ),
        click.option(
            "--min-thickness",
            type=float,
            default=0.001,
            show_default=True,
            help="Smallest hull thickness in metres (capped at 5 % of the part's size).",
        ),
        click.option("--merge-parts", is_flag=True, help="Decompose the whole mesh at once, not part by part."),
        click.option("--threshold", type=float, default=0.05, show_default=True, help="CoACD concavity threshold."),
        click.option(
            "--timeout",
            "timeout_s",
            type=float,
            default=300.0,
            show_default=True,
            help="Seconds one CoACD run may take.",
        ),
        click.option(
            "--time-budget",
            "time_budget_s",
            type=click.FloatRange(min=0, min_open=True),
            default=180.0,
            show_default=True,
            help="Seconds all CoACD runs of one asset may take; parts left then get their convex hull.",
        ),
        click.option(
            "--cache-dir",
            type=click.Path(path_type=Path, file_okay=False),
            default=None,
            help="Cache of decompositions and passed MuJoCo checks (default: the user cache folder).",
        ),
        click.option("--no-cache", is_flag=True, help="Do not read or write the caches."),
    ]
    for decorator in reversed(decorators):
        func = decorator(func)
    return func


def _normalise_options(kw: dict[str, Any], **overrides: Any) -> NormaliseOptions:
    """Build :class:`NormaliseOptions` from the click keywords (removing them from ``kw``), then ``overrides``."""
    from meshtool.repair.normalise import NormaliseOptions

    values = {key: kw.pop(key) for key in ("units", "scale", "up", "search_paths", "strict", "model_root")}
    values.update(overrides)
    return NormaliseOptions(**values)


def _user_cache() -> Path:
    import platformdirs

    return Path(platformdirs.user_cache_dir("meshtool"))


def _check_cache(hull_cache: Path | None) -> Path | None:
    """Where passing MuJoCo checks are remembered.

    ``checks`` beside the default ``hulls`` cache, or inside a ``--cache-dir``; nothing with ``--no-cache``.
    """
    if hull_cache is None:
        return None
    return hull_cache.parent / "checks" if hull_cache == _user_cache() / "hulls" else hull_cache / "checks"


def _hull_options(kw: dict[str, Any]) -> HullOptions:
    """Build :class:`HullOptions` from the click keywords (removing them from ``kw``)."""
    preset, max_hulls, max_vertices = kw.pop("preset"), kw.pop("max_hulls"), kw.pop("max_hull_vertices")
    cache_dir, no_cache = kw.pop("cache_dir"), kw.pop("no_cache")
    values: dict[str, Any] = {
        "mode": kw.pop("hull_mode"),
        "min_thickness": kw.pop("min_thickness"),
        "merge_parts": kw.pop("merge_parts"),
        "threshold": kw.pop("threshold"),
        "timeout_s": kw.pop("timeout_s"),
        "time_budget_s": kw.pop("time_budget_s"),
        "cache_dir": None if no_cache else (cache_dir or _user_cache() / "hulls"),
    }
    if max_hulls is not None:
        values["max_hulls"] = max_hulls
    if max_vertices is not None:
        values["max_hull_vertices"] = max_vertices
    return HullOptions.preset(preset, **values) if preset else HullOptions(**values)


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


def _is_folder(path: Path) -> bool:
    """Whether ``path`` is a folder; a path that cannot be looked at (missing, too long) is not: the reader says why."""
    try:
        return stat.S_ISDIR(os.stat(path).st_mode)
    except (OSError, ValueError):
        return False


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


@click.command("mjcf")
@click.argument("src", type=click.Path(path_type=Path))  # a missing file: exit 1 (docs/cli.md)
@output_dir_option("Folder to write NAME/ (NAME.xml, meshes, textures) into, per asset.")
@click.option("--free-joint", is_flag=True, help="Give each body a free joint.")
@click.option("--density", type=float, default=1000.0, show_default=True, help="Collision density, kg/m^3.")
@click.option("--mass", type=float, default=None, help="Total body mass in kg (overrides --density).")
@click.option(
    "--units",
    type=click.Choice([*UNITS, "auto"]),
    default=None,
    help="For a mesh file: the unit it was modelled in (as obj2bin --units).",
)
@click.option(
    "--up", type=click.Choice(["auto", "y", "z"]), default="auto", help="For a mesh file: its up axis (as obj2bin)."
)
@force_option
def mjcf(
    src: Path,
    out_dir: Path,
    free_joint: bool,
    density: float,
    mass: float | None,
    units: str | None,
    up: str,
    force: bool,
) -> None:
    """Write a MuJoCo model for SRC: an .mbin, a mesh file (packed first, as obj2bin does) or a folder of .mbin."""
    from meshtool.mjcf.asset_model import MjcfOptions, write_mjcf
    from meshtool.packfile import load
    from meshtool.pipeline import ConvertOptions
    from meshtool.repair.normalise import NormaliseOptions, safe_file_stem

    with _guard(False):
        options = MjcfOptions(free_joint=free_joint, density=density, mass=mass)
        if src.suffix.lower() in mesh_suffixes() and not _is_folder(src):
            from meshtool.mjcf.mesh_model import mesh_mjcf

            convert_options = ConvertOptions(NormaliseOptions(units=units, up=up))
            xml, _, found = mesh_mjcf(src, out_dir, convert_options, options, force=force)
            wrote(xml, kind="mjcf")
            findings(found)
            return
        sources = find_files(src, suffix("mbin")) if _is_folder(src) else [src]
        if not sources:
            raise OptionsError(f"no .mbin files under {src}")
        stems = [safe_file_stem(p.stem) or "asset" for p in sources]
        clash = next((p for p, n in zip(sources, stems, strict=True) if stems.count(n) > 1), None)
        if clash is not None:
            raise OptionsError(f"two .mbin files would both become {safe_file_stem(clash.stem)!r}", hint="rename one")
        told: list[Finding] = []
        for path in sources:
            with load(path) as packed:
                xml, found = write_mjcf(
                    packed, out_dir, safe_file_stem(path.stem) or "asset", path, options, force=force, inputs=sources
                )
            told += found
            wrote(xml, kind="mjcf")
    told_once(told)


def _package_dir(_ctx: click.Context, _param: click.Parameter, values: tuple[str, ...]) -> tuple[tuple[str, Path], ...]:
    pairs = []
    for value in values:
        name, sep, folder = value.partition("=")
        if not sep or not folder:  # an empty NAME maps package:///... (talos_full_v2 writes those)
            raise click.BadParameter(f"expected NAME=DIR, got {value!r}")
        pairs.append((name, Path(folder)))
    return tuple(pairs)


@click.command("urdf")
@click.argument("robot", type=click.Path(path_type=Path, dir_okay=False))
@output_dir_option("Folder for NAME.xml (MJCF), its OBJ meshes and PNG textures, and meshes/*.mbin.")
@click.option(
    "--package-dir",
    "package_dirs",
    multiple=True,
    callback=_package_dir,
    help="Folder of a ROS package for package://NAME/... paths, as NAME=DIR (repeatable; =DIR maps package:///...).",
)
@click.option("--actuators", is_flag=True, help="Add a motor per moving joint, limited to its URDF effort.")
@click.option("--free-base", is_flag=True, help="Give the root link a free joint (mobile robots).")
@click.option("--allow-outside", is_flag=True, help="Let relative mesh paths leave the robot's package folder.")
@click.option(
    "--package-search",
    is_flag=True,
    help="Look for package://NAME in folders named NAME above the URDF and beside them "
    "(default: only the robot's own package and --package-dir).",
)
@force_option
@hull_options
def urdf(
    robot: Path,
    out_dir: Path,
    package_dirs: tuple[tuple[str, Path], ...],
    actuators: bool,
    free_base: bool,
    allow_outside: bool,
    package_search: bool,
    force: bool,
    **hull_kw: Any,
) -> None:
    """Import ROBOT (a URDF): every mesh normalised, packed and hulled; an MJCF of the robot."""
    from meshtool.urdf.import_robot import UrdfOptions, import_urdf
    from meshtool.urdf.write import write_import

    with _guard(False), overwrite_allowed(force):
        options = UrdfOptions(package_dirs, _hull_options(hull_kw), actuators, free_base, allow_outside, package_search)
        result = import_urdf(robot, options)
        findings(result.findings)
        write_import(result, out_dir)
        xml = out_dir / (result.name + suffix("mjcf"))
        wrote(
            xml,
            f"wrote {xml}: {len(result.links)} links, {len(result.joints)} moving "
            f"joints, {len(result.mbins)} mesh(es) in {out_dir / 'meshes'}",
            kind="mjcf",
        )


def _summary(stats: dict[str, Any]) -> str:
    return (
        f"{stats['vertices']} vertices, {stats['triangles']} triangles, "
        f"{stats['materials']} material(s), {stats['textures']} texture(s), "
        f"extent {' x '.join(f'{e:.4g}' for e in stats['bbox']['extent'])} m"
    )


def _report(status: str, output: Path, findings: list[Finding], stats: dict[str, Any]) -> dict[str, Any]:
    return {"status": status, "output": str(output), "findings": [f.to_dict() for f in findings], "stats": stats}


@contextlib.contextmanager
def _guard(as_json: bool) -> Iterator[None]:
    """Map library errors to exit 1 (one ``error:`` line) and bugs to exit 3."""
    try:
        yield
    except MeshtoolError as exc:
        if as_json:  # the command's own JSON document (normalize, obj2bin, hulls, info --json)
            report({"status": "error", "output": None, "error": exc.to_dict(), "findings": [], "stats": None})
        fail(exc)
    except Exception as exc:  # a bug in meshtool: say so, keep the traceback for MESHTOOL_DEBUG
        exit_on_bug(exc)
