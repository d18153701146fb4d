"""Trajectories of the :class:`~simrun.services.joint_service.JointService`: checked waypoints, looked up per tick.

A trajectory is a list of times (seconds from the call) and one row of joint positions per time (rad or m).
:func:`check_waypoints` refuses, with one line naming the index (issue 42; docs/limits.md):

* more than :data:`MAX_POINTS` points (before any is converted);
* a time that is not a positive finite number, or that is less than one model timestep after the one before
  it (the first: after the call): a span of 1e-300 s asks for a speed no actuator has and made MuJoCo
  unstable; equal or decreasing times are the same error;
* a position that is not finite, or outside what its joint and actuator allow
  (:func:`simrun.services.joint_drives.check_position`).

:class:`Trajectory` follows the points: at each tick, the segment ``k`` with ``times[k] <= s < times[k + 1]``
(``s`` the time since the call) is found from the last tick's segment (a cursor: the same or the next one,
O(1) per tick as time advances) or else by binary search (:func:`bisect.bisect_right`, O(log n): after a
restore or a jump). Before, the search ran from the first point at every tick: a 1M-point trajectory made a
2 s scene take 122 s. Either way it is the segment the linear search found, so runs replay bit for bit.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from collections.abc import Mapping
from typing import Any

import numpy as np

from simrun.errors import EntityError
from simrun.services.joint_drives import Drive, check_position, range_slack

#: Most points of one trajectory (docs/limits.md). At 500 Hz a point per tick for 200 s.
MAX_POINTS = 100_000
#: How far below one timestep a gap between two times may fall and still count as one (float rounding).
_ROUNDING = 1e-9


def check_waypoints(
    joints: list[str] | tuple[str, ...],
    drives: Mapping[str, Drive],
    times: Any,
    positions: Any,
    timestep: float,
    what: str = "trajectory",
) -> tuple[list[float], list[list[float]]]:
    """The times (s) and the ``len(times)`` x ``len(joints)`` rows of positions (rad or m), checked (see the module).

    ``positions`` is nested rows or flat (row after row). ``drives`` has every joint of ``joints``;
    ``timestep`` is the model's, s.

    Raises:
        EntityError: Too many points, a bad time or spacing, a missing, non-finite or out-of-range position.
    """
    if isinstance(times, str | bytes) or not hasattr(times, "__len__"):
        raise EntityError(f"{what}: times must be a list of positive finite seconds, got {times!r}")
    count = len(times)
    if count > MAX_POINTS:
        raise EntityError(
            f"{what}: {count} points; a trajectory has at most {MAX_POINTS} (docs/limits.md): "
            "split it into trajectories given one after another"
        )
    try:
        stamps = np.asarray(times, dtype=float)
    except (TypeError, ValueError):
        raise EntityError(f"{what}: times must be a list of positive finite seconds") from None
    if count == 0 or stamps.ndim != 1:
        raise EntityError(f"{what}: times must be positive finite seconds, at least one")
    bad = np.flatnonzero(~np.isfinite(stamps) | (stamps <= 0))
    if bad.size:
        k = int(bad[0])
        raise EntityError(f"{what}: times[{k}] = {times[k]!r}: times must be positive finite seconds")
    gaps = np.diff(stamps, prepend=0.0)
    close = np.flatnonzero(gaps < timestep * (1.0 - _ROUNDING))
    if close.size:
        k = int(close[0])
        rule = f"times must increase, each at least one timestep ({timestep:g} s) after the one before"
        if k == 0:
            raise EntityError(
                f"{what}: times[0] = {stamps[0]:g} s is less than one timestep ({timestep:g} s) from now: "
                f"times are seconds from the call; {rule}"
            )
        after = "is not after" if gaps[k] <= 0 else f"is {gaps[k]:g} s after"
        raise EntityError(f"{what}: times[{k}] = {stamps[k]:g} s {after} times[{k - 1}] = {stamps[k - 1]:g} s: {rule}")
    try:
        flat = np.asarray(positions, dtype=float).ravel()
    except (TypeError, ValueError):
        flat = np.zeros(0)
    if flat.size != count * len(joints):
        raise EntityError(f"{what}: positions needs {count} x {len(joints)} finite values, got {flat.size}")
    rows = flat.reshape(count, len(joints))
    lowest = np.array([drives[j].lowest for j in joints])
    highest = np.array([drives[j].highest for j in joints])
    slack = np.array([range_slack(drives[j]) for j in joints])
    outside = np.argwhere(~((rows >= lowest - slack) & (rows <= highest + slack)))  # NaN included
    if outside.size:
        k, j = (int(i) for i in outside[0])
        if not math.isfinite(rows[k, j]):
            raise EntityError(f"{what}: point {k}: joint {joints[j]!r} position {rows[k, j]!r} is not a finite number")
        check_position(joints[j], drives[joints[j]], float(rows[k, j]), f"{what}: point {k}")
    return stamps.tolist(), np.clip(rows, lowest, highest).tolist()  # a hair outside: the range's end


class Trajectory:
    """A trajectory being followed: from ``rows[0]`` at ``t0`` through ``rows[k]`` at ``t0 + times[k]``.

    Attributes:
        t0: Simulation time of the call, s.
        times: ``0.0`` then the waypoints' times, s from ``t0`` (increasing).
        joints: The joints it moves.
        rows: Positions per time (rad or m): the targets at the call first, then one row per waypoint.
    """

    __slots__ = ("_cursor", "joints", "rows", "t0", "times")

    def __init__(self, t0: float, times: list[float], joints: list[str], rows: list[list[float]]) -> None:
        self.t0, self.times, self.joints, self.rows = t0, times, joints, rows
        self._cursor = 0  # the segment of the last tick (not state: any start finds the same segment)

    @classmethod
    def from_state(cls, state: Mapping[str, Any]) -> Trajectory:
        """Inverse of :meth:`state`."""
        times = [float(t) for t in state["times"]]
        rows = [[float(v) for v in row] for row in state["rows"]]
        return cls(float(state["t0"]), times, [str(j) for j in state["joints"]], rows)

    def state(self) -> dict[str, Any]:
        """``t0``, ``times``, ``joints``, ``rows``: JSON-ready (the lists are shared, never changed)."""
        return {"t0": self.t0, "times": self.times, "joints": self.joints, "rows": self.rows}

    def segment(self, s: float) -> int:
        """The ``k`` with ``times[k] <= s < times[k + 1]``, for ``0 <= s < times[-1]`` (see the module)."""
        times, k = self.times, self._cursor
        if not times[k] <= s:
            k = bisect_right(times, s) - 1
        elif not s < times[k + 1]:
            k += 1
            if not s < times[k + 1]:
                k = bisect_right(times, s) - 1
        self._cursor = k
        return k

    def targets(self, now: float, profile: str) -> list[tuple[float, float]] | None:
        """(position, velocity) targets of :attr:`joints` at simulation time ``now``, or ``None``: it has ended.

        ``profile``: ``linear`` (the segment's slope as velocity) or ``cosine`` (the blend
        ``(1 - cos(pi u)) / 2``, its slope as velocity). A ``now`` before ``t0`` (the world was rebuilt: time 0
        again) starts the trajectory over on the new clock.
        """
        if now < self.t0:
            self.t0 = now
        s = now - self.t0
        times, rows = self.times, self.rows
        if s >= times[-1]:
            return None
        k = self.segment(s)
        span = times[k + 1] - times[k]
        u = (s - times[k]) / span
        here, there = rows[k], rows[k + 1]
        if profile == "cosine":
            blend, slope = 0.5 - 0.5 * math.cos(math.pi * u), 0.5 * math.pi * math.sin(math.pi * u) / span
            return [(a + (b - a) * blend, (b - a) * slope) for a, b in zip(here, there, strict=True)]
        return [(a + (b - a) * u, (b - a) / span) for a, b in zip(here, there, strict=True)]
