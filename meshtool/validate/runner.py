"""Run the per-asset task over many assets: discovery, cache, executors (local processes or Dask).

The executor only decides where the checks run (:mod:`meshtool.validate.pool` locally,
:mod:`meshtool.validate.remote` on Dask); results are sorted by asset path afterwards, so reports are
identical whatever the executor and the number of workers.
"""

from __future__ import annotations

import errno
import os
import time
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path

from meshtool.errors import MeshtoolError
from meshtool.files.resolve import find_files
from meshtool.files.safeopen import printable
from meshtool.findings import Severity
from meshtool.formats import mesh_suffixes, output_named
from meshtool.validate.cache import ResultCache
from meshtool.validate.config import ValidateConfig
from meshtool.validate.pool import Checker
from meshtool.validate.remote import run_dask
from meshtool.validate.task import AssetResult, AssetTask
from meshtool.work.batch import BatchError, Executor, run_batch
from meshtool.work.progress import Meter, TickSink

EXECUTORS = ("local", "dask")


def suffixes() -> tuple[str, ...]:
    """What validate checks in a folder: every mesh format's suffixes and the pack's (the formats registry)."""
    return (*mesh_suffixes(), *output_named("mbin").suffixes)


class ValidateError(MeshtoolError, RuntimeError):
    """The validation could not run (bad paths are ``usage``; executor failures are not).

    Attributes:
        usage: A usage error (exit 2).
        exit_code: The exit code otherwise: 1 for an unreachable scheduler (the user's setup), 3 for a failure
            of meshtool itself.
    """

    def __init__(self, message: str, *, usage: bool = False, exit_code: int = 3, **kwargs: str | None) -> None:
        super().__init__(message, **kwargs)  # type: ignore[arg-type]
        self.usage = usage
        self.exit_code = 2 if usage else exit_code


@dataclass(frozen=True, slots=True)
class ValidateOptions:
    """Options of :func:`validate` (the fields of ``meshtool validate``).

    Attributes:
        config: Severity overrides, ignores and limits.
        jobs: Worker processes (1 checks in this process with the local executor).
        executor: ``local`` (a process pool) or ``dask`` (``dask.distributed``).
        scheduler: A Dask scheduler address; ``None`` starts a local cluster of ``jobs`` workers.
        cache_dir: The result cache folder; ``None`` disables the cache.
        changed_only: Report only assets checked in this run (cache misses); unchanged ones are counted.
        thumbnails: Render a thumbnail per asset (the HTML report shows them).
        timeout: Seconds one asset's check may take (X002 past it; 0: no limit); ``None``: the
            configuration's ``timeout`` (default :data:`meshtool.validate.config.DEFAULT_TIMEOUT`).
        connect_timeout: Seconds to wait for the Dask scheduler.
    """

    config: ValidateConfig = field(default_factory=ValidateConfig)
    jobs: int = 1
    executor: str = "local"
    scheduler: str | None = None
    cache_dir: Path | None = None
    changed_only: bool = False
    thumbnails: bool = False
    timeout: float | None = None
    connect_timeout: float = 30.0

    def __post_init__(self) -> None:
        if self.executor not in EXECUTORS:
            raise ValidateError(f"unknown executor {self.executor!r}", usage=True, hint="use local or dask")
        if self.jobs < 1:
            raise ValidateError(f"-j must be at least 1, got {self.jobs}", usage=True)
        if self.timeout is not None and not 0 <= self.timeout < float("inf"):
            raise ValidateError(f"--timeout must be 0 or more seconds, got {self.timeout}", usage=True)

    def effective_timeout(self) -> float | None:
        """Seconds per asset, or ``None`` for no limit."""
        seconds = self.config.timeout if self.timeout is None else self.timeout
        return seconds or None


@dataclass(slots=True)
class ValidationReport:
    """The outcome of one run.

    Attributes:
        assets: One result per reported asset, sorted by path, configuration applied.
        checked: Assets checked in this run (the cache's misses).
        cache_hits: Assets whose result came from the cache (its hits: not checked again, whatever report
            format the run that stored them wrote).
        thumbnails_drawn: Cached results whose missing thumbnail this run drew alone (a run asking for
            thumbnails after one that did not); no rule was judged again for them.
        unchanged_skipped: Unchanged assets left out of ``assets`` (``changed_only``).
        seconds: Wall time of the run.
        executor: ``local`` or ``dask``.
        jobs: Workers asked for.
        config_file: The configuration file, or ``None``.
        where: Assets checked in this run per place (``this process``, ``2 local worker processes``, a Dask
            worker's address); empty when every result came from the cache.
        cache_notes: One line per cache entry found but not used (damaged, answering another key): those
            assets were checked again (:mod:`meshtool.files.cachefile`).
    """

    assets: list[AssetResult]
    checked: int = 0
    cache_hits: int = 0
    thumbnails_drawn: int = 0
    unchanged_skipped: int = 0
    seconds: float = 0.0
    executor: str = "local"
    jobs: int = 1
    config_file: str | None = None
    where: dict[str, int] = field(default_factory=dict)
    cache_notes: list[str] = field(default_factory=list)

    def counts(self) -> dict[str, int]:
        """Findings per severity over all assets."""
        counts = {s.value: 0 for s in Severity}
        for asset in self.assets:
            for f in asset.findings:
                counts[f.severity.value] += 1
        return counts

    def failed(self, strict: bool) -> bool:
        """Whether there are errors (or, with ``strict``, warnings)."""
        counts = self.counts()
        return counts["error"] > 0 or (strict and counts["warning"] > 0)

    def internal_errors(self) -> int:
        """Assets meshtool itself failed on (X001)."""
        return sum(any(f.code == "X001" for f in a.findings) for a in self.assets)


def discover(paths: list[Path]) -> list[tuple[Path, Path]]:
    """Every OBJ and ``.mbin`` named or under the folders named, as (file, folder it was found under).

    Hidden folders (``.git``, ``.venv``, caches) are skipped; the list is sorted and has no duplicates. Entries
    with an asset's suffix that are not regular files (a FIFO named ``x.obj``) are listed too: the check
    reports them (S001) without opening them.

    Raises:
        ValidateError: A path does not exist, or nothing to check was found (usage errors).
    """
    found: dict[Path, tuple[Path, Path]] = {}
    for path in paths:
        try:
            os.stat(path)
        except OSError as exc:
            if exc.errno == errno.ENOENT:
                raise ValidateError("no such file or folder", exit_code=1, path=str(path)) from None  # docs/cli.md
            reason = exc.strerror or type(exc).__name__
            raise ValidateError(f"cannot be read: {reason}", exit_code=1, path=printable(path)) from None
        if path.is_dir():
            for suffix in suffixes():
                for file in find_files(path, suffix, special=True):
                    if not any(part.startswith(".") for part in file.relative_to(path).parts[:-1]):
                        found.setdefault(file.resolve(), (file, path))
        elif os.path.exists(path):
            if path.suffix.lower() not in suffixes():
                raise ValidateError("not an OBJ or .mbin file", usage=True, path=str(path))
            found.setdefault(path.resolve(), (path, path.parent))
        else:
            raise ValidateError("no such file or folder", exit_code=1, path=str(path))  # as every command (docs/cli.md)
    if not found:
        raise ValidateError(
            "no OBJ or .mbin files found", usage=True, path=", ".join(map(str, paths)), hint="check the paths"
        )
    return sorted(found.values(), key=lambda pair: display_path(pair[0]))


def display_path(path: Path) -> str:
    """``path`` relative to the working folder when inside it, else absolute; ``/``-separated."""
    absolute = path.resolve()
    try:
        return absolute.relative_to(Path.cwd().resolve()).as_posix()
    except ValueError:
        return absolute.as_posix()


def validate(
    paths: list[Path], options: ValidateOptions | None = None, progress: TickSink | None = None
) -> ValidationReport:
    """Check every asset under ``paths``.

    Args:
        paths: Files and folders.
        options: See :class:`ValidateOptions`.
        progress: Called with a :class:`meshtool.work.progress.Tick` as each asset is done (cached ones first,
            not counted in its rate; ``last``: the asset's display path).

    Returns:
        The report (findings with the configuration applied). Exit codes are the caller's business.

    Raises:
        ValidateError: Bad paths (``usage``), or the executor failed.
    """
    options = options or ValidateOptions()
    start = time.perf_counter()
    config = options.config
    tasks = []
    for file, root in discover(paths):
        settings = config.settings_for(file)
        tasks.append(
            AssetTask(
                file,
                display_path(file),
                settings.limits,
                config.source_roots,
                root,
                options.thumbnails,
                units=settings.units,
                up=settings.up,
            )
        )
    cache = ResultCache(options.cache_dir, config.fingerprint())
    meter = Meter(len(tasks), progress)
    results: dict[str, AssetResult] = {}
    todo: list[AssetTask] = []
    pictures: list[AssetTask] = []  # cached results without the thumbnail this run wants: drawn alone
    for task in tasks:
        cached = cache.lookup(task)
        if cached is None:
            todo.append(task)
            continue
        results[task.display] = cached
        if task.thumbnails and cached.thumbnail is None and cached.drawable and not options.changed_only:
            pictures.append(replace(task, thumbnail_only=True))
        meter.advance(task.display, computed=False)
    by_display = {t.display: t for t in todo}
    listings = {t.display: cache.listings(t) for t in todo}  # before the checks read: a later change is news
    runner = _run_dask if options.executor == "dask" else _run_local
    where: dict[str, int] = {}
    drawn = {t.display: t for t in pictures}
    for result, place in runner(todo + pictures, options):
        if result.path in drawn:
            _add_thumbnail(results[result.path], result, drawn[result.path], cache)
            continue
        where[place] = where.get(place, 0) + 1
        result.listings = listings[result.path]
        cache.store(by_display[result.path], result)
        results[result.path] = result
        meter.advance(result.path)
    report = ValidationReport(
        [],
        checked=cache.misses,
        cache_hits=cache.hits,
        thumbnails_drawn=len(pictures),
        executor=options.executor,
        jobs=options.jobs,
        config_file=config.file,
        where=dict(sorted(where.items())),
        cache_notes=list(cache.problems),
    )
    for task in tasks:
        result = results[task.display]
        result.format = task.format  # by the formats registry, whatever the cache holds
        if options.changed_only and result.cached:
            report.unchanged_skipped += 1
            continue
        folder = Path(task.display).parent
        result.findings = [
            replace(f, path=(folder / f.path).as_posix() if f.path else task.display)
            for f in config.apply(result.findings, task.path)
        ]
        report.assets.append(result)
    report.seconds = time.perf_counter() - start
    return report


def _add_thumbnail(cached: AssetResult, drawn: AssetResult, task: AssetTask, cache: ResultCache) -> None:
    """A thumbnail drawn alone (``drawn``) joins the cached result it was drawn for, and the cache entry."""
    failed = next((f.message for f in drawn.findings if f.code in ("X001", "X002")), None)
    if failed is not None:  # the findings stand; the picture is missing, and why
        cached.thumbnail_note = f"no thumbnail: {failed}"
        return
    cached.thumbnail, cached.thumbnail_note = drawn.thumbnail, drawn.thumbnail_note
    if cached.thumbnail is None and cached.thumbnail_note is None:  # the plugin draws none for it: remembered
        cached.drawable = False
    if cached.thumbnail is not None or not cached.drawable:  # not a missing GL context: that may change
        cache.store(task, cached)


def _run_local(tasks: list[AssetTask], options: ValidateOptions) -> Iterator[tuple[AssetResult, str]]:
    timeout = options.effective_timeout()
    if not tasks:  # everything came from the cache
        return
    if options.jobs == 1 or (len(tasks) <= 1 and timeout is None):
        executor = Executor(jobs=1, timeout=timeout, alarm=True)
        for _, result, where in run_batch(tasks, Checker(), executor):
            yield result, where
    else:  # a single task with a deadline also goes to a worker: only a process can be stopped for sure
        workers = min(options.jobs, len(tasks))
        executor = Executor(jobs=workers, timeout=timeout)
        for _, result, _ in run_batch(largest_first(tasks), Checker(), executor):
            yield result, f"{workers} local worker process{'es' if workers > 1 else ''}"


def largest_first(tasks: list[AssetTask]) -> list[AssetTask]:
    """``tasks`` by file size, largest first (ties by name): workers that take one asset at a time finish together.

    In path order the corpus' largest meshes could come last and keep one worker busy while the others idle
    (issue 28: ``-j 2`` was 1.33x ``-j 1``); longest-first bounds that tail by the largest single asset. The
    report's order does not depend on it (results are put in path order).
    """

    def size(task: AssetTask) -> int:
        try:
            return task.path.stat().st_size
        except OSError:  # a missing file is reported by its check
            return 0

    return sorted(tasks, key=lambda task: (-size(task), task.display))


def _run_dask(tasks: list[AssetTask], options: ValidateOptions) -> Iterator[tuple[AssetResult, str]]:
    try:
        yield from run_dask(
            tasks, options.scheduler, options.jobs, options.effective_timeout(), options.connect_timeout
        )
    except BatchError as exc:  # dask missing or its scheduler unreachable: the batch layer's one-line error
        raise ValidateError(exc.message, hint=exc.hint, exit_code=1) from None
