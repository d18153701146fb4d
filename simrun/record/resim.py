"""Re-simulating a ``.simlog`` from a checkpoint and comparing every recorded frame bit for bit.

The layout is described in :mod:`simrun.record.simlog`.
"""

from __future__ import annotations

import math
from typing import Any

import mujoco

from simrun.record.simlog_format import CHECKPOINT, STATE, Record, SimlogError, state_of
from simrun.record.simlog_read import Simlog, check_model
from simrun.world.world import World


class _Comparator:
    """Checks, at each recorded frame time, that the re-simulated state equals the recorded one."""

    def __init__(self, frames: list[Record], period: float, start: float) -> None:
        self.frames, self.period, self.next_time = frames, period, start + period
        self.compared = 0
        self.mismatch: float | None = None

    def tick(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        while self.frames and self.frames[0].time < data.time - 0.5 * model.opt.timestep:
            self.frames.pop(0)
        if self.frames and abs(self.frames[0].time - data.time) <= 0.5 * model.opt.timestep:
            record = self.frames.pop(0)
            self.compared += 1
            if self.mismatch is None and state_of(model, data).tobytes() != record.state.tobytes():
                self.mismatch = record.time

    def reset(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Nothing to reset."""

    def snapshot(self) -> dict[str, Any]:
        """Not part of checkpoints (it is added after them)."""
        return {}

    def restore(self, state: dict[str, Any]) -> None:
        """Nothing to restore."""


def resimulate(world: World, log: Simlog, start: float) -> tuple[int, float | None]:
    """Re-simulate from the last checkpoint at or before ``start`` with the recorded commands.

    The world's controllers must be those of the recording, in the same order (the scene's bindings and
    sensors). Each recorded frame after the checkpoint is compared with the re-simulated state at the same
    point of the step (after the controllers' ticks).

    Returns:
        The number of frames compared and the time of the first frame that differs (``None``: bit-identical).
    """
    if not math.isfinite(start):
        raise SimlogError(f"--from must be a finite time, got {start}")
    model, data = world.model, world.data
    checkpoint: Record | None = None
    later: list[Record] = []
    last_time = 0.0
    for record in log.records():
        last_time = record.time
        if record.kind == CHECKPOINT and record.time <= start + 1e-12:
            checkpoint, later = record, []
        elif checkpoint is not None:
            later.append(record)
    if checkpoint is None:
        raise SimlogError(f"{log.path}: no checkpoint at or before {start} s")
    controllers = list(world.controllers)
    snaps = checkpoint.controllers or []
    if len(controllers) != len(snaps):
        raise SimlogError(f"{log.path}: the world has {len(controllers)} controllers, the recording {len(snaps)}")
    check_model(log, world)
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
    comparator = _Comparator(later, log.frame_period, checkpoint.time)
    world.controllers.append(comparator)
    commands = [c for c in log.commands() if c.t > checkpoint.time + 1e-12]
    dt = model.opt.timestep
    try:
        while data.time < last_time + 0.5 * dt and comparator.frames:
            while commands and commands[0].t <= data.time + 0.5 * dt:
                commands.pop(0).apply(world)
            world.step(1)
    except (KeyError, TypeError, ValueError, IndexError, OverflowError) as exc:
        raise SimlogError(
            f"{log.path}: re-simulation from the checkpoint at t = {checkpoint.time:g} s failed: the recorded "
            f"controller snapshots are not usable ({type(exc).__name__}: {exc})"
        ) from None
    finally:
        world.controllers.remove(comparator)
    return comparator.compared, comparator.mismatch


def _misfit(template: Any, value: Any, where: str) -> str | None:
    """Why a recorded snapshot does not have the shape of a fresh one (``template``), or ``None``.

    Keys and JSON types must match (numbers may be ints or floats; ``None`` and empty containers in the
    template accept any value of plain JSON data).
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
        if not isinstance(value, list) or len(value) != len(template):
            return f"{here}: expected an array of {len(template)}"
        return next((p for k, t in enumerate(template) if (p := _misfit(t, value[k], f"{where}[{k}]"))), None)
    if isinstance(template, dict):
        if not isinstance(value, dict) or set(value) != set(template):
            return f"{here}: expected the keys {sorted(template)}"
        return next((p for k, t in template.items() if (p := _misfit(t, value[k], f"{where}.{k}".lstrip(".")))), None)
    return None
