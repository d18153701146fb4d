r"""``.simlog`` recordings: versioned, streamed to disk in records, replayable and re-simulatable bit-exactly.

Layout (little-endian): 8-byte magic ``\x89SIMLOG\n``, u16 major, u16 minor, u32 header length, the header
as UTF-8 JSON (MuJoCo version, platform, scene path and SHA-256, seed, timestep, state size, frame period,
the timed commands, the controller module's name and SHA-256), then records: u8 kind, u32 length, payload.
Kind 1, a frame: f64 time and the full integration state (``mj_getState(mjSTATE_INTEGRATION)``, f64
array). Kind 2, a checkpoint: a frame followed by the JSON snapshots of every world controller (drive and
arm services, sensors). Kind 3: f64 time and the recorded sensor readings as JSON. Records are written as
the run goes, so memory stays bounded; the reader streams them back. They go to a temporary file beside
the target, renamed over it when the run ends (also when it ends with an error: the records up to then);
a recording that cannot be written whole (a full disk) leaves no ``.simlog`` and no temporary file.

Version 1.2 (``Recorder(live=True)``, the recordings of ``simrun serve``) is written so that it cannot be
lost: the file is made under a unique temporary name (``O_EXCL``) with its header, renamed over the target
at once, and then grows in chunks: kind 4, u32 length, u32 CRC-32 of the records that follow, the records
(kinds 1-3, and kind 5: a command applied, f64 time and the JSON ``[t, service, entity, call, args]``, so
the header never grows with the commands). In 1.2 a sensor record holds one new sample of one sensor
(``{name: reading}``), written when the sensor samples (the recorder ticks at the fastest recorded sensor's
rate, so a 100 Hz IMU keeps all its samples); a camera's image is stored once per rendered frame as kind 7:
f64 time, u32 JSON length, JSON ``{"name", "format": "png", "width", "height"}``, the PNG bytes. A chunk
goes to the operating system at every checkpoint, every
:data:`CHUNK_BYTES` and every :data:`CHUNK_WALL` wall seconds; finishing writes the last chunk and an end
record (kind 6, length 0), with no second copy of the file. A recording cut short (SIGKILL, a full disk, a
power cut) reads up to its last whole chunk; :attr:`Simlog.truncated` says what was cut.

A recording is data: the reader checks every header key's presence, type and range, every record's
length, time and finiteness, and never runs code it names. Paths in the header (scene, controller) are
relative to the recording's folder, so a recording moves with its scene.

The module is the format's public face; the parts live in :mod:`simrun.record.simlog_format` (kinds,
versions, limits), :mod:`simrun.record.simlog_write` (:class:`Recorder`), :mod:`simrun.record.simlog_read`
(:class:`Simlog`, kinematic replay) and :mod:`simrun.record.resim` (:func:`resimulate`).
"""

from __future__ import annotations

from simrun.record.resim import resimulate
from simrun.record.simlog_format import (
    CHECKPOINT,
    CHUNK,
    CHUNK_BYTES,
    CHUNK_WALL,
    CHUNKED_MINOR,
    COMMAND,
    END,
    FRAME,
    IMAGE,
    KINDS,
    MAGIC,
    MAJOR,
    MAX_FRAME_PERIOD,
    MAX_HEADER_BYTES,
    MAX_STATE_SIZE,
    MIN_FRAME_PERIOD,
    MINOR,
    RESET,
    SENSORS,
    STATE,
    Record,
    SimlogError,
    state_of,
)
from simrun.record.simlog_read import Simlog, check_model, check_scene, replay_states, truncation_note
from simrun.record.simlog_write import Recorder

__all__ = [
    "CHECKPOINT",
    "CHUNK",
    "CHUNKED_MINOR",
    "CHUNK_BYTES",
    "CHUNK_WALL",
    "COMMAND",
    "END",
    "FRAME",
    "IMAGE",
    "KINDS",
    "MAGIC",
    "MAJOR",
    "MAX_FRAME_PERIOD",
    "MAX_HEADER_BYTES",
    "MAX_STATE_SIZE",
    "MINOR",
    "MIN_FRAME_PERIOD",
    "RESET",
    "Record",
    "Recorder",
    "SENSORS",
    "STATE",
    "Simlog",
    "SimlogError",
    "check_model",
    "check_scene",
    "replay_states",
    "resimulate",
    "state_of",
    "truncation_note",
]
