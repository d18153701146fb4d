"""Recording a served world: a ``.simlog`` whose commands are the service calls clients made while it ran.

A ``.simlog`` header lists the run's timed commands, but a served world's commands arrive while it runs.
:class:`LiveRecording` therefore streams the frames and checkpoints through the ordinary
:class:`~simrun.record.simlog.Recorder` into a spool file beside the target (``.NAME.spool``, header without
commands); when the recording ends (``POST /api/recording/stop``, or the server shuts down) it writes the
target: the same header with the commands applied since the recording started (each at the simulated
time it was applied, :meth:`simrun.serve.loop.SimLoop.apply`), then the spooled records, and removes the
spool. ``simrun resim`` applies those commands at the same steps: a served run re-simulates bit for bit.
With ``mcap``, the finished recording is also converted (:func:`simrun.record.mcap_export.export_mcap`).
"""

from __future__ import annotations

import json
import struct
from pathlib import Path
from typing import TYPE_CHECKING, Any

from meshtool.errors import OutputError
from meshtool.files.outdir import AtomicFile
from simrun.errors import SimrunError
from simrun.outfile import check_output
from simrun.record.simlog import MAGIC, MAJOR, MINOR, Recorder
from simrun.world.world import World

if TYPE_CHECKING:
    from simrun.serve.loop import SimLoop

#: Bytes copied at a time from the spool to the recording.
_COPY = 1 << 20


class LiveRecording:
    """A recording of a served world from now until :meth:`finish` (see the module).

    Args:
        world: The served world, its services bound (the recorder must be its last controller).
        loop: The simulation loop (its ``applied`` commands are the run's).
        path: The ``.simlog`` to write.
        scene: The scene file served.
        sensors: Sensors whose readings are kept.
        seed: The sensor seed, recorded.
        mcap: Also write the finished recording as MCAP here.

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
        check_output(path, inputs=[scene])
        if mcap is not None:
            check_output(mcap, inputs=[scene, path])
        self.path, self.mcap, self.loop = path, mcap, loop
        self.start = float(world.time)
        self._first_command = len(loop.applied)
        self.spool = path.with_name(f".{path.name}.spool")
        self.recorder = Recorder(world, self.spool, scene, [], seed=seed, sensors=sensors)
        self.active = True
        self.written: list[Path] = []

    def describe(self) -> dict[str, Any]:
        """``{"path", "active", "since", "frames"}`` for the state document."""
        return {"path": str(self.path), "active": self.active, "since": self.start, "frames": self.recorder.frames}

    def finish(self) -> list[Path]:
        """Stop recording and write the ``.simlog`` (and the MCAP); returns the files written.

        Raises:
            SimrunError: The recording cannot be written (nothing is left behind).
        """
        if not self.active:
            return self.written
        self.active = False
        commands = [c for c in self.loop.applied[self._first_command :] if c.t >= self.start]
        try:
            self.recorder.close()
            self._write(commands)
        finally:
            self.spool.unlink(missing_ok=True)
        self.written = [self.path]
        if self.mcap is not None:
            from simrun.record.mcap_export import export_mcap

            export_mcap(self.path, self.mcap)
            self.written.append(self.mcap)
        return self.written

    def _write(self, commands: list[Any]) -> None:
        with self.spool.open("rb") as spool:
            head = spool.read(16)
            length = struct.unpack("<I", head[12:16])[0]
            header = json.loads(spool.read(length).decode("utf-8"))
            header["commands"] = [[c.t, c.service, c.entity, c.call, list(c.args)] for c in commands]
            raw = json.dumps(header, sort_keys=True).encode("utf-8")
            try:
                out = AtomicFile(self.path)
            except OutputError as exc:
                raise SimrunError(f"{self.path}: {exc.message}") from None
            try:
                out.write(MAGIC + struct.pack("<HHI", MAJOR, MINOR, len(raw)) + raw)
                while block := spool.read(_COPY):
                    out.write(block)
                out.commit()
            except OutputError as exc:
                out.abort()
                raise SimrunError(f"{self.path}: {exc.message}; nothing recorded") from None
