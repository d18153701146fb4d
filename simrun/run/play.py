"""Headless playback: run a world with timed service commands, render video or frames, summarise.

``simrun play`` uses :func:`play`; commands come from a TOML file of ``[[commands]]`` tables
(:mod:`simrun.run.commands`) or from a Python controller module given on the command line.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image

from simrun.errors import SimrunError
from simrun.robots.contract import robots as robot_contracts
from simrun.run.commands import Command, check_commands, load_commands
from simrun.safeio import FileReadError, read_regular
from simrun.world.world import World

__all__ = ["Command", "PlayResult", "PythonController", "encode_gif", "encode_mp4", "load_commands", "play"]


class PythonController:
    """A user's control module as a world controller: its ``step(world)`` runs every ``period`` seconds.

    The module is the user's own code, named on the command line (never taken from a data file: a
    ``.simlog`` records only its SHA-256, which ``simrun resim --controller`` checks before running it);
    module-level state is not checkpointed, so a re-simulation from a checkpoint is exact only for
    controllers that keep their state in the world.

    Args:
        world: The world it controls.
        path: The ``.py`` file.
        period: Seconds between calls of ``step(world)``.
        sha256: When given, the file's SHA-256 must equal it (hex), else nothing is run.

    Attributes:
        sha256: The SHA-256 (hex) of the module's source as run.

    Raises:
        SimrunError: The file cannot be read, differs from ``sha256``, fails to import or has no ``step``.
    """

    def __init__(self, world: World, path: Path, period: float = 0.02, sha256: str | None = None) -> None:
        import importlib.util

        try:
            source = read_regular(path, "controller")
        except FileReadError as exc:
            raise SimrunError(str(exc)) from None
        self.sha256 = hashlib.sha256(source).hexdigest()
        if sha256 is not None and sha256 != self.sha256:
            raise SimrunError(
                f"{path}: controller SHA-256 {self.sha256[:16]}... differs from the recorded {sha256[:16]}...; "
                "give the controller file the run used"
            )
        spec = importlib.util.spec_from_loader(f"simrun_controller_{path.stem}", loader=None, origin=str(path))
        if spec is None:
            raise SimrunError(f"{path}: cannot be loaded as a Python module")
        module = importlib.util.module_from_spec(spec)
        module.__file__ = str(path)
        try:
            exec(compile(source, str(path), "exec"), module.__dict__)  # the user's own module, checked above
        except Exception as exc:  # the user's module failed to import: one line, with its error
            raise SimrunError(f"{path}: {type(exc).__name__}: {exc}") from None
        if not callable(getattr(module, "step", None)):
            raise SimrunError(f"{path}: a controller module needs a function step(world)")
        self.world, self.path, self.period, self.next_time = world, path, period, world.time
        self._step = module.step
        world.controllers.append(self)

    def tick(self, model: Any, data: Any) -> None:
        """Run the module's ``step(world)`` (its errors are the user's: one line naming the module)."""
        try:
            self._step(self.world)
        except SimrunError as exc:
            raise SimrunError(f"{self.path}: step(world) at t = {data.time:.3f} s: {exc}") from None
        except Exception as exc:
            raise SimrunError(f"{self.path}: step(world) raised {type(exc).__name__}: {exc}") from None

    def reset(self, model: Any, data: Any) -> None:
        """Nothing to reset."""

    def snapshot(self) -> dict[str, Any]:
        """Only the clock (see the class note)."""
        return {"next_time": self.next_time}

    def restore(self, state: dict[str, Any]) -> None:
        """Inverse of :meth:`snapshot`."""
        self.next_time = float(state["next_time"])
        self.world.reschedule()  # next_time may have moved earlier


@dataclass
class PlayResult:
    """What a run did (the ``--json`` summary)."""

    simulated_s: float
    wall_s: float
    steps: int
    frames: int
    distances: dict[str, float] = field(default_factory=dict)
    sensor_samples: dict[str, int] = field(default_factory=dict)
    warnings: dict[str, int] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary with steps/s and the real-time factor."""
        return {
            "simulated_s": self.simulated_s,
            "wall_s": self.wall_s,
            "steps": self.steps,
            "steps_per_s": self.steps / self.wall_s if self.wall_s > 0 else math.inf,
            "realtime_factor": self.simulated_s / self.wall_s if self.wall_s > 0 else math.inf,
            "frames": self.frames,
            "distances_m": self.distances,
            "sensor_samples": self.sensor_samples,
            "warnings": self.warnings,
        }


#: Simulated seconds between the samples of a robot's position that the reported distance adds up
#: (a fixed grid counted in physics steps from the start of the run: rendering never moves it).
DISTANCE_PERIOD = 0.02
#: Longest stretch stepped between two looks at the clock (progress, real-time pacing), seconds.
CHUNK_SECONDS = 0.1


def play(
    world: World,
    duration: float,
    commands: list[Command] | None = None,
    frame_sink: Any = None,
    fps: float = 15.0,
    realtime: bool = False,
    progress: Any = None,
) -> PlayResult:
    """Run ``world`` for ``duration`` simulated seconds.

    Rendering never changes what is simulated or reported: commands are applied, and robot positions
    sampled for the distance (every :data:`DISTANCE_PERIOD` s), at the first physics step where they are
    due, whatever frames are taken in between; a frame is taken at the first step at or after its time.

    Args:
        world: The world (compiled on demand).
        duration: Seconds of simulated time.
        commands: Timed service calls, applied when their time comes.
        frame_sink: Called as ``frame_sink(data)`` ``fps`` times per simulated second (rendering).
        fps: Frame rate of ``frame_sink``.
        realtime: Sleep so simulated time does not run ahead of the wall clock.
        progress: Called with the simulated time after each chunk (a progress bar).

    Returns:
        The summary.
    """
    if not (math.isfinite(duration) and duration >= 0):
        raise SimrunError(f"duration must be a finite number of seconds >= 0, got {duration}")
    if frame_sink and not (math.isfinite(fps) and fps > 0):
        raise SimrunError(f"fps must be a positive number, got {fps}")
    check_commands(world, list(commands or []))
    model, data = world.model, world.data
    pending = list(commands or [])
    roots = {name: robot.root for name, robot in robot_contracts(world).items() if robot.mobile}
    robots = {name: np.array(world.body(root).xpos) for name, root in roots.items()}
    travelled = dict.fromkeys(robots, 0.0)
    start_wall = time.perf_counter()
    dt = model.opt.timestep
    total = round(duration / dt)  # as World.run
    sample_every = max(1, round(DISTANCE_PERIOD / dt))
    chunk = max(1, round(CHUNK_SECONDS / dt))
    frame_period = 1.0 / fps if frame_sink else math.inf
    next_frame = data.time
    frames = done = 0
    start_time = data.time
    while done < total:
        while pending and pending[0].t <= data.time + 0.5 * dt:
            pending.pop(0).apply(world)
        if frame_sink and data.time + 0.5 * dt >= next_frame:
            frame_sink(data)
            frames += 1
            while next_frame <= data.time + 0.5 * dt:
                next_frame += frame_period
        limit = min(total - done, sample_every - done % sample_every, chunk)
        if pending:
            limit = min(limit, max(1, _steps_until(data.time, dt, pending[0].t, limit)))
        if frame_sink:
            limit = min(limit, max(1, _steps_until(data.time, dt, next_frame, limit)))
        world.step(limit)
        done += limit
        if done % sample_every == 0 or done == total:
            for name, previous in robots.items():
                now = np.array(world.body(roots[name]).xpos)
                travelled[name] += float(np.linalg.norm(now[:2] - previous[:2]))
                robots[name] = now
        if realtime:
            ahead = (data.time - start_time) - (time.perf_counter() - start_wall)
            if ahead > 0:
                time.sleep(ahead)
        if progress is not None:
            progress(data.time - start_time)
    wall = time.perf_counter() - start_wall
    samples = {name: int(sensor.samples) for name, sensor in world.sensors.items()}
    return PlayResult(float(duration), wall, total, frames, travelled, samples, world.warnings())


def _steps_until(now: float, dt: float, target: float, limit: int) -> int:
    """Steps after which ``target`` is due (``time + dt/2 >= target``), at most ``limit``.

    Time is added step by step as MuJoCo adds it, so the step found is the one the clock check finds.
    """
    steps = 0
    while steps < limit and now + 0.5 * dt < target:
        now += dt
        steps += 1
    return steps


def encode_gif(frames: list[np.ndarray], fps: float) -> bytes:
    """Frames as an animated GIF (Pillow), looping forever."""
    if not frames:
        raise SimrunError("no frames to encode")
    images = [Image.fromarray(f) for f in frames]
    buffer = io.BytesIO()
    images[0].save(
        buffer,
        format="GIF",
        save_all=True,
        append_images=images[1:],
        duration=round(1000 / fps),
        loop=0,
        optimize=False,
    )
    return buffer.getvalue()


def encode_mp4(frames: list[np.ndarray], fps: float, path: Path) -> None:
    """Frames as an H.264 MP4 through imageio-ffmpeg, written to a temporary file and renamed."""
    import imageio_ffmpeg

    if not frames:
        raise SimrunError("no frames to encode")
    height, width = frames[0].shape[:2]
    tmp = path.with_name(f".{path.name}.tmp.mp4")
    try:  # a path that cannot be written (too long a name, no folder) fails here, before ffmpeg says so itself
        os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_CLOEXEC, 0o644))
    except (OSError, ValueError) as exc:
        raise SimrunError(f"cannot write {path}: {getattr(exc, 'strerror', None) or exc}") from None
    try:
        writer = imageio_ffmpeg.write_frames(
            str(tmp),
            (width, height),
            fps=fps,
            codec="libx264",
            pix_fmt_out="yuv420p",
            macro_block_size=2,
            ffmpeg_log_level="error",
        )
        writer.send(None)
        for frame in frames:
            writer.send(np.ascontiguousarray(frame))
        writer.close()
        tmp.replace(path)
    except (OSError, RuntimeError) as exc:
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)
        raise SimrunError(f"cannot write {path}: {exc}") from None
