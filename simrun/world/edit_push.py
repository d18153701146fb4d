"""Pushing bodies of a running world: a force and torque for a while (see :mod:`simrun.world.edit`)."""

from __future__ import annotations

import math
from typing import Any

import mujoco
import numpy as np

from simrun.world.edit import EditError, _entity, edit_fail
from simrun.world.edit_carry import _bound_to
from simrun.world.registry.conversion import convert
from simrun.world.world import World

#: Longest push of :func:`apply_force`, simulated seconds.
MAX_PUSH_SECONDS = 3600.0
#: Largest force (N) or torque (N m) component of a push.
MAX_WRENCH = 1e6


class Pushes:
    """A world controller holding the wrenches of :func:`apply_force` until each one's end time.

    ``xfrc_applied`` of a pushed body is the sum of its pushes still running (world frame: force in N, torque
    in N m, at the body's centre of mass); it is cleared at the first step at or after a push's end.
    ``period`` is set at each tick to reach the next end (the world adds it to ``next_time``).

    Args:
        world: The world (this controller appends itself to its controllers).
    """

    def __init__(self, world: World) -> None:
        self.world = world
        #: ``(body, [fx, fy, fz, tx, ty, tz], end time s)``, in the order applied.
        self.pushes: list[tuple[str, list[float], float]] = []
        self.period = math.inf
        self.next_time = math.inf
        world.controllers.append(self)

    def add(self, body: str, wrench: list[float], end: float) -> None:
        """Start a push now (sets ``xfrc_applied`` at once)."""
        self.pushes.append((body, wrench, end))
        self.next_time = min(self.next_time, end)
        self._write(self.world.model, self.world.data, {body})
        self.world.reschedule()

    def _write(self, model: mujoco.MjModel, data: mujoco.MjData, bodies: set[str]) -> None:
        for body in bodies:
            b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
            if b >= 0:
                total = np.zeros(6)
                for name, wrench, _ in self.pushes:
                    if name == body:
                        total += wrench
                data.xfrc_applied[b] = total

    def tick(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Clear the pushes that have ended; aim the next tick at the next end."""
        now = float(data.time) + 0.5 * float(model.opt.timestep)
        ended = {body for body, _, end in self.pushes if end <= now}
        self.pushes = [p for p in self.pushes if p[2] > now]
        self._write(model, data, ended)
        upcoming = min((end for _, _, end in self.pushes), default=math.inf)
        self.period = upcoming - self.next_time if math.isfinite(upcoming) else math.inf

    def reset(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Forget every push (``World.reset`` clears ``xfrc_applied``)."""
        self.pushes, self.period = [], math.inf

    def snapshot(self) -> dict[str, Any]:
        """The running pushes and the clock."""
        return {"pushes": [[b, list(w), e] for b, w, e in self.pushes], "next_time": self.next_time}

    def restore(self, state: dict[str, Any]) -> None:
        """Inverse of :meth:`snapshot`."""
        self.pushes = [(str(b), [float(v) for v in w], float(e)) for b, w, e in state["pushes"]]
        self.next_time = float(state["next_time"])
        self.world.reschedule()


def pushes(world: World) -> Pushes:
    """The world's :class:`Pushes` controller, created on first use."""
    found = next((c for c in world.controllers if isinstance(c, Pushes)), None)
    return found if found is not None else Pushes(world)


def apply_force(
    world: World,
    name: str,
    force: Any = (0.0, 0.0, 0.0),
    torque: Any = (0.0, 0.0, 0.0),
    duration: float = 0.1,
    body: str | None = None,
) -> dict[str, Any]:
    """Push a body with a force (N) and torque (N m), world frame, at its centre of mass, for ``duration`` s.

    The push acts on the steps from now until ``duration`` simulated seconds later (rounded to the timestep)
    and adds to any other push of the same body.

    Args:
        world: The running world.
        name: The entity.
        force: (fx, fy, fz), N.
        torque: (tx, ty, tz), N m.
        duration: Simulated seconds, in (0, :data:`MAX_PUSH_SECONDS`].
        body: The body pushed, by full name (a robot's link ``NAME/link``); ``None``: the entity's own body.

    Returns:
        ``{"name", "body", "from": s, "until": s}``.

    Raises:
        EditError: No such entity or body, a body welded to the world, a value out of range (its field).
    """
    entity = _entity(world, name)
    fail = edit_fail("", name)
    wrench = [
        *convert(force, tuple[float, float, float], fail, ("force",)),
        *convert(torque, tuple[float, float, float], fail, ("torque",)),
    ]
    if any(abs(v) > MAX_WRENCH for v in wrench):
        raise EditError(f"force and torque components must be at most {MAX_WRENCH:g}", key="force", entity=name)
    seconds = convert(duration, float, fail, ("duration",))
    if not 0 < seconds <= MAX_PUSH_SECONDS:
        raise EditError(f"must be in (0, {MAX_PUSH_SECONDS:g}] seconds, got {seconds!r}", key="duration", entity=name)
    target = name if body is None else body
    if not isinstance(target, str) or not _bound_to(target, {name}):
        raise EditError(f"body must be {name!r} or one of its bodies ({name}/...), got {target!r}", key="body")
    model = world.model
    b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, target) if entity.HAS_BODY else -1
    if b < 0:
        raise EditError(f"{target!r} is no body", key="body" if body else "name", entity=name)
    if int(model.body_weldid[b]) == 0:
        raise EditError(f"{target!r} is welded to the world; a force cannot move it", key="name", entity=name)
    start = float(world.data.time)
    pushes(world).add(target, wrench, start + seconds)
    return {"name": name, "body": target, "from": start, "until": start + seconds}
