"""The one composer of meshtool's stages, and mesh to ``.mbin`` conversion (one file, or a folder tree).

The stages run in sequence here and nowhere else (``tests/test_layering.py`` checks it; a file converted enters
each stage's entry once, ``tests/test_pipeline_stages.py``): read, frame and repair (:func:`repaired_asset`: a
:class:`~meshtool.stages.NormalisedAsset`), hulls
(:func:`asset_hulls`: a :class:`~meshtool.hulls.compute.HullSet`), pack (:func:`pack_asset`: ``.mbin``
bytes whose META is a :class:`~meshtool.packfile.meta.PackMeta`). ``obj2bin`` FILE and DIR, ``meshtool
hulls``, ``meshtool mjcf``, URDF meshes (:mod:`meshtool.urdf.meshes`), ``meshtool validate``
(:mod:`meshtool.validate.task`) and simrun's mesh assets call these. Whether a pack is still current is
:func:`is_current` / :func:`source_states` here, for every caller.

A folder's files run where :mod:`meshtool.work.batch` puts them: this process, local worker processes (they die
with their parent: on Linux the kernel sends them SIGKILL when the parent dies, ``prctl(PR_SET_PDEATHSIG)``,
and everywhere a watchdog thread exits a worker when its parent changes, so a killed ``obj2bin -j N`` leaves
no worker behind; a file past ``--timeout`` has its worker killed), or a Dask cluster (``--executor dask``).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

from meshtool.errors import MeshtoolError, OutputError, PackFormatError, StrictModeError
from meshtool.files.outdir import check_output, refuse_inputs, write_file
from meshtool.files.resolve import file_sha256, find_files
from meshtool.files.safeopen import printable
from meshtool.findings import Finding
from meshtool.formats import mesh_suffixes, suffix
from meshtool.frame.declared import decide_asset_frame
from meshtool.frame.modelroot import model_root_resolver
from meshtool.hulls.compute import Hull, HullOptions, HullSet, compute_hulls, quality
from meshtool.packfile import PackMeta, SourceEntry, load, pack
from meshtool.packfile.meta import source_entries, source_files, source_path
from meshtool.read.source_asset import read_source_asset
from meshtool.repair.convert import convert_asset
from meshtool.repair.mesh import TriMesh
from meshtool.repair.normalmaps import mujoco_findings
from meshtool.repair.options import NormaliseOptions, safe_file_stem
from meshtool.stages import NormalisedAsset
from meshtool.work.batch import Executor, run_batch
from meshtool.work.progress import report as report_progress
from meshtool.work.progress import subject as progress_subject


@dataclass(frozen=True, slots=True)
class ConvertOptions:
    """Options of ``obj2bin``.

    Attributes:
        normalise: The normaliser's options (units, scale, up axis, search paths, strict).
        quantize: Write the quantised encoding.
        hulls: How collision hulls are made (default: one convex hull).
        check: Compile the packed asset in MuJoCo before writing it (:mod:`meshtool.mjcf.loadcheck`; skipped with
            a note when simrun is not installed) and refuse one MuJoCo rejects. Not part of the
            fingerprint: it never changes the bytes written.
        check_cache: Folder where passing checks are remembered (:func:`meshtool.mjcf.loadcheck.check_pack`);
            ``None`` compiles every time.
    """

    normalise: NormaliseOptions = field(default_factory=NormaliseOptions)
    quantize: bool = False
    hulls: HullOptions = field(default_factory=HullOptions)
    check: bool = True
    check_cache: Path | None = None

    def fingerprint(self) -> dict[str, Any]:
        """The options as recorded in the file's metadata (paths as strings)."""
        n = asdict(self.normalise)
        n["search_paths"] = [str(p) for p in self.normalise.search_paths]
        if n.get("model_root") is None:
            n.pop("model_root", None)  # packs made without --model-root keep their metadata byte for byte
        else:
            n["model_root"] = str(n["model_root"])
        n.pop("name", None)
        return {"normalise": n, "quantize": self.quantize, "hulls": self.hulls.fingerprint()}


@dataclass(slots=True)
class ConvertResult:
    """Outcome of one conversion.

    Attributes:
        source: The OBJ.
        output: The ``.mbin`` written (or found up to date).
        status: ``written``, ``unchanged`` or ``failed``.
        findings: The normaliser's findings (empty when unchanged).
        stats: Counts and sizes (empty when unchanged).
        error: The one-line error when failed.
    """

    source: Path
    output: Path
    status: str
    findings: list[Finding] = field(default_factory=list)
    stats: dict[str, Any] = field(default_factory=dict)
    error: str | None = None


def convert(src: Path, out: Path, options: ConvertOptions | None = None, *, force: bool = False) -> ConvertResult:
    """Normalise ``src`` and write it as ``out`` (.mbin) atomically.

    Args:
        src: The OBJ.
        out: The ``.mbin`` to write.
        options: Conversion options.
        force: Replace an existing ``out`` that is not a meshtool ``.mbin`` (never an input: the OBJ, or an
            MTL or texture it uses).

    Raises:
        MeshtoolError: The input cannot be converted, MuJoCo refuses the packed asset
            (:class:`meshtool.mjcf.model_desc.ModelError`, with ``options.check``), or the output cannot be written or
            would replace an input or a file meshtool did not write (:class:`OutputError`).
    """
    options = options or ConvertOptions()
    refuse_inputs(out, [src])  # before any work: `obj2bin box.obj -o box.obj`
    packed = pack_file(src, options)
    check_output(out, "mbin", force=force, inputs=[src, *packed.inputs], data=packed.data)
    write_file(out, packed.data)
    return ConvertResult(src, out, "written", packed.findings, packed.stats)


@dataclass(slots=True)
class Packed:
    """An ``.mbin`` made in memory by :func:`pack_file`.

    Attributes:
        data: The file's bytes.
        findings: The normaliser's, the hulls' and MuJoCo's findings.
        stats: Counts and sizes (as :attr:`ConvertResult.stats`).
        inputs: The files the conversion read: the source, its MTLs, textures and buffers
            (:meth:`PackMeta.source_files`).
    """

    data: bytes
    findings: list[Finding]
    stats: dict[str, Any]
    inputs: list[Path]


def pack_file(src: Path, options: ConvertOptions | None = None) -> Packed:
    """Normalise ``src`` (OBJ, STL, PLY, glTF/GLB, COLLADA), compute its hulls and pack it, in memory.

    The one path from a mesh file to an ``.mbin``: :func:`convert` writes it, ``obj2bin --mjcf`` and
    ``meshtool mjcf MESH`` build a MuJoCo model from it, simrun scenes use it for a mesh file asset.

    Raises:
        MeshtoolError: The input cannot be converted, or MuJoCo refuses the packed asset (with ``options.check``).
    """
    options = options or ConvertOptions()
    with progress_subject(printable(src.name)):
        return _pack_file(src, options)


def repaired_asset(src: Path, options: NormaliseOptions, *, data: bytes | None = None) -> NormalisedAsset:
    """Stages read, frame, repair: ``src`` in metres, Z-up, PNG textures, its record.

    Every caller goes through here (``obj2bin``, ``meshtool normalize``, ``meshtool hulls``, ``meshtool mjcf``,
    URDF meshes, ``validate``, simrun's mesh assets). Each stage's entry takes the record the one before it
    returned (:mod:`meshtool.stages`): the file -> :class:`~meshtool.stages.SourceAsset` (read, with its MTLs and
    its polygons as triangles, the vertices the output keeps marked) -> :class:`~meshtool.stages.FramedAsset`
    (frame: unit, scale, up axis, decided on the kept vertices) -> :class:`~meshtool.stages.NormalisedAsset`
    (repair: the triangles cleaned, in metres, Z-up, materials, PNG textures, ``asset.json``).

    Args:
        src: The mesh file. Its folder is the asset root: references never resolve outside it except into
            ``options.search_paths`` or the model root.
        options: See :class:`~meshtool.repair.options.NormaliseOptions`.
        data: The bytes of ``src`` when the caller has already read them race-free (the URDF importer reads
            each mesh beneath its package with :meth:`meshtool.files.resolve.Resolver.read_real`); else read here.

    Raises:
        MeshtoolError: The file cannot be read or converted (the message names file and line), or
            ``strict`` is set and there are warnings.
    """
    resolver, root_findings = model_root_resolver(
        src, options.search_paths, confine=options.confine, model_root=options.model_root
    )
    source = read_source_asset(
        src, resolver, data=data, up=options.up, units=options.units, scale=options.scale, notes=root_findings
    )
    framed = decide_asset_frame(source, units=options.units, scale=options.scale, up=options.up)
    return convert_asset(framed, options)


def asset_hulls(mesh: TriMesh, options: HullOptions, name: str) -> HullSet:
    """Stage hulls: the collision hulls of a repaired mesh (:func:`meshtool.hulls.compute.compute_hulls`)."""
    return compute_hulls(mesh, options, name)


def pack_asset(
    asset: NormalisedAsset,
    hulls: list[Hull],
    options: dict[str, Any],
    report: dict[str, Any] | None,
    *,
    quantize: bool = False,
) -> bytes:
    """Stage pack: the ``.mbin`` bytes of a repaired asset and its hulls.

    Args:
        asset: From :func:`repaired_asset`.
        hulls: From :func:`asset_hulls`.
        options: What made the pack, recorded as META ``options`` (:meth:`ConvertOptions.fingerprint`).
        report: The hulls' report recorded as ``hull_quality`` (``None``: not recorded).
        quantize: The quantised encoding.
    """
    return pack(asset, quantize, options, hulls, report)


def _pack_file(src: Path, options: ConvertOptions) -> Packed:
    report_progress("reading and normalising")
    asset = repaired_asset(src, options.normalise)
    report_progress("collision hulls")
    hull_set = asset_hulls(asset.mesh, options.hulls, src.name)
    report_progress("packing")
    report = quality(asset.mesh, hull_set.hulls) if hull_set.hulls else None
    findings = [*asset.findings, *hull_set.findings]
    if options.normalise.strict and any(f.severity.value == "warning" for f in hull_set.findings):
        first = next(f for f in hull_set.findings if f.severity.value == "warning")
        raise StrictModeError(f"hull warning in strict mode: {first.one_line()}", path=src.name)
    data = pack_asset(asset, hull_set.hulls, options.fingerprint(), report, quantize=options.quantize)
    findings += mujoco_findings(asset.materials, src.name)  # about MuJoCo's use of the pack: not stored in it
    checked = "off"
    if options.check:  # before anything is written: a pack MuJoCo refuses is an error, not an output
        report_progress("checking in MuJoCo")
        from meshtool.mjcf.loadcheck import check_pack

        checked, skipped = check_pack(data, src.name, options.check_cache)
        findings += skipped
    used = source_files(source_entries(asset.manifest.get("sources")), [src.parent, *options.normalise.search_paths])
    stats = dict(asset.stats)
    stats["bytes"] = len(data)
    stats["hulls"] = report or {"hulls": 0}
    stats["hull_cache_hits"] = hull_set.cache_hits
    stats["mujoco_check"] = checked
    return Packed(data, findings, stats, used)


def is_unchanged(src: Path, out: Path, options: ConvertOptions) -> bool:
    """Whether ``out`` was made from the current ``src`` (and the MTLs/textures it used) with ``options``.

    Compares the options and every source file's SHA-256 recorded in the file's metadata.
    """
    if file_sha256(out) is None:
        return False
    try:
        packed = load(out, verify=False)
    except (PackFormatError, MeshtoolError):
        return False
    try:
        return is_current(packed.pack_meta, src, options)
    finally:
        packed.close()


def is_current(meta: PackMeta | Mapping[str, Any], src: Path, options: ConvertOptions) -> bool:
    """Whether the pack with metadata ``meta`` was made from the current ``src`` with ``options``.

    The options and the SHA-256 of every source file (the mesh, its MTLs and textures) must match; a
    foreign or hostile META is never current.
    """
    meta = meta if isinstance(meta, PackMeta) else PackMeta(meta if isinstance(meta, Mapping) else {})
    if not meta.has_options or meta.options != options.fingerprint() or not meta.sources_well_formed():
        return False
    states = source_states(meta, [src.parent, *options.normalise.search_paths])
    return bool(meta.sources) and all(path is not None and now == entry.sha256 for entry, path, now in states)


def source_states(meta: PackMeta, roots: Sequence[Path]) -> list[tuple[SourceEntry, Path | None, str | None]]:
    """Each file a pack was made from (:meth:`PackMeta.file_sources`) with its path and current SHA-256.

    The one staleness check: :func:`is_current` (``obj2bin``'s skip, simrun's pack cache) and validate's K003.

    Args:
        meta: The pack's metadata.
        roots: The source's folder, then the search paths (:func:`meshtool.packfile.meta.source_path`).

    Returns:
        ``(entry, path, sha256 now)`` per file source; path ``None`` for a search path ``roots`` lacks,
        digest ``None`` for a file that is missing or unreadable.
    """
    out: list[tuple[SourceEntry, Path | None, str | None]] = []
    for entry in meta.file_sources():
        path = source_path(entry.path, roots)
        out.append((entry, path, None if path is None else file_sha256(path)))
    return out


def tree_jobs(src_dir: Path, out_dir: Path) -> list[tuple[Path, Path]]:
    """Every mesh file under ``src_dir`` (sorted) with its ``.mbin`` path under ``out_dir``, same layout.

    Mesh files have a suffix of :func:`meshtool.formats.mesh_suffixes`.

    Files of one folder whose stems clash (``box.obj`` and ``box.stl``) get the suffix appended to all but
    the first in sorted order (``box.mbin``, ``box_stl.mbin``).
    """
    jobs = []
    taken: set[Path] = set()
    found = sorted({p for ext in mesh_suffixes() for p in find_files(src_dir, ext)})
    for src in found:
        rel = src.relative_to(src_dir)
        folder = out_dir.joinpath(*(safe_file_stem(p) or "_" for p in rel.parts[:-1]))
        stem = safe_file_stem(src.stem) or "asset"
        out = folder / f"{stem}{suffix('mbin')}"
        if out in taken:
            out = folder / f"{stem}_{src.suffix.lower().lstrip('.')}{suffix('mbin')}"
        taken.add(out)
        jobs.append((src, out))
    return jobs


def _run(src: Path, out: Path, options: ConvertOptions, force: bool = False, base: Path | None = None) -> ConvertResult:
    """Convert ``src`` to ``out``, reporting both paths as given.

    Relative paths are read and written beneath ``base`` when given (a Dask worker's working folder is not the
    command's), so results are the same bytes on every executor.
    """
    read_src, write_out = (base / src, base / out) if base is not None else (src, out)
    if is_unchanged(read_src, write_out, options):
        return ConvertResult(src, out, "unchanged")
    try:
        result = convert(read_src, write_out, options, force=force)
    except MeshtoolError as exc:
        return ConvertResult(src, out, "failed", error=f"{src}: {exc.one_line()}")
    return replace(result, source=src, output=out)


@dataclass(frozen=True, slots=True)
class _ConvertWork:
    """One file of ``obj2bin DIR``, for the batch layer (:mod:`meshtool.work.batch`): a task is ``(src, out)``."""

    options: ConvertOptions
    force: bool
    total: int
    base: Path | None = None  # the command's working folder: relative task paths are beneath it

    def prepare(self) -> None:
        """Nothing to import ahead: the converter is this module."""

    def __call__(self, task: tuple[int, Path, Path], /) -> ConvertResult:
        k, src, out = task
        with progress_subject(f"[{k}/{self.total}] {printable(src.name)}"):
            return _run(src, out, self.options, self.force, self.base)

    def lost(self, task: tuple[int, Path, Path], why: str, /) -> ConvertResult:
        _, src, out = task
        return ConvertResult(src, out, "failed", error=f"{src}: not converted: {why}")


def convert_tree(
    src_dir: Path,
    out_dir: Path,
    options: ConvertOptions | None = None,
    jobs: int = 1,
    *,
    force: bool = False,
    executor: Executor | None = None,
) -> Iterator[ConvertResult]:
    """Convert every mesh file under ``src_dir``; yields results as they finish.

    Args:
        src_dir: Folder searched recursively for every mesh format meshtool reads.
        out_dir: Output root; the folder layout is kept (names made safe).
        options: Conversion options (``normalise.name`` is ignored).
        jobs: Worker processes (1 converts in this process); they die with this process. Ignored when
            ``executor`` is given.
        force: Replace existing outputs that are not meshtool ``.mbin`` files (never an input).
        executor: Where the files are converted (:mod:`meshtool.work.batch`: this process, local worker processes
            with an optional per-file timeout, or a Dask cluster). Each pack's bytes are the same whichever.

    Yields:
        One result per file, unchanged ones included; a file whose worker died or ran past the timeout is
        ``failed`` with the reason.
    """
    options = options or ConvertOptions()
    executor = executor or Executor(jobs=max(1, jobs))
    work = tree_jobs(src_dir, out_dir)
    outputs = [o for _, o in work]
    if len(set(outputs)) != len(outputs):
        clash = next(o for o in outputs if outputs.count(o) > 1)
        raise OutputError("two sources map to the same output", path=str(clash), hint="rename one of them")
    tasks = [(k, src, out) for k, (src, out) in enumerate(work, start=1)]
    pending = {k - 1: src for k, src, _ in tasks}
    if not executor.in_process:
        report_progress(_waiting(pending, executor.jobs), 0, len(work))
    for index, result, _where in run_batch(tasks, _ConvertWork(options, force, len(work), Path.cwd()), executor):
        del pending[index]
        if not executor.in_process:
            report_progress(_waiting(pending, executor.jobs), len(work) - len(pending), len(work))
        yield result


def _waiting(pending: dict[int, Path], jobs: int) -> str:
    """``converting``, and the files still running once no more wait for a worker (the last, slow ones)."""
    if not pending or len(pending) > jobs:
        return "converting"
    names = sorted(printable(p.name) for p in pending.values())
    return f"converting (still running: {', '.join(names)})"
