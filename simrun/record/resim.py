"""Re-simulating a ``.simlog`` from a checkpoint and comparing every recorded frame bit for bit.

:func:`resimulate` streams the recording twice (one record in memory at a time): once to find the
checkpoint (the first one by default, else the last at or before ``start``), then from it, stepping the
world and comparing each recorded frame with the re-simulated state at the same point of the step; it stops
at the first frame that differs and says what differs (the state component, its index and name, both
values). Commands are applied as recorded: version 1.1's timed commands after the checkpoint's time, a
chunked recording's command records after the checkpoint record (a command applied at the instant a
recording started comes after its first checkpoint). The layout is described in :mod:`simrun.record.simlog`.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt

from simrun.errors import SimrunError
from simrun.record.simlog_format import CHECKPOINT, CHUNKED_MINOR, COMMAND, FRAME, STATE, Record, SimlogError, state_of
from simrun.record.simlog_read import Simlog, check_model
from simrun.run.commands import Command
from simrun.world.world import World

#: The parts of ``mjSTATE_INTEGRATION`` in MuJoCo's order (``mj_getState``), for naming what differs.
_PARTS = (
    ("time", mujoco.mjtState.mjSTATE_TIME),
    ("qpos", mujoco.mjtState.mjSTATE_QPOS),
    ("qvel", mujoco.mjtState.mjSTATE_QVEL),
    ("act", mujoco.mjtState.mjSTATE_ACT),
    ("qacc_warmstart", mujoco.mjtState.mjSTATE_WARMSTART),
    ("ctrl", mujoco.mjtState.mjSTATE_CTRL),
    ("qfrc_applied", mujoco.mjtState.mjSTATE_QFRC_APPLIED),
    ("xfrc_applied", mujoco.mjtState.mjSTATE_XFRC_APPLIED),
    ("eq_active", mujoco.mjtState.mjSTATE_EQ_ACTIVE),
    ("mocap_pos", mujoco.mjtState.mjSTATE_MOCAP_POS),
    ("mocap_quat", mujoco.mjtState.mjSTATE_MOCAP_QUAT),
    ("userdata", mujoco.mjtState.mjSTATE_USERDATA),
    ("plugin_state", mujoco.mjtState.mjSTATE_PLUGIN),
)


@dataclass(frozen=True, slots=True)
class Mismatch:
    """The first recorded frame the re-simulation does not reproduce.

    Attributes:
        time: The frame's simulated time, seconds.
        what: What differs, one phrase (``qpos[7] (joint 'boebot/left_wheel'): recorded 0.1, re-simulated 0.2``).
    """

    time: float
    what: str


@dataclass(frozen=True, slots=True)
class Resimulation:
    """What :func:`resimulate` did; unpacks as ``(compared, mismatch)``.

    Attributes:
        compared: Recorded frames compared (the checkpoint's own not counted).
        mismatch: The first frame that differs, ``None``: bit-identical.
        start: The time of the checkpoint it started from, seconds.
    """

    compared: int
    mismatch: Mismatch | None
    start: float

    def __iter__(self) -> Iterator[Any]:
        yield self.compared
        yield self.mismatch


class _Comparator:
    """A controller that compares the state with the next recorded frame at the step where its time comes.

    It is due at that frame's time (set by :func:`resimulate` as frames are read; ``period`` infinite), so it
    ticks once per frame, after the others' ticks.
    """

    def __init__(self, frames: deque[Record]) -> None:
        self.frames, self.period = frames, math.inf
        self.next_time = frames[0].time if frames else math.inf
        self.compared = 0
        self.mismatch: Mismatch | None = None

    def tick(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        half = 0.5 * model.opt.timestep
        if self.mismatch is not None or not self.frames:
            return
        record = self.frames[0]
        if record.time < data.time - half:
            self.mismatch = Mismatch(record.time, f"no re-simulated step at the recorded time (now {data.time!r} s)")
        elif record.time <= data.time + half:
            self.frames.popleft()
            state = state_of(model, data)
            if state.tobytes() != record.state.tobytes():
                self.mismatch = Mismatch(record.time, difference(model, record.state, state))
            else:
                self.compared += 1

    def reset(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Nothing to reset."""

    def snapshot(self) -> dict[str, Any]:
        """Not part of checkpoints (it is added after them)."""
        return {}

    def restore(self, state: dict[str, Any]) -> None:
        """Nothing to restore."""


def difference(model: mujoco.MjModel, recorded: npt.NDArray[np.float64], resimulated: npt.NDArray[np.float64]) -> str:
    """The first number that differs between two integration states, named (part, index, joint), both values."""
    index = int(np.flatnonzero(recorded.view(np.uint64) != resimulated.view(np.uint64))[0])
    at, name = index, "state"
    for part_name, part in _PARTS:
        size = int(mujoco.mj_stateSize(model, part))
        if at < size:
            name = part_name
            break
        at -= size
    where = f"{name}[{at}]" if name != "time" else "time"
    if name in ("qpos", "qvel"):
        address = model.jnt_qposadr if name == "qpos" else model.jnt_dofadr
        joints = [j for j in range(model.njnt) if address[j] <= at]
        if joints:
            where += f" (joint {model.joint(max(joints, key=lambda j: address[j])).name!r})"
    return f"{where}: recorded {recorded[index]!r}, re-simulated {resimulated[index]!r}"


def _checkpoint(log: Simlog, start: float | None) -> Record:
    """The first checkpoint (``start`` ``None``) or the last at or before ``start``; streamed."""
    chosen: Record | None = None
    for record in log.records(edits=True):  # edits before it are applied by resimulate (_edits_before)
        if record.kind != CHECKPOINT:
            continue
        if start is None:
            return record
        if record.time > start + 1e-12:
            break
        chosen = record
    if chosen is None:
        if start is None:
            raise SimlogError(f"{log.path}: the recording holds no checkpoint to start from")
        raise SimlogError(f"{log.path}: no checkpoint at or before {start} s")
    return chosen


def resimulate(world: World, log: Simlog, start: float | None = None) -> Resimulation:
    """Re-simulate from the recording's first checkpoint, or the last at or before ``start``, with its commands.

    The world's controllers must be those of the recording, in the same order (the scene's bindings and
    sensors). Each recorded frame after the checkpoint is compared with the re-simulated state at the same
    point of the step (after the controllers' ticks); the run stops at the first that differs.

    Args:
        world: The recording's scene, loaded and prepared (:func:`simrun.run.session.prepare`).
        log: The recording.
        start: Seconds; ``None``: the first checkpoint.

    Returns:
        Frames compared, the first mismatch (``None``: bit-identical) and the checkpoint's time.

    Raises:
        SimlogError: A malformed recording (as it is read), no such checkpoint, snapshots that do not fit.
    """
    if start is not None and not math.isfinite(start):
        raise SimlogError(f"--from must be a finite time, got {start}")
    checkpoint = _checkpoint(log, start)
    check_model(log, world)
    _edits_before(world, log, checkpoint)
    model, data = world.model, world.data
    controllers = list(world.controllers)
    snaps = checkpoint.controllers or []
    if len(controllers) != len(snaps):
        raise SimlogError(f"{log.path}: the world has {len(controllers)} controllers, the recording {len(snaps)}")
    if int(mujoco.mj_stateSize(model, STATE)) != len(checkpoint.state):
        raise SimlogError(
            f"{log.path}: checkpoint at t = {checkpoint.time:g} s holds {len(checkpoint.state)} state values, "
            f"the (edited) world has {int(mujoco.mj_stateSize(model, STATE))}"
        )
    mujoco.mj_setState(model, data, checkpoint.state, STATE)
    mujoco.mj_forward(model, data)
    for k, (controller, snap) in enumerate(zip(controllers, snaps, strict=True)):
        problem = _misfit(controller.snapshot(), snap, "")
        if problem:
            raise SimlogError(
                f"{log.path}: checkpoint at t = {checkpoint.time:g} s: snapshot {k} ({type(controller).__name__}) "
                f"does not fit: {problem}"
            )
        try:
            controller.restore(snap)
        except (KeyError, TypeError, ValueError, IndexError) as exc:
            raise SimlogError(
                f"{log.path}: checkpoint at t = {checkpoint.time:g} s: snapshot {k} does not fit "
                f"{type(controller).__name__} ({type(exc).__name__}: {exc})"
            ) from None
    world.reschedule()
    chunked = log.minor >= CHUNKED_MINOR
    commands: deque[Command] = deque([] if chunked else [c for c in log.commands() if c.t > checkpoint.time + 1e-12])
    events = (r for r in log.events() if r.offset > checkpoint.offset)
    frames: deque[Record] = deque()

    def fill() -> None:
        """Read on to the next frame, keeping the commands on the way."""
        for record in events:
            if record.kind == COMMAND and chunked:
                commands.append(record.command)
            elif record.kind in (FRAME, CHECKPOINT):
                frames.append(record)
                return

    fill()
    comparator = _Comparator(frames)
    world.controllers.append(comparator)
    half = 0.5 * model.opt.timestep
    try:
        while frames and comparator.mismatch is None:
            while commands and commands[0].t <= world.data.time + half:  # an edit gives the world a new MjData
                commands.popleft().apply(world)
            world.step(1)
            if not frames:
                fill()
                comparator.next_time = frames[0].time if frames else math.inf
                world.reschedule()
    except (KeyError, TypeError, ValueError, IndexError, OverflowError) as exc:
        if isinstance(exc, SimlogError):
            raise
        raise SimlogError(
            f"{log.path}: re-simulation from the checkpoint at t = {checkpoint.time:g} s failed: the recorded "
            f"controller snapshots are not usable ({type(exc).__name__}: {exc})"
        ) from None
    finally:
        world.controllers.remove(comparator)
    return Resimulation(comparator.compared, comparator.mismatch, checkpoint.time)


def _edits_before(world: World, log: Simlog, checkpoint: Record) -> None:
    """Apply to ``world`` every edit recorded before ``checkpoint`` (``simrun serve --edit``), in file order.

    A recording started after edits begins with them (its prelude), and a later checkpoint comes after those
    made while recording: applied first, at their simulated times, they turn the scene's world into the one
    the checkpoint holds the state of (which then replaces the state they leave).

    Raises:
        SimlogError: An edit the rebuilt world refuses.
    """
    from simrun.world.edit_apply import EditRecord  # the edit modules load only for recordings with edits

    if not log.edits:
        return
    for record in log.events():
        if record.offset >= checkpoint.offset:
            return
        edit = record.command
        if record.kind == COMMAND and isinstance(edit, EditRecord):
            world.data.time = edit.t
            try:
                edit.apply(world)
            except SimrunError as exc:
                raise SimlogError(
                    f"{log.path}: byte {record.offset}: the edit at t = {edit.t:g} s before the checkpoint at "
                    f"t = {checkpoint.time:g} s does not apply to the scene's world: {exc}"
                ) from None


def _misfit(template: Any, value: Any, where: str) -> str | None:
    """Why a recorded snapshot does not have the shape of a fresh one (``template``), or ``None``.

    Keys and JSON types must match (numbers may be ints or floats; ``None`` and empty containers in the
    template accept any value of plain JSON data); an array of arrays or objects (records, such as the pushes
    running) may have any length, each record of the shape of the template's first.
    """
    here = where or "snapshot"
    if template is None or (isinstance(template, dict | list) and not template):
        return None
    if isinstance(template, bool) or isinstance(value, bool):
        return None if isinstance(template, bool) and isinstance(value, bool) else f"{here}: expected a boolean"
    if isinstance(template, int | float):
        return None if isinstance(value, int | float) else f"{here}: expected a number, got {type(value).__name__}"
    if isinstance(template, str):
        return None if isinstance(value, str) else f"{here}: expected a string"
    if isinstance(template, list):
        if isinstance(template[0], dict | list) and isinstance(value, list):  # records (pushes running now):
            # as many as there are at that instant, each of the template's first record's shape
            return next((p for k, v in enumerate(value) if (p := _misfit(template[0], v, f"{where}[{k}]"))), None)
        if not isinstance(value, list) or len(value) != len(template):
            return f"{here}: expected an array of {len(template)}"
        return next((p for k, t in enumerate(template) if (p := _misfit(t, value[k], f"{where}[{k}]"))), None)
    if isinstance(template, dict):
        if not isinstance(value, dict) or set(value) != set(template):
            return f"{here}: expected the keys {sorted(template)}"
        return next((p for k, t in template.items() if (p := _misfit(t, value[k], f"{where}.{k}".lstrip(".")))), None)
    return None
