"""The per-asset task: every rule on one OBJ or ``.mbin``, as a pure function of the files it reads.

:func:`check_asset` is what an executor runs (in this process, a worker process or a Dask worker). It takes
a picklable :class:`AssetTask` and returns a picklable :class:`AssetResult` with the raw findings (default
severities; the configuration's overrides and ignores are applied later) and every file it read with its
SHA-256, so that the cache can tell when the result is out of date.
"""

from __future__ import annotations

import contextlib
import hashlib
import stat
import traceback
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from meshtool.errors import MeshtoolError
from meshtool.files.resolve import Resolver, file_sha256, printable
from meshtool.findings import Finding, Severity
from meshtool.formats import mesh_format, mesh_format_named, output_named
from meshtool.frame.consumers import find_consumers
from meshtool.frame.modelroot import find_model_root
from meshtool.frame.units import scale_findings
from meshtool.hulls.compute import Hull, HullOptions
from meshtool.packfile import PackMeta, parse
from meshtool.pipeline import ConvertOptions, asset_hulls, pack_asset, repaired_asset, source_states
from meshtool.repair.normalise import NormalisedAsset, NormaliseOptions
from meshtool.validate.collision import collision_findings
from meshtool.validate.config import Limits
from meshtool.validate.geometry import geometry_findings
from meshtool.validate.physics import physics_plugin
from meshtool.validate.rules import RULES, hit
from meshtool.validate.source import encoding_findings, from_normaliser, name_findings, reference_findings

#: Bumped whenever a rule changes what it reports: cached results of older rules are not reused.
RULESET_VERSION = 4


@dataclass(frozen=True, slots=True)
class AssetTask:
    """One asset to check.

    Attributes:
        path: The OBJ or ``.mbin`` file.
        display: How reports name it (relative to the working folder when inside it).
        limits: Budgets and thresholds.
        source_roots: Folders where ``.mbin`` sources are looked for besides the pack's own folder (K003);
            each is tried as is and with the pack's folder relative to ``scan_root`` appended.
        scan_root: The folder the asset was found under.
        thumbnails: Render a thumbnail.
        units: Unit of a source mesh's coordinates (:class:`meshtool.repair.normalise.NormaliseOptions` ``units``:
            ``mm``, ``cm``, ``m``..., ``auto``); ``None``: decided as ``normalize`` decides it. Packs are metres.
        up: Up axis of a source mesh (``y``, ``z``, ``auto``); ``None``: decided as ``normalize`` decides it.
        thumbnail_only: Only draw the thumbnail of an asset whose findings are cached (no rule is judged:
            :func:`judge_asset` packs the asset and asks the physics plugin for the picture alone).
    """

    path: Path
    display: str
    limits: Limits = field(default_factory=Limits)
    source_roots: tuple[Path, ...] = ()
    scan_root: Path | None = None
    thumbnails: bool = False
    units: str | None = None
    up: str | None = None
    thumbnail_only: bool = False

    @property
    def kind(self) -> str:
        """``obj`` (a source mesh of any reader's format) or ``mbin``."""
        return "mbin" if self.path.suffix.lower() in output_named("mbin").suffixes else "obj"

    @property
    def format(self) -> str:
        """The file's format by the formats registry: a mesh format's name (``obj``, ``stl``...) or ``mbin``."""
        if self.kind == "mbin":
            return output_named("mbin").name
        return (mesh_format(self.path) or mesh_format_named("obj")).name

    def settings(self) -> dict[str, Any]:
        """What besides the files changes this asset's raw findings: units, up axis and limits (cache key part)."""
        return {"units": self.units, "up": self.up, "limits": self.limits.as_dict()}


@dataclass(slots=True)
class AssetResult:
    """Everything found about one asset.

    Attributes:
        path: The asset as reports name it.
        kind: ``obj`` (a source mesh of any reader's format) or ``mbin``.
        findings: Raw findings (default severities), sorted by rule, file and line; their paths are relative
            to the asset's folder until :func:`meshtool.validate.runner.validate` makes them display paths.
        deps: Absolute path -> SHA-256 of every file read (``None``: looked for and absent).
        listings: Listing key -> digest (:func:`meshtool.validate.snapshot.dependency_listings`) of the
            folders the check could look into, taken before the check by the runner when it caches
            (``None``: too many entries, the result is not cached).
        stats: Numbers for reports (triangles, volume, hull fit, mass, ...).
        thumbnail: PNG bytes, or ``None``.
        notes: Checks not done and why, one line each (what the thumbnail could not be is ``thumbnail_note``).
        cached: Whether this result came from the cache (set by the runner).
        format: The file's format (:attr:`AssetTask.format`: ``obj``, ``stl``, ``ply``, ``gltf``, ``glb``,
            ``collada``, ``mbin``), set by the runner; every report labels the asset with it.
        drawable: The physics plugin compiled the asset (no P001), so a thumbnail can be drawn.
        thumbnail_note: Why there is no thumbnail when one was asked for (no GL context...), or ``None``.
            Kept apart from ``notes`` so that a report's text does not depend on whether pictures were drawn.
    """

    path: str
    kind: str
    findings: list[Finding] = field(default_factory=list)
    deps: dict[str, str | None] = field(default_factory=dict)
    listings: dict[str, str | None] = field(default_factory=dict)
    stats: dict[str, Any] = field(default_factory=dict)
    thumbnail: bytes | None = None
    notes: list[str] = field(default_factory=list)
    cached: bool = False
    format: str = ""
    drawable: bool = False
    thumbnail_note: str | None = None


#: How the physics plugin's notes about the picture begin (:mod:`simrun.asset_check`): they go to
#: :attr:`AssetResult.thumbnail_note`, not to the notes every report prints.
THUMBNAIL_NOTE = "no thumbnail"


@dataclass(slots=True)
class ReadAsset:
    """An asset after the phase that reads files (the judging phase needs no file system).

    Attributes:
        task: The asset.
        result: Findings, deps and stats of the reading phase.
        asset: An OBJ as :func:`meshtool.pipeline.repaired_asset` read it (MTLs and textures included).
        mbin: A pack's bytes.
        done: Nothing left to judge (the file could not be read, or the check failed).
    """

    task: AssetTask
    result: AssetResult
    asset: NormalisedAsset | None = None
    mbin: bytes | None = None
    done: bool = False


def check_asset(task: AssetTask) -> AssetResult:
    """Run every rule on one asset. Never raises: a failure of meshtool itself becomes an X001 finding."""
    return judge_asset(read_asset(task))


def read_asset(task: AssetTask) -> ReadAsset:
    """The phase that touches files: read the asset and everything it references, resolve, decode, hash.

    Executors that run checks away from the files (Dask) run this where the files are and ship the result
    to :func:`judge_asset`. Never raises.
    """
    read = ReadAsset(task, AssetResult(task.display, task.kind))
    special = _special_file(task.path)
    if special:  # never opened: a FIFO blocks the reader, a device never ends
        rule = "K001" if task.kind == "mbin" else "S001"
        read.result.findings.append(hit(rule, f"is {special}, not a regular file: not read", task.path.name))
        read.done = True
        return read
    with _internal_errors(read):
        if task.kind == "mbin":
            _read_mbin(read)
        else:
            _read_obj(read)
    return read


def judge_asset(read: ReadAsset) -> AssetResult:
    """The phase that computes: geometry, hulls, collision and physics rules on what :func:`read_asset` read."""
    if not read.done:
        with _internal_errors(read):
            if read.task.kind == "mbin":
                _judge_mbin(read)
            else:
                _judge_obj(read)
    result = read.result
    result.findings.sort(key=lambda f: (f.code, f.path or "", f.line or 0, f.message))
    return result


@contextlib.contextmanager
def _internal_errors(read: ReadAsset) -> Iterator[None]:
    """Any exception becomes an X001 finding (a bug in meshtool or a library, not in the asset)."""
    try:
        with np.errstate(all="ignore"):  # degenerate input makes trimesh divide by zero; rules judge the results
            yield
    except Exception as exc:
        where = traceback.extract_tb(exc.__traceback__)[-1]
        message = f"{type(exc).__name__}: {exc} (at {Path(where.filename).name}:{where.lineno})"
        read.result.findings.append(hit("X001", message, read.task.path.name))
        read.done = True


def _special_file(path: Path) -> str | None:
    """What ``path`` is when it exists but is not a regular file or a folder (after symbolic links)."""
    try:
        mode = path.stat().st_mode
    except OSError:
        return None
    kinds = {
        stat.S_ISFIFO: "a FIFO (named pipe)",
        stat.S_ISSOCK: "a socket",
        stat.S_ISCHR: "a character device",
        stat.S_ISBLK: "a block device",
    }
    return next((what for test, what in kinds.items() if test(mode)), None)


def _read_obj(read: ReadAsset) -> None:
    task, result = read.task, read.result
    src = task.path
    shown = printable(src.name)
    resolver = Resolver(src.parent)
    try:
        data = resolver.read_source(src)
    except MeshtoolError as exc:  # over the read limit, unreadable, changed while read: a finding, not a bug
        result.findings.append(hit("S001", exc.message, shown))
        result.findings.extend(name_findings([shown]))
        read.done = True
        return
    result.deps[str(src.resolve())] = hashlib.sha256(data).hexdigest()
    if (mesh_format(src) or mesh_format_named("obj")).text:  # binary formats (STL, PLY, GLB) are no text
        result.findings.extend(encoding_findings(shown, data))
    try:
        asset = repaired_asset(src, NormaliseOptions(units=task.units, up=task.up))
    except MeshtoolError as exc:
        rule = {"non-finite": "G001", "gltf-buffer-missing": "S013"}.get(str(exc.code), "S001")
        # a binary file's location is a byte offset, which findings have no field for: it leads the message
        located = exc.message if exc.line is not None or exc.offset is None else f"byte {exc.offset}: {exc.message}"
        result.findings.append(hit(rule, located, exc.path or shown, exc.line))
        result.findings.extend(name_findings([shown]))
        read.done = True
        return
    read.asset = asset
    manifest = asset.manifest
    for source in manifest["sources"]:
        if source["role"] == "texture" and source["path"].split("/", 1)[0] == shown:
            continue  # an image embedded in the glTF/GLB: the file's own digest covers it
        real = asset.source_paths.get(source["path"]) or (src.parent / source["path"]).resolve()
        result.deps[str(real)] = source["sha256"]  # the real name: shown names spell stray bytes as \xNN
    consumers = find_consumers(src, find_model_root(src.parent))  # the run's index: read once, reused
    result.findings.extend(from_normaliser(asset.findings, consumers))
    result.findings.extend(reference_findings(manifest["resolutions"]))
    result.findings.extend(name_findings(s["path"] for s in manifest["sources"]))
    for source in manifest["sources"][1:]:
        real = asset.source_paths.get(source["path"])
        if source["role"] == "mtl" and real is not None:
            try:  # the file the normaliser read, by its real name (not its shown one)
                mtl_bytes = resolver.read(real, "mtl")
            except MeshtoolError:
                continue  # an MTL in a model root above the OBJ's folder, or changed since: read once is enough
            result.findings.extend(encoding_findings(source["path"], mtl_bytes))


def _judge_obj(read: ReadAsset) -> None:
    task, result, asset = read.task, read.result, read.asset
    assert asset is not None
    name = task.path.name
    mesh = asset.mesh
    if task.thumbnail_only:
        if mesh.faces.shape[0] > 0:
            hull_options = HullOptions(mode="convex", max_hull_vertices=task.limits.max_hull_vertices)
            hull_set = asset_hulls(mesh, hull_options, name)
            options = ConvertOptions(hulls=hull_options)
            _thumbnail(task, result, pack_asset(asset, hull_set.hulls, options.fingerprint(), None))
        return
    result.stats.update(asset.stats)
    result.findings.extend(geometry_findings(mesh.positions, mesh.faces, name, task.limits))
    if mesh.faces.shape[0] == 0:
        result.notes.append("collision and physics not checked: the mesh has no faces")
        return
    hull_options = HullOptions(mode="convex", max_hull_vertices=task.limits.max_hull_vertices)
    hull_set = asset_hulls(mesh, hull_options, name)
    found, report = collision_findings(mesh.positions, mesh.faces, hull_set.hulls, name, task.limits)
    result.findings.extend(found)
    result.stats["collision"] = report
    options = ConvertOptions(hulls=hull_options)
    packed = pack_asset(asset, hull_set.hulls, options.fingerprint(), report)
    _physics(task, result, packed)


def _read_mbin(read: ReadAsset) -> None:
    task, result = read.task, read.result
    path = task.path
    name = path.name
    try:
        data = Resolver(path.parent).read_source(path, "other")
    except MeshtoolError as exc:  # over the read limit or unreadable: the pack cannot be checked (as a FIFO)
        result.findings.append(hit("K001", exc.message, name))
        read.done = True
        return
    result.deps[str(path.resolve())] = hashlib.sha256(data).hexdigest()
    try:
        packed = parse(data, name, verify=True)
    except MeshtoolError as exc:
        rule = "K002" if exc.code == "pack-version" else "K001"
        result.findings.append(hit(rule, exc.one_line().removeprefix(f"{name}: "), name))
        read.done = True
        return
    _staleness(task, result, packed.pack_meta)  # looks for the sources: where the files are
    packed.close()
    read.mbin = data


def _judge_mbin(read: ReadAsset) -> None:
    task, result, data = read.task, read.result, read.mbin
    assert data is not None
    if task.thumbnail_only:
        _thumbnail(task, result, data)
        return
    name = task.path.name
    packed = parse(data, name, verify=False)  # verified when read
    positions = np.asarray(packed.positions, dtype=np.float64)
    faces = np.asarray(packed.indices, dtype=np.int64)
    result.stats.update(packed.pack_meta.stats)
    result.findings.extend(geometry_findings(positions, faces, name, task.limits))
    extent = np.ptp(positions, axis=0) if len(positions) else np.zeros(3)
    result.findings.extend(hit("U001", f.message, name) for f in scale_findings(extent, name, True))
    hulls = [Hull(np.asarray(v, np.float64), np.asarray(f, np.int64), 0) for v, f in packed.hulls]
    if not hulls:
        result.findings.append(hit("C004", "no collision hulls: MuJoCo would collide with the visual mesh", name))
    found, report = collision_findings(positions, faces, hulls, name, task.limits)
    result.findings.extend(found)
    result.stats["collision"] = report
    packed.close()
    if faces.shape[0] == 0:
        result.notes.append("physics not checked: the pack has no triangles")
        return
    _physics(task, result, data)


def _staleness(task: AssetTask, result: AssetResult, meta: PackMeta) -> None:
    """K003: find the pack's sources (its folder, then the source roots) and compare their hashes."""
    if not meta.sources:
        result.notes.append("staleness not checked: the pack records no sources")
        return
    folder = task.path.parent
    candidates = [folder]
    for root in task.source_roots:
        if task.scan_root is not None:
            with contextlib.suppress(ValueError):  # the pack is not under the scanned folder
                candidates.append(root / folder.resolve().relative_to(task.scan_root.resolve()))
        candidates.append(root)
    obj = meta.sources[0].path
    for base in candidates:
        first = base / obj
        digest = file_sha256(first)
        result.deps[str(first.absolute())] = digest  # not resolved: a link retargeted later is looked up anew
        if digest is None:
            continue
        changed, missing = [], []
        for source, path, now in source_states(meta, [base]):
            if path is not None:
                result.deps[str(path.absolute())] = now
            if now is None:
                missing.append(source.path)
            elif now != source.sha256:
                changed.append(source.path)
        if changed or missing:
            parts = [f"changed: {', '.join(changed)}"] if changed else []
            parts += [f"missing: {', '.join(missing)}"] if missing else []
            result.findings.append(hit("K003", f"made from older sources ({'; '.join(parts)})", task.path.name))
        result.stats["sources_dir"] = str(base)
        return
    result.notes.append(f"staleness not checked: source {obj!r} not found beside the pack or in source-roots")


def _physics(task: AssetTask, result: AssetResult, mbin: bytes) -> None:
    if any(RULES[f.code].severity is Severity.ERROR and f.code[0] == "G" for f in result.findings):
        result.notes.append("physics not checked: geometry errors")
        return
    plugin = physics_plugin()
    if plugin is None:
        result.notes.append("physics not checked: no physics plugin installed (pip install meshtool-simrun)")
        return
    outcome = plugin(mbin, task.path.name, task.limits.as_dict(), task.thumbnails)
    scale_wrong = any(f.code == "U001" for f in result.findings)
    # a mass far off, or a fall from far up, because the size is far off: one cause, reported once (U001)
    result.findings.extend(f for f in outcome.findings if not (scale_wrong and f.code in ("P002", "P004")))
    result.drawable = not any(f.code == "P001" for f in outcome.findings)  # MuJoCo compiled it: it can be drawn
    _keep_picture(result, outcome.thumbnail, outcome.notes)
    result.stats["physics"] = outcome.stats


def _keep_picture(result: AssetResult, thumbnail: bytes | None, notes: list[str]) -> None:
    """The plugin's thumbnail, its notes about the picture as ``thumbnail_note`` and the others as notes."""
    result.thumbnail = thumbnail
    result.notes.extend(n for n in notes if not n.startswith(THUMBNAIL_NOTE))
    result.thumbnail_note = next((n for n in notes if n.startswith(THUMBNAIL_NOTE)), None)


def _thumbnail(task: AssetTask, result: AssetResult, mbin: bytes) -> None:
    """Only the picture (:attr:`AssetTask.thumbnail_only`): the plugin compiles the pack and draws it.

    The drop is cut to one step (``settle-time`` 0): the picture shows the asset upright whatever the drop
    did, and the plugin's findings are not kept (the cached ones stand).
    """
    plugin = physics_plugin()
    if plugin is None:
        result.thumbnail_note = f"{THUMBNAIL_NOTE}: no physics plugin installed (pip install meshtool-simrun)"
        return
    outcome = plugin(mbin, task.path.name, {**task.limits.as_dict(), "settle_time": 0.0}, True)
    _keep_picture(result, outcome.thumbnail, [n for n in outcome.notes if n.startswith(THUMBNAIL_NOTE)])
