"""Recording a served world: a ``.simlog`` whose commands are the service calls clients made while it ran.

:class:`LiveRecording` writes a chunked version-1.2 recording in place (:class:`~simrun.record.simlog.Recorder`
with ``live=True``): the target exists from the start (made under a unique ``O_EXCL`` temporary name and
renamed over it at once, so no other file is ever touched), frames, checkpoints, sensor readings and the
commands applied (each at the simulated time it was applied, :meth:`simrun.serve.loop.SimLoop.apply`) go
into chunks as they happen, and finishing (``POST /api/recording/stop``, SIGINT/SIGTERM, a crash of the
simulation thread) writes the last chunk and an end record: no spool, no second copy, and a header that
does not grow with the commands. A server killed outright (SIGKILL) leaves a recording readable up to its
last chunk; a full disk ends the recording with one error and keeps what was written, while the world
goes on. ``simrun resim`` applies the commands at the same steps: a served run re-simulates bit for bit.
With ``mcap``, the MCAP is written as the recording goes too (:class:`simrun.record.mcap_export.McapStream`,
the recorder's listener, through foxglove-sdk's writer and the channels of the live Foxglove stream): the
messages :func:`simrun.record.mcap_export.export_mcap` would write from the finished ``.simlog``, in place
from the start, a chunk ended with every chunk of the recording (a SIGKILL leaves its whole chunks
readable), finished with its summary by :meth:`LiveRecording.finish`; nothing is converted at the end.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from simrun.outfile import check_output, scene_files
from simrun.record.simlog import Recorder
from simrun.run.commands import Command
from simrun.world.world import World

if TYPE_CHECKING:
    from simrun.record.mcap_export import McapStream
    from simrun.serve.loop import SimLoop


class LiveRecording:
    """A recording of a served world from now until :meth:`finish` (see the module).

    Args:
        world: The served world, its services bound (the recorder must be its last controller).
        loop: The simulation loop (its ``applied`` commands are the run's).
        path: The ``.simlog`` to write.
        scene: The scene file served.
        sensors: Sensors whose readings are kept.
        seed: The sensor seed, recorded.
        mcap: Also write the recording as MCAP here, as it is recorded.

    Raises:
        SimrunError: The output is refused (an input, a file simrun did not write) or cannot be made.
    """

    def __init__(
        self,
        world: World,
        loop: SimLoop,
        path: Path,
        scene: Path,
        sensors: tuple[str, ...] = (),
        seed: int = 0,
        mcap: Path | None = None,
    ) -> None:
        check_output(path, inputs=scene_files(scene), world=world)
        if mcap is not None:
            check_output(mcap, inputs=[*scene_files(scene), path], world=world)
        self.path, self.mcap, self.loop = path, mcap, loop
        self.start = float(world.time)
        unknown = [n for n in sensors if n not in world.sensors]  # the recorder's refusal, before any file is made
        self.stream: McapStream | None = None
        if mcap is not None and not unknown:
            from simrun.record.mcap_export import McapStream

            self.stream = McapStream(world, mcap, path, sensors)
        try:
            self.recorder = Recorder(world, path, scene, [], seed=seed, sensors=sensors, live=True,
                                     listener=self.stream, prelude=list(loop.edit_history))  # fmt: skip
        except BaseException:  # whatever stops it (Ctrl+C included), the MCAP made beside it goes; re-raised
            if self.stream is not None:
                self.stream.discard()
            raise
        if self.stream is not None:
            self.stream.start()
        self.active = True
        self.written: list[Path] = []

    def describe(self) -> dict[str, Any]:
        """``{"path", "active", "since", "frames", "error"}`` for the state document (``error``: why it ended)."""
        return {
            "path": str(self.path),
            "active": self.active and self.recorder.failed is None,
            "since": self.start,
            "frames": self.recorder.frames,
            "error": self.recorder.failed,
        }

    def command(self, command: Command) -> None:
        """Record a service command applied at ``command.t`` (from the loop thread)."""
        if self.active and command.t >= self.start:
            self.recorder.command(command)

    def finish(self) -> list[Path]:
        """Stop recording: write the last chunk and the end record (and the MCAP); returns the files written.

        Raises:
            SimrunError: The recording ended early (a full disk): the file keeps what was written.
        """
        if not self.active:
            return self.written
        self.active = False
        self.written = [self.path]
        try:
            self.recorder.close()  # raises the failure that ended it early; the file stays
        finally:
            if self.stream is not None:
                self.written.append(self.stream.out)
                self.stream.close()  # its summary (raises why it ended early; its whole chunks stay)
        return self.written
