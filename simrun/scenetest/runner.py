"""``simrun test``'s library entry: plan every scene x variation x seed, run them anywhere, record failures.

:func:`run_tests` checks every scene first (:func:`simrun.scenetest.spec.load_case`: a bad scene, commands
file or expectation is one error before anything runs), plans one :class:`~simrun.scenetest.task.RunTask`
per run in a fixed order (scene, variation, seed), hands them to the batch layer shared with meshtool
(:func:`meshtool.work.batch.run_batch`: this process, local worker processes or Dask; the scenes' bundles
are its shared payload, sent to each worker once), and puts the results back in that order, so the report
does not depend on which worker finished first. Failed runs are written, with their scene as run and the files it
reads, under ``record_dir``, where ``simrun resim`` re-simulates them bit for bit.
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Any

import tomli_w

from meshtool.formats import suffix
from meshtool.work.batch import Executor, run_batch
from meshtool.work.progress import TickSink
from simrun.errors import SimrunError
from simrun.outfile import write_bytes
from simrun.scenetest.bundle import Bundle
from simrun.scenetest.spec import Case, discover, load_case
from simrun.scenetest.task import RunResult, RunTask, SceneRuns
from simrun.scenetest.vary import Axis, VaryError, apply, check_key, draw, jitter, variations

EXECUTORS = ("local", "dask")
#: Size of a failed run's picture in HTML reports, pixels.
THUMBNAIL_SIZE = (320, 240)


@dataclass
class TestOptions:
    """How to run the tests.

    Attributes:
        seeds: The seeds every variation of every scene runs with.
        axes: ``--vary`` keys.
        jobs: Worker processes (local) or LocalCluster workers (dask without a scheduler).
        executor: ``local`` or ``dask``.
        scheduler: Dask scheduler address, or ``None`` for a LocalCluster.
        connect_timeout: Seconds to try reaching the scheduler.
        timeout: Seconds one run may take (``None``: no limit): locally the run goes to a worker process
            (even with one job) that is killed at the deadline; on Dask the run is abandoned there.
        record_dir: Folder to write failed runs into (scene as run, its files, ``.simlog``), or ``None``.
        thumbnails: Render a failed run's last state (for HTML reports).
    """

    __test__ = False  # not a pytest class

    seeds: list[int] = field(default_factory=lambda: [0])
    axes: list[Axis] = field(default_factory=list)
    jobs: int = 1
    executor: str = "local"
    scheduler: str | None = None
    connect_timeout: float = 30.0
    timeout: float | None = None
    record_dir: Path | None = None
    thumbnails: bool = False


@dataclass
class Run:
    """One run in the report.

    Attributes:
        case: The scene's case.
        seed: Its seed.
        variation: Index of its grid variation.
        values: Every value the run varied: ``--vary`` keys (in the order given) then jitter
            (``jitter.ENTITY.x`` ...), as written into the scene.
        result: What it gave.
        recording: The ``.simlog`` written for it (POSIX path), or ``None``.
        resim: The command that re-simulates it, or ``None``.
    """

    case: Case
    seed: int
    variation: int
    values: dict[str, float]
    result: RunResult
    recording: str | None = None
    resim: str | None = None

    @property
    def label(self) -> str:
        """``SCENE seed=S KEY=VALUE ...``: the run's name in reports."""
        return run_label(self.case, self.seed, self.values)


def run_label(case: Case, seed: int, values: dict[str, float]) -> str:
    """``SCENE seed=S KEY=VALUE ...``: a run's name (reports, the progress line)."""
    shown = " ".join(f"{k}={_num(v)}" for k, v in values.items())
    return f"{case.display} seed={seed}" + (f" {shown}" if shown else "")


def _num(value: float) -> str:
    return repr(float(value)) if value != int(value) else str(int(value))


@dataclass
class TestReport:
    """Every run, in plan order, and how the session went (the last two are not in the reports' bodies).

    Attributes:
        cases: The scenes tested.
        runs: One per scene x variation x seed.
        seeds: The seeds.
        axes: The ``--vary`` keys.
        executor: ``local`` or ``dask``.
        where: How many runs each process or worker ran.
        seconds: Wall-clock seconds of the whole session.
    """

    __test__ = False  # not a pytest class

    cases: list[Case]
    runs: list[Run]
    seeds: list[int]
    axes: list[Axis]
    executor: str = "local"
    where: dict[str, int] = field(default_factory=dict)
    seconds: float = 0.0

    def counts(self) -> dict[str, int]:
        """Runs by status: ``passed``, ``failed``, ``error``."""
        tally = Counter(r.result.status for r in self.runs)
        return {s: tally.get(s, 0) for s in ("passed", "failed", "error")}

    def failed(self) -> bool:
        """Whether any run failed or could not finish."""
        return any(r.result.status != "passed" for r in self.runs)

    def internal(self) -> bool:
        """Whether simrun itself failed in a run (a crash or a bug)."""
        return any(r.result.internal for r in self.runs)


def plan(
    cases: list[Case], options: TestOptions
) -> tuple[list[RunTask], list[tuple[Case, int, int, dict[str, float]]]]:
    """The runs' tasks and, per task, (case, seed, variation, values).

    Raises:
        VaryError: A ``--vary`` key that names nothing in any scene, or a parameter that cannot vary.
    """
    unused = {a.key for a in options.axes}
    tasks: list[RunTask] = []
    info: list[tuple[Case, int, int, dict[str, float]]] = []
    thumbnail = THUMBNAIL_SIZE if options.thumbnails else None
    for case in cases:
        names = {t.get("name") for g in ("entities", "sensors") for t in case.doc.get(g, []) if isinstance(t, dict)}
        axes = [a for a in options.axes if a.key.partition(".")[0] in names]
        for axis in axes:
            check_key(case.doc, axis.key, entity_class)
            unused.discard(axis.key)
        grid = variations(axes)
        stem = PurePosixPath(case.bundle.scene).stem
        original = case.bundle.files[case.bundle.scene]
        for v, fixed in enumerate(grid):
            for seed in options.seeds:
                drawn = draw(axes, seed)
                values = {a.key: (fixed[a.key] if a.key in fixed else drawn[a.key]) for a in axes}
                offsets = jitter(case.jitter, seed)
                name = f"{stem}.seed{seed}" + (f".v{v}" if len(grid) > 1 else "") + ".toml"
                text = original
                if values or offsets:
                    doc = apply(case.doc, values, offsets, entity_class)
                    shown = " ".join(f"{k}={_num(x)}" for k, x in {**values, **_jitter_keys(offsets)}.items())
                    head = f"# The scene {case.display} as simrun test ran it: seed={seed} {shown}\n"
                    text = (head + tomli_w.dumps(doc)).encode("utf-8")
                tasks.append(
                    RunTask(
                        len(tasks),
                        case.bundle.digest,
                        name,
                        text,
                        seed,
                        case.duration,
                        case.commands,
                        case.controller,
                        case.expectations,
                        options.record_dir is not None,
                        thumbnail,
                    )
                )
                info.append((case, seed, v, {**values, **_jitter_keys(offsets)}))
    if unused:
        raise VaryError(f"--vary {sorted(unused)[0]}: no scene has an entity or sensor of that name")
    return tasks, info


def entity_class(name: str) -> Any:
    """The class of an entity type name of a scene file, or ``None``."""
    try:
        from simrun.world.registry import tables as registry
    except ImportError:  # before the scene-type registry
        from simrun.scene import scene_file as scene

        return getattr(scene, "ENTITY_TYPES", {}).get(name)
    try:
        return registry.load("entities", name)
    except SimrunError:
        return None


def _jitter_keys(offsets: dict[str, float]) -> dict[str, float]:
    return {f"jitter.{k}": v for k, v in offsets.items()}


def run_tests(paths: list[Path], options: TestOptions, progress: TickSink | None = None) -> TestReport:
    """Test every scene under ``paths`` (see the module).

    Args:
        paths: Scene files or folders.
        options: Seeds, variations, executor, recording.
        progress: Called with a :class:`meshtool.work.progress.Tick` after each run (``last``: its label).

    Raises:
        SpecError, VaryError: Nothing to test, or a bad ``--vary`` key (usage errors).
        SceneError, SimrunError: A scene, commands file or expectation that cannot run (with FILE:LINE), or
            a failed-run recording that cannot be written.
        meshtool.work.batch.BatchError: dask.distributed is missing, or the Dask scheduler cannot be reached.
    """
    started = time.perf_counter()
    cases = [load_case(p) for p in discover(paths)]
    tasks, info = plan(cases, options)
    bundles = {c.bundle.digest: c.bundle for c in cases}
    labels = [run_label(case, seed, values) for case, seed, _, values in info]
    results: dict[int, RunResult] = {}
    where: Counter[str] = Counter()
    for result, worker in _execute(tasks, bundles, options, progress, labels):
        results[result.index] = result
        where[worker] += 1
    runs = [Run(c, seed, v, values, results[k]) for k, (c, seed, v, values) in enumerate(info)]
    if options.record_dir is not None:
        _record(runs, tasks, options.record_dir, cases)
    report = TestReport(cases, runs, list(options.seeds), list(options.axes), options.executor, dict(where))
    report.seconds = time.perf_counter() - started
    return report


def executor_of(options: TestOptions, runs: int) -> Executor:
    """Where ``runs`` runs go: Dask, or local workers (``jobs``, at most one per run).

    One local job runs in this process, unless a ``timeout`` needs a worker process it can stop.
    """
    if options.executor == "dask":
        return Executor(
            "dask",
            jobs=options.jobs,
            timeout=options.timeout,
            scheduler=options.scheduler,
            connect_timeout=options.connect_timeout,
        )
    return Executor("local", jobs=max(1, min(options.jobs, runs)), timeout=options.timeout)


def _execute(
    tasks: list[RunTask],
    bundles: dict[str, Bundle],
    options: TestOptions,
    progress: TickSink | None = None,
    labels: list[str] | None = None,
) -> Iterator[tuple[RunResult, str]]:
    """(result, where it ran) per task as they finish; the bundles the tasks use are the batch's shared payload."""
    shared = {digest: bundles[digest] for digest in sorted({t.digest for t in tasks})}
    names = labels or [t.scene_name for t in tasks]
    executor = executor_of(options, len(tasks))
    for _, result, where in run_batch(
        tasks, SceneRuns(), executor, shared=shared, progress=progress, label=lambda t: names[t.index]
    ):
        yield result, where


def _record(runs: list[Run], tasks: list[RunTask], folder: Path, cases: list[Case]) -> None:
    """Write each failed run's scene, files and ``.simlog`` under ``folder`` (one subfolder per scene)."""
    ids: dict[str, str] = {}
    for case in cases:
        stem = PurePosixPath(case.bundle.scene).stem
        ident, n = stem, 1
        while ident in ids.values():
            n += 1
            ident = f"{stem}-{n}"
        ids[case.display] = ident
    written: set[str] = set()
    for run, task in zip(runs, tasks, strict=True):
        if run.result.simlog is None:
            continue
        bundle = run.case.bundle
        base = folder / ids[run.case.display]
        if bundle.digest not in written:
            for name, data in bundle.files.items():
                write_bytes(base.joinpath(*PurePosixPath(name).parts), data)
            written.add(bundle.digest)
        scene_dir = base.joinpath(*PurePosixPath(bundle.scene).parent.parts)
        scene = scene_dir / task.scene_name
        log = scene.with_suffix(suffix("simlog"))
        write_bytes(scene, task.scene_text)
        write_bytes(log, run.result.simlog)
        run.recording = log.as_posix()
        command = f"simrun resim {log.as_posix()}"
        if task.controller is not None:
            command += f" --controller {base.joinpath(*PurePosixPath(task.controller).parts).as_posix()}"
        run.resim = command


__all__ = ["EXECUTORS", "Run", "SimrunError", "TestOptions", "TestReport", "plan", "run_tests"]
