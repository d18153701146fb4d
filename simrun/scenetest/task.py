"""One run of ``simrun test``: a task that carries everything it needs, and the worker code that runs it.

A :class:`RunTask` holds the scene text as run (variations and jitter written in), the seed, the timed
commands and the expectations; the scene's other files travel once per worker as a
:class:`~simrun.scenetest.bundle.Bundle`. :func:`run_task` unpacks the bundle into a private folder (once
per bundle and process), writes the scene text next to the original scene's place in it, loads and runs
it through the library (:func:`simrun.run.session.prepare`, :func:`simrun.run.play.play`) with an
:class:`~simrun.scenetest.observer.Observer`, and returns a :class:`RunResult`: plain data, the same whichever process
or machine ran it. With ``record``, the run is recorded as a ``.simlog`` whose bytes come back when it
failed (re-simulated by ``simrun resim`` next to the scene text).

:class:`SceneRuns` is what the batch layer (:mod:`meshtool.work.batch`) runs: the bundles are its shared
payload (sent to each worker once), a run that did not finish (its worker died, the deadline passed) is an
``error`` result saying why.
"""

from __future__ import annotations

import atexit
import io
import shutil
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import TYPE_CHECKING

from meshtool.formats import suffix
from simrun.errors import SimrunError
from simrun.run.commands import Command
from simrun.scenetest.bundle import Bundle, materialise
from simrun.scenetest.expect import Expectation, Outcome
from simrun.scenetest.observer import Observer

if TYPE_CHECKING:
    from simrun.world.world import World

_folders: dict[str, Path] = {}  # bundle digest -> unpacked folder (per process)


@dataclass(frozen=True)
class RunTask:
    """Everything one run needs besides its bundle.

    Attributes:
        index: Position of the run in the report.
        digest: Digest of the scene's bundle.
        scene_name: File name the scene text is written under (next to the original scene in the bundle).
        scene_text: The scene as run (UTF-8).
        seed: The run's seed (sensor noise; jitter and draws are already in ``scene_text``).
        duration: Simulated seconds.
        commands: Timed commands.
        controller: Bundle path of a ``.py`` controller module, or ``None``.
        expectations: What to check.
        record: Record a ``.simlog`` and return it when the run fails.
        thumbnail: (width, height) of a picture of a failed run's last state, or ``None``.
    """

    index: int
    digest: str
    scene_name: str
    scene_text: bytes
    seed: int
    duration: float
    commands: tuple[Command, ...]
    controller: str | None
    expectations: tuple[Expectation, ...]
    record: bool = False
    thumbnail: tuple[int, int] | None = None


@dataclass
class RunResult:
    """What one run gave.

    Attributes:
        index: The task's index.
        status: ``passed``, ``failed`` (an expectation did not hold) or ``error`` (the run could not finish:
            the message says why; ``internal`` when simrun itself failed).
        outcomes: One per expectation (empty when the run did not finish).
        error: Why the run stopped (``error`` status), else ``None``.
        internal: The error is a bug or a crash, not the scene's fault.
        simlog: The recording of a failed run, when asked for.
        thumbnail: PNG of the failed run's last state, when asked for.
        notes: Things the report should say that do not fail the run (a thumbnail that could not be made).
        wall_s: Seconds the simulation took (not in reports: it varies).
    """

    index: int
    status: str
    outcomes: list[Outcome] = field(default_factory=list)
    error: str | None = None
    internal: bool = False
    simlog: bytes | None = None
    thumbnail: bytes | None = None
    notes: list[str] = field(default_factory=list)
    wall_s: float = 0.0


def unpacked(bundle: Bundle) -> Path:
    """The folder this process unpacked ``bundle`` into (unpacked on first use, removed at exit)."""
    folder = _folders.get(bundle.digest)
    if folder is None:
        folder = Path(tempfile.mkdtemp(prefix="simrun-test-"))
        atexit.register(shutil.rmtree, folder, True)
        materialise(bundle, folder)
        _folders[bundle.digest] = folder
    return folder


def run_task(task: RunTask, bundle: Bundle) -> RunResult:
    """Run one task (in any process: a worker, a Dask worker or this one).

    Errors of the scene or the run become an ``error`` result; bugs become ``internal`` errors, never an
    exception.
    """
    try:
        return _run(task, bundle)
    except SimrunError as exc:
        return RunResult(task.index, "error", error=_clean(str(exc), task, bundle))
    except Exception as exc:  # a bug in simrun or MuJoCo: reported, and the run goes on
        return RunResult(task.index, "error", error=f"internal error: {type(exc).__name__}: {exc}", internal=True)


@dataclass(frozen=True, slots=True)
class SceneRuns:
    """The batch :class:`~meshtool.work.batch.SharedWork` of ``simrun test``: runs, with every bundle shared.

    The shared payload maps bundle digest -> :class:`~simrun.scenetest.bundle.Bundle` (each worker gets it
    once and unpacks a bundle on its first run of that scene).
    """

    def prepare(self) -> None:
        """Import the simulator before the first run's deadline starts (loading MuJoCo is not a run's time)."""
        import simrun.run.play  # noqa: F401

    def __call__(self, task: RunTask, bundles: Mapping[str, Bundle], /) -> RunResult:
        """The run's result."""
        return run_task(task, bundles[task.digest])

    def lost(self, task: RunTask, why: str, /) -> RunResult:
        """An ``error``: stopped at ``--timeout``, or an internal error naming how its worker was lost."""
        from meshtool.work.batch import Lost

        if isinstance(why, Lost) and why.timeout is not None:
            message = f"the run did not finish within {why.timeout:g} s and was stopped (--timeout)"
            return RunResult(task.index, "error", error=message)
        if isinstance(why, Lost) and why.failure is not None:
            why = f"the Dask worker running it failed ({why.failure})"
        return RunResult(task.index, "error", error=f"internal error: {why}", internal=True)


def _scene_path(task: RunTask, bundle: Bundle) -> Path:
    folder = unpacked(bundle)
    return folder.joinpath(*PurePosixPath(bundle.scene).parent.parts, task.scene_name)


def _clean(message: str, task: RunTask, bundle: Bundle) -> str:
    """A message without this process's private folder (it names the file as the bundle does)."""
    folder = str(unpacked(bundle))
    return " ".join(message.replace(folder + "/", "").split())


def _run(task: RunTask, bundle: Bundle) -> RunResult:
    from simrun.record.simlog import Recorder
    from simrun.run.play import play
    from simrun.run.session import prepare
    from simrun.scene.scene_file import load_scene

    scene = _scene_path(task, bundle)
    scene.write_bytes(task.scene_text)
    log = scene.with_suffix(suffix("simlog"))
    recorder = None
    try:
        world = load_scene(scene)
        controller = unpacked(bundle).joinpath(*PurePosixPath(task.controller).parts) if task.controller else None
        prepare(world, controller, seed=task.seed)
        observer = Observer(list(task.expectations), world)
        if task.record:
            recorder = Recorder(world, log, scene, list(task.commands), seed=task.seed, controller=controller)
        observer.observe()
        try:
            summary = play(world, task.duration, list(task.commands), progress=lambda _t: observer.observe())
        finally:
            if recorder is not None:
                recorder.close()
        outcomes = observer.finish(summary.simulated_s, summary.wall_s)
        passed = all(o.passed for o in outcomes)
        result = RunResult(task.index, "passed" if passed else "failed", outcomes, wall_s=summary.wall_s)
        if not passed:
            if recorder is not None:
                result.simlog = log.read_bytes()
            if task.thumbnail is not None:
                _thumbnail(world, task.thumbnail, result)
        return result
    except SimrunError as exc:
        result = RunResult(task.index, "error", error=_clean(str(exc), task, bundle))
        if recorder is not None and log.exists():
            result.simlog = log.read_bytes()
        return result
    finally:
        log.unlink(missing_ok=True)
        scene.unlink(missing_ok=True)


def _thumbnail(world: World, size: tuple[int, int], result: RunResult) -> None:
    """A PNG of the world's current state (the main camera, else a free camera framing the bodies)."""
    from PIL import Image

    from simrun.run.render import FrameRenderer

    try:
        renderer = FrameRenderer(world.model, size[0], size[1], "visual", None, world.data)
        buffer = io.BytesIO()
        Image.fromarray(renderer.render(world.data)).save(buffer, format="PNG")
        result.thumbnail = buffer.getvalue()
    except SimrunError as exc:
        result.notes.append(f"no thumbnail: {exc}")
