"""Play and re-simulation sessions: a scene made ready to run, in the one order that recordings depend on.

A ``.simlog`` checkpoint stores the snapshot of every world controller in order, so ``simrun play`` and
``simrun resim`` must create the same controllers in the same order; both go through :func:`prepare`:

1. the scene's entities, then its ``[[sensors]]`` (created by :func:`simrun.scene.scene_file.load_scene`);
2. every ``[[services]]`` binding, in scene order (:meth:`World.check_bindings`);
3. the Python controller module, when the run has one;
4. sensor noise reseeded (sensor *k* gets ``seed + k``);
5. last, the :class:`~simrun.record.simlog.Recorder` (a controller that must see the others' ticks).

:func:`run_play` is ``simrun play`` without the terminal: it returns the summary and writes the video,
frames and recording; :func:`run_resim` is ``simrun resim``.
"""

from __future__ import annotations

import io
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image

from meshtool.formats import output_for, suffix
from simrun.errors import SimrunError, UsageError
from simrun.outfile import check_output, reading, refuse_inputs, world_inputs, write_bytes
from simrun.record.resim import Resimulation
from simrun.record.simlog import Recorder, Simlog, check_model, check_scene, resimulate
from simrun.run.commands import Command
from simrun.run.play import PlayResult, PythonController, encode_gif, encode_mp4, load_commands, play
from simrun.run.render import FrameRenderer
from simrun.scene.scene_file import load_scene
from simrun.world.world import World

#: Default frame size of every rendering command (play, replay, snapshot), pixels (width, height).
DEFAULT_SIZE = (640, 480)
#: Default frames per simulated second of videos.
DEFAULT_FPS = 15.0


#: The outputs of the formats registry a video is written as.
VIDEO_KINDS = ("gif", "mp4")


def video_kind(path: Path) -> str | None:
    """``gif`` or ``mp4`` by ``path``'s suffix (the formats registry), ``None`` for anything else."""
    row = output_for(path)
    return row.name if row is not None and row.name in VIDEO_KINDS else None


def prepare(
    world: World,
    controller: Path | None = None,
    controller_sha256: str | None = None,
    seed: int | None = None,
) -> PythonController | None:
    """Steps 2-4 of the module's order: bind every service, add the controller module, reseed the sensors.

    Args:
        world: A world loaded from a scene (entities and sensors in place).
        controller: A Python controller module (``step(world)``), the user's own file.
        controller_sha256: When given, the controller's SHA-256 must equal it (re-simulation).
        seed: Reseed sensor *k*'s noise with ``seed + k``.

    Returns:
        The controller, when one was given.

    Raises:
        SimrunError: A binding that does not fit (with the scene file and line), or a bad controller.
    """
    world.check_bindings()
    python = PythonController(world, controller, sha256=controller_sha256) if controller is not None else None
    if seed is not None:
        for k, sensor in enumerate(world.sensors.values()):
            sensor.reseed(seed + k)
    return python


@dataclass
class PlayOptions:
    """What ``simrun play`` was asked for.

    Attributes:
        duration: Simulated seconds.
        commands: A TOML file of timed commands, or a ``.py`` controller module.
        video: ``.gif`` or ``.mp4`` output.
        frames_dir: Folder for one PNG per frame.
        render_mode: A render mode, or ``None`` (``visual`` when a video or frames are asked for).
        camera: Camera name (``None``: the main view, else a free camera framing the bodies).
        size: Frame size (width, height), pixels.
        fps: Frames per simulated second.
        realtime: Do not run faster than the wall clock.
        record: ``.simlog`` output.
        seed: Sensor noise seed.
        record_sensors: Sensor names whose readings the recording keeps.
        also: Outputs the caller writes after the run (``--record-as``), checked with the others before it.
    """

    duration: float = 5.0
    commands: Path | None = None
    video: Path | None = None
    frames_dir: Path | None = None
    render_mode: str | None = None
    camera: str | None = None
    size: tuple[int, int] = DEFAULT_SIZE
    fps: float = DEFAULT_FPS
    realtime: bool = False
    record: Path | None = None
    seed: int | None = None
    record_sensors: tuple[str, ...] = ()
    also: tuple[Path, ...] = ()


def run_play(scene: Path, options: PlayOptions, progress: Any = None) -> PlayResult:
    """Load ``scene``, run it as ``options`` say, and write the video, frames and recording.

    Outputs go through :mod:`simrun.outfile` (the caller's output policy applies). Rendering never
    changes the simulation or the summary (see :func:`simrun.run.play.play`).

    Args:
        scene: The scene file.
        options: What to run and write.
        progress: Called with the simulated seconds done (a progress display).

    Returns:
        The summary.

    Raises:
        SimrunError: Any bad input or output, with its file (and line where it has one).
    """
    world = reading(load_scene(scene), options.commands, scene=scene)
    world.compile()  # every file the scene reads is known: no output may be one of them
    refuse_inputs([options.video, options.record, *options.also, *_frames_over_inputs(scene, options, world)])
    for target in (options.video, options.record):  # the .mp4 and .simlog writers do not go through write_bytes
        if target is not None:
            check_output(target)
    if options.video is not None and video_kind(options.video) is None:
        kinds = " or ".join(suffix(kind) for kind in VIDEO_KINDS)
        raise UsageError(f"{options.video}: video must end in {kinds}")
    python = options.commands is not None and options.commands.suffix == ".py"
    commands: list[Command] = load_commands(options.commands) if options.commands and not python else []
    mode = options.render_mode or ("visual" if options.video or options.frames_dir else "none")
    frames: list[Any] = []
    sink = None
    if mode != "none":
        width, height = options.size
        renderer = FrameRenderer(world.model, width, height, mode, options.camera, world.data)
        sink = lambda data: frames.append(renderer.render(data))  # noqa: E731
    elif options.video or options.frames_dir:
        raise SimrunError("render mode 'none' cannot write video or frames")
    prepare(world, options.commands if python else None, seed=options.seed)
    recorder = None
    if options.record:
        controller = options.commands if python else None
        recorder = Recorder(
            world,
            options.record,
            scene,
            commands,
            seed=options.seed or 0,
            sensors=options.record_sensors,
            controller=controller,
        )
    try:
        result = play(world, options.duration, commands, sink, options.fps, options.realtime, progress)
    finally:
        if recorder is not None:
            recorder.close()
    if options.video is not None:
        if video_kind(options.video) == "gif":
            write_bytes(options.video, encode_gif(frames, options.fps))
        else:
            encode_mp4(frames, options.fps, options.video)
    if options.frames_dir is not None:
        for k, frame in enumerate(frames):
            buffer = io.BytesIO()
            Image.fromarray(np.asarray(frame)).save(buffer, format="PNG")
            write_bytes(options.frames_dir / f"frame_{k:05d}{suffix('png')}", buffer.getvalue())
    return result


def _frames_over_inputs(scene: Path, options: PlayOptions, world: World) -> list[Path]:
    """The ``--frames`` files (``frame_NNNNN.png``) that would have the name of an input: the check decides."""
    if options.frames_dir is None:
        return []
    named = [scene, options.commands, *world_inputs(world)]
    return [options.frames_dir / p.name for p in named if p is not None and _FRAME.fullmatch(p.name)]


_FRAME = re.compile(r"frame_\d{5,}\.png", re.IGNORECASE)


def run_resim(log: Path, start: float | None = None, controller: Path | None = None) -> Resimulation:
    """Re-simulate a recording from its first checkpoint, or its last at or before ``start`` (``simrun resim``).

    A recording never names code to run: a run that used a Python controller needs the same file given
    as ``controller``, which runs only if its SHA-256 equals the recorded one. The recording is streamed
    and the run stops at the first frame that differs (:func:`simrun.record.resim.resimulate`).

    Returns:
        Frames compared, the first that differs (``None``: bit-identical) and the checkpoint's time; it
        unpacks as ``(compared, mismatch)``.

    Raises:
        SimrunError: An unreadable or inconsistent recording, a changed scene, a missing or different controller.
    """
    recording = Simlog(log)
    try:
        recorded = recording.controller_sha256()
        if recording.header["controller"] is not None and controller is None:
            raise SimrunError(
                f"{log}: the run used the controller {recording.header['controller']!r}; give that file with "
                "--controller PATH (it runs only if its SHA-256 matches the recording)"
            )
        if controller is not None and recording.header["controller"] is None:
            raise SimrunError(f"{log}: the recorded run used no controller; leave out --controller")
        if controller is not None and recorded is None:
            raise SimrunError(f"{log}: the recording holds no controller SHA-256 to check {controller} against")
        scene = recording.scene_path()
        check_scene(recording, scene)
        world = load_scene(scene)
        check_model(recording, world)
        prepare(world, controller, controller_sha256=recorded)
        return resimulate(world, recording, start)
    finally:
        recording.close()
