"""The ``.simlog`` format: magic, versions, record kinds, limits, the error type and a frame's state.

The layout itself is described in :mod:`simrun.record.simlog`; :mod:`simrun.record.simlog_write` writes it,
:mod:`simrun.record.simlog_read` reads it and :mod:`simrun.record.resim` re-simulates it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt

from meshtool.formats import output_named
from simrun.errors import SimrunError

MAGIC = output_named("simlog").magic[0]  # the formats registry's row
MAJOR, MINOR = 1, 1
#: The minor version of chunked recordings (``Recorder(live=True)``).
CHUNKED_MINOR = 2
FRAME, CHECKPOINT, SENSORS, CHUNK, COMMAND, END, IMAGE, RESET, EDIT = 1, 2, 3, 4, 5, 6, 7, 8, 9
#: The record kinds a reader knows (anything else is refused as corrupt: a new kind is a new reader).
KINDS = {FRAME: "frame", CHECKPOINT: "checkpoint", SENSORS: "sensors", CHUNK: "chunk", COMMAND: "command",
         END: "end", IMAGE: "image", RESET: "reset", EDIT: "edit"}  # fmt: skip
#: Bytes of records gathered before a chunk is written (live recordings).
CHUNK_BYTES = 1 << 20
#: Longest wall time records wait before their chunk is written, seconds (live recordings).
CHUNK_WALL = 0.5
STATE = mujoco.mjtState.mjSTATE_INTEGRATION
#: Largest header accepted, bytes.
MAX_HEADER_BYTES = 16 * 1024 * 1024
#: Frame periods accepted, seconds.
MIN_FRAME_PERIOD, MAX_FRAME_PERIOD = 1e-5, 60.0
#: Largest state size accepted (numbers per frame).
MAX_STATE_SIZE = 10_000_000
_HEADER: dict[str, tuple[type, ...]] = {
    "mujoco": (str,),
    "platform": (str,),
    "scene": (str,),
    "scene_sha256": (str,),
    "seed": (int,),
    "timestep": (int, float),
    "state_size": (int,),
    "frame_period": (int, float),
    "commands": (list,),
    "sensors": (list,),
    "controller": (str, type(None)),
}


class SimlogError(SimrunError, ValueError):
    """A ``.simlog`` is truncated, corrupt, or of an unknown major version."""


def state_of(model: mujoco.MjModel, data: mujoco.MjData) -> npt.NDArray[np.float64]:
    """The full integration state of ``data``."""
    state = np.empty(mujoco.mj_stateSize(model, STATE))
    mujoco.mj_getState(model, data, state, STATE)
    return state


@dataclass(frozen=True, slots=True)
class Record:
    """One record in time order: a frame (checkpoints: and the controllers' snapshots), a command, a reset.

    Attributes:
        kind: :data:`FRAME`, :data:`CHECKPOINT`, :data:`SENSORS`, :data:`COMMAND` or :data:`RESET`.
        time: Simulated time, seconds.
        state: The integration state (``mjSTATE_INTEGRATION``, f64, the header's ``state_size``); empty
            for other kinds.
        controllers: A checkpoint's controller snapshots in world order (sensor records: ``[readings]``).
        command: A command record's command (version 1.2). An edit record (:data:`EDIT`, ``simrun serve --edit``)
            is read as a command record whose command is its :class:`~simrun.world.edit_apply.EditRecord`
            (``t``, ``kind``, ``args``; applied as a command is: ``apply(world)``).
        info: A reset record's JSON object (``{"count": resets since the last record, "warnings": {...}}``).
        offset: The record's byte offset in the file.
    """

    kind: int
    time: float
    state: npt.NDArray[np.float64]
    controllers: list[dict[str, Any]] | None
    command: Any = None
    info: dict[str, Any] | None = None
    offset: int = 0


def _refuse_constant(name: str) -> float:
    """JSON's ``NaN`` is refused in recordings; ``Infinity`` is kept (a drive's never-commanded clock is -inf)."""
    if name == "NaN":
        raise ValueError("NaN in the data")
    return float(name.replace("Infinity", "inf"))
