"""How a run is judged against its expectations (:mod:`simrun.scenetest.expect` reads the ``[[expect]]`` tables).

:func:`check_against` refuses expectations that name what the world lacks or times after the run's end;
:class:`Observer` takes the observations (at the start, every :data:`simrun.run.play.DISTANCE_PERIOD` seconds of
simulated time, at every command time, and at the end) and turns them into one :class:`~simrun.scenetest.expect.Outcome`
per expectation. Every failure says what was measured, when, and by how much it missed (units: metres, degrees,
seconds).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import mujoco
import numpy as np

from simrun.errors import EntityError, SceneError
from simrun.scenetest.expect import Expectation, Outcome, _fmt_vec
from simrun.world.world import World


def check_against(expectations: list[Expectation], world: World, duration: float) -> None:
    """Refuse expectations that name what ``world`` lacks, or times after ``duration`` seconds.

    Raises:
        SceneError: With the expectation's file and line.
    """
    ids: dict[str, Expectation] = {}
    for e in expectations:
        if e.id in ids:
            other = ids[e.id]
            raise SceneError(f"duplicate id (also {other.file}:{other.line})", e.file, "expect", e.line, e.id)
        ids[e.id] = e
        _Probe(e, world)  # resolves names
        if e.start > duration + 1e-9 or (e.stop is not None and e.stop > duration + 1e-9):
            late = e.stop if e.stop is not None and e.stop > duration else e.start
            raise SceneError(
                f"time {late:g} s is after the end of the run ({duration:g} s); lower it or raise [test] duration",
                e.file,
                "expect",
                e.line,
                e.id,
            )


class _Probe:
    """Measures one expectation on a world: ``measure() -> (ok, measured text, miss)``."""

    def __init__(self, e: Expectation, world: World) -> None:
        self.e, self.world = e, world
        p = e.params
        try:
            if "body" in p:
                self.body = world.body(p["body"])
                self.body_id = int(self.body.id)
                self._xpos = world.data.xpos  # the MjData self.body views (measure reads it too)
            self.point = np.array(self.body.xpos) if p.get("point") == "start" else np.array(p.get("point", ()))
            if e.kind == "joint":
                self.joint = world.joint(p["joint"])
                if int(world.model.jnt_type[self.joint.id]) not in (2, 3):  # slide, hinge
                    raise EntityError(f"joint {p['joint']!r} is not a hinge or slide joint")
            if e.kind == "sensor" and p["sensor"] not in world.sensors:
                known = ", ".join(world.sensors) or "none"
                raise EntityError(f"no sensor named {p['sensor']!r} (known: {known})")
            if e.kind == "no_contact":
                model = world.model
                self.groups = []
                for name in p["between"]:
                    world.entity(name)
                    bodies = {b for b in range(model.nbody) if _owned(model.body(b).name, name)}
                    self.groups.append(np.array([model.geom_bodyid[g] in bodies for g in range(model.ngeom)]))
        except (EntityError, KeyError) as exc:
            reason = exc.args[0] if isinstance(exc, KeyError) and exc.args else exc
            raise SceneError(str(reason), e.file, "expect", e.line, e.id) from None
        if e.kind == "no_contact":
            a, b = self.groups
            #: pair[g1, g2]: a contact of geoms g1 and g2 is one between the two entities (either order).
            self.pair = np.outer(a, b) | np.outer(b, a) if a.size <= _PAIR_MATRIX_GEOMS else None
        if e.kind == "region":
            self.low, self.high = np.array(p["min"]), np.array(p["max"])
        self._data: mujoco.MjData | None = None
        checks: dict[str, Callable[[mujoco.MjData], tuple[bool, float]]] = {
            "position": self._check_position,
            "region": self._check_region,
            "no_contact": self._check_no_contact,
            "finite": self._check_finite,
            "no_warnings": self._check_no_warnings,
        }
        #: ``check(data) -> (ok, miss)``: what :meth:`measure` gives, without its text, read from MuJoCo's arrays.
        self.check = checks.get(e.kind, self._check_measured)

    def _check_measured(self, data: mujoco.MjData) -> tuple[bool, float]:
        ok, _, miss = self.measure()
        return ok, miss

    def _bind(self, data: mujoco.MjData) -> None:
        """Views of ``data``'s fixed-size arrays, taken once per ``MjData`` (they follow its values)."""
        self._data = data
        self._warnings = data.warning.number
        self._no_warnings = bytes(self._warnings.nbytes)
        self._state = (data.qpos, data.qvel, data.qacc)

    def _check_position(self, data: mujoco.MjData) -> tuple[bool, float]:
        """The distance as :meth:`measure` computes it (``numpy.linalg.norm`` of a vector is ``sqrt(x . x)``)."""
        offset = self._xpos[self.body_id, : len(self.point)] - self.point
        distance = math.sqrt(float(offset.dot(offset)))
        within: float = self.e.params["within"]
        return distance <= within, distance - within

    def _check_region(self, data: mujoco.MjData) -> tuple[bool, float]:
        """The distance outside the box as :meth:`measure` computes it."""
        here = self._xpos[self.body_id, : len(self.low)]
        outside = np.maximum(self.low - here, 0) + np.maximum(here - self.high, 0)
        miss = math.sqrt(float(outside.dot(outside)))
        return miss == 0, miss

    def _check_no_contact(self, data: mujoco.MjData) -> tuple[bool, float]:
        """No contact of the pair: geom-pair masks over the contact arrays (a contact found: :meth:`measure`)."""
        if data.ncon:
            contacts = data.contact
            g1, g2 = contacts.geom1, contacts.geom2
            if self.pair is not None:
                found = np.count_nonzero(self.pair[g1, g2]) > 0
            else:
                a, b = self.groups
                found = ((a[g1] & b[g2]) | (a[g2] & b[g1])).any()
            if found:
                return self._check_measured(data)
        return True, 0.0

    def _check_finite(self, data: mujoco.MjData) -> tuple[bool, float]:
        """Finite: a sum of squares is finite when every term is (not finite, even by overflow: :meth:`measure`).

        Squares overflow only beyond 1e154 (MuJoCo resets a state past 1e10 with a warning); numpy then warns.
        """
        if data is not self._data:
            self._bind(data)
        qpos, qvel, qacc = self._state
        if math.isfinite(float(qpos.dot(qpos)) + float(qvel.dot(qvel)) + float(qacc.dot(qacc))):
            return True, 0.0
        return self._check_measured(data)

    def _check_no_warnings(self, data: mujoco.MjData) -> tuple[bool, float]:
        """No warning: MuJoCo's counters (``data.warning.number``) are all zero (else :meth:`measure`)."""
        if data is not self._data:
            self._bind(data)
        if self._warnings.tobytes() != self._no_warnings:  # a counter is not zero
            return self._check_measured(data)
        return True, 0.0

    def measure(self) -> tuple[bool, str, float]:
        e, p, data = self.e, self.e.params, self.world.data
        kind = e.kind
        if kind == "position":
            here = np.array(self.body.xpos)[: len(self.point)]
            distance = float(np.linalg.norm(here - self.point))
            return distance <= p["within"], self.position_text(here), distance - p["within"]
        if kind == "region":
            here = np.array(self.body.xpos)[: len(p["min"])]
            outside = np.maximum(np.array(p["min"]) - here, 0) + np.maximum(here - np.array(p["max"]), 0)
            miss = float(np.linalg.norm(outside))
            return miss == 0, f"{p['body']} at {_fmt_vec(here)}", miss
        if kind == "heading":
            xmat = np.array(self.body.xmat).reshape(3, 3)
            yaw = math.degrees(math.atan2(xmat[1, 0], xmat[0, 0]))
            error = abs((yaw - p["yaw"] + 180.0) % 360.0 - 180.0)
            return error <= p["within"], f"{p['body']} heading {yaw:.2f} degrees, {error:.2f} off", error - p["within"]
        if kind in ("sensor", "joint"):
            if kind == "joint":
                values = [float(self.joint.qpos[0])]
                what = f"joint {p['joint']} at"
            else:
                values, what = self._reading()
            if not values:
                return False, f"{what} no reading yet", math.inf
            miss = max(max(p["min"] - v, v - p["max"], 0.0) if math.isfinite(v) else math.inf for v in values)
            shown = _fmt_vec(values) if len(values) > 1 else f"{values[0]:.6g}"
            return miss == 0, f"{what} {shown}", miss
        if kind == "no_contact":
            first, depth = None, 0.0
            for c in data.contact[: data.ncon]:
                g1, g2 = int(c.geom1), int(c.geom2)
                a, b = self.groups
                if (a[g1] and b[g2]) or (a[g2] and b[g1]):
                    depth = max(depth, -float(c.dist))
                    first = first or (_geom(self.world, g1), _geom(self.world, g2))
            if first is None:
                return True, "no contact", 0.0
            return False, f"contact {first[0]} - {first[1]}, {depth * 1000:.2f} mm deep", depth
        if kind == "finite":
            for name in ("qpos", "qvel", "qacc"):
                values = getattr(data, name)
                bad = np.flatnonzero(~np.isfinite(values))
                if bad.size:
                    return False, f"{name}[{int(bad[0])}] = {values[bad[0]]!r}", math.inf
            return True, "finite", 0.0
        if kind == "no_warnings":
            raised = self.world.warnings()
            if raised:
                text = ", ".join(f"{k} x{n}" for k, n in sorted(raised.items()))
                return False, f"MuJoCo warning(s) {text}", float(sum(raised.values()))
            return True, "no warnings", 0.0
        raise AssertionError(kind)  # realtime is judged from the run's summary

    def position_text(self, here: np.ndarray) -> str:
        """What a ``position`` expectation measured with the body at ``here`` (its first 2 or 3 coordinates)."""
        distance = float(np.linalg.norm(here - self.point))
        return f"{self.e.params['body']} at {_fmt_vec(here)}, {distance:.4f} m from {_fmt_vec(self.point)}"

    def position_now(self) -> np.ndarray:
        """A copy of the body's position now, as :meth:`measure` reads it (the first 2 or 3 coordinates)."""
        return np.array(self._xpos[self.body_id, : len(self.point)])

    def _reading(self) -> tuple[list[float], str]:
        p = self.e.params
        value = self.world.sensors[p["sensor"]].reading
        what = (
            f"sensor {p['sensor']}"
            + (f".{p['field']}" if p["field"] else "")
            + (f"[{p['index']}]" if p["index"] is not None else "")
        )
        if value is None:
            return [], what
        if p["field"] is not None:
            if not hasattr(value, p["field"]):
                fields = ", ".join(getattr(value, "__dataclass_fields__", {})) or "none"
                raise SceneError(
                    f"the reading has no field {p['field']!r} (fields: {fields})",
                    self.e.file,
                    "expect",
                    self.e.line,
                    self.e.id,
                )
            value = getattr(value, p["field"])
        try:
            flat = np.asarray(value, dtype=float).ravel()
        except (TypeError, ValueError):
            shown = f"field {p['field']!r}" if p["field"] else "reading"
            raise SceneError(
                f"the sensor's {shown} is not numbers ({value!r:.60}); name a numeric field",
                self.e.file,
                "expect",
                self.e.line,
                self.e.id,
            ) from None
        if p["index"] is not None:
            if p["index"] >= flat.size:
                raise SceneError(
                    f"index {p['index']} is past the reading's {flat.size} value(s)",
                    self.e.file,
                    "expect",
                    self.e.line,
                    self.e.id,
                )
            flat = flat[p["index"] : p["index"] + 1]
        return [float(v) for v in flat], f"{what} ="


#: Most geoms for which ``no_contact`` keeps a geom x geom pair matrix (1 MiB); above, two geom masks.
_PAIR_MATRIX_GEOMS = 1024


def _owned(body: str, entity: str) -> bool:
    return body == entity or body.startswith(entity + "/")


def _geom(world: World, g: int) -> str:
    name = mujoco.mj_id2name(world.model, mujoco.mjtObj.mjOBJ_GEOM, g)
    return name or f"geom {g}"


@dataclass
class _State:
    """What one expectation has seen so far."""

    decided: bool = False
    passed: bool = True
    text: str = ""
    time: float | None = None
    miss: float = -math.inf  # the kept observation's miss (positive: beyond the tolerance)
    count: int = 0
    first: float | None = None
    last: float | None = None
    here: np.ndarray | None = None  # a kept position whose text is written when the run ends

    def keep(self, passed: bool, text: str, time: float | None, miss: float) -> None:
        self.passed, self.text, self.time, self.miss, self.here = passed, text, time, miss, None


#: Kinds whose closest call is worth reporting when they hold (the others hold with nothing to measure).
_MEASURED = ("position", "region", "heading", "sensor", "joint")


class Observer:
    """Evaluates expectations on a running world: :meth:`observe` at each observation, :meth:`finish` at the end.

    Args:
        expectations: Checked with :func:`check_against` beforehand.
        world: The world being run.
    """

    def __init__(self, expectations: list[Expectation], world: World) -> None:
        self.world = world
        self.probes = [_Probe(e, world) for e in expectations if e.kind != "realtime"]
        self.realtime = [e for e in expectations if e.kind == "realtime"]
        self.dt = float(world.model.opt.timestep)
        self.state = [_State() for _ in self.probes]
        self._live: list[int] = []
        self._wake = -math.inf
        self._schedule()

    def observe(self) -> None:
        """Look at the world now (simulated time ``world.time``).

        Each live expectation is checked from MuJoCo's arrays (:attr:`_Probe.check`); its text is made only when
        the observation is the one it keeps (the first failure, the closest call, the best attempt).
        """
        now, half = self.world.time, 0.5 * self.dt
        if now < self._wake:
            return
        data = self.world.data
        closed = False
        for k in self._live:
            probe, state = self.probes[k], self.state[k]
            e = probe.e
            if now < e.start - half:
                continue
            if e.stop is not None and now > e.stop + half:
                self._close(probe, state)
                closed = True
                continue
            ok, miss = probe.check(data)
            state.count += 1
            if state.first is None:
                state.first = now
            state.last = now
            if e.mode == "at":
                self._keep(probe, state, now)
                state.decided = closed = True
            elif e.mode == "always":
                if not ok:
                    self._keep(probe, state, now)
                    state.decided = closed = True
                elif state.time is None or miss > state.miss:  # keep the closest call
                    if e.kind == "position":  # the position now; its words when the run ends
                        state.keep(True, "", now, miss)
                        state.here = probe.position_now()
                    else:
                        self._keep(probe, state, now)
            elif ok:  # sometime
                self._keep(probe, state, now)
                state.decided = closed = True
            elif state.time is None or miss < state.miss:  # keep the best attempt
                self._keep(probe, state, now)
        if closed:
            self._schedule()

    def _schedule(self) -> None:
        """The expectations still observed (not decided, not due only at the end) and when the first one opens."""
        self._live = [k for k, (p, s) in enumerate(zip(self.probes, self.state, strict=True)) if not s.decided]
        self._live = [k for k in self._live if self.probes[k].e.mode != "end"]
        starts = [self.probes[k].e.start for k in self._live]
        self._wake = min(starts) - 0.5 * self.dt if starts else math.inf

    @staticmethod
    def _keep(probe: _Probe, state: _State, now: float) -> None:
        ok, text, miss = probe.measure()
        state.keep(ok, text, now, miss)

    def _close(self, probe: _Probe, state: _State) -> None:
        state.decided = True
        if state.count == 0:  # no observation fell in the window
            state.keep(False, "no observation in the window (they come every 20 ms)", None, math.inf)
        elif probe.e.mode == "sometime":
            state.passed = False

    def finish(self, simulated_s: float, wall_s: float) -> list[Outcome]:
        """Close every window at the end of the run and give the outcomes, in the expectations' order.

        Args:
            simulated_s: Simulated seconds of the run (for ``realtime``).
            wall_s: Wall-clock seconds the run took.
        """
        now = self.world.time
        outcomes: dict[str, Outcome] = {}
        for probe, state in zip(self.probes, self.state, strict=True):
            e = probe.e
            if e.mode == "end" or (e.mode == "at" and not state.decided):  # "at": due at the very end
                ok, text, miss = probe.measure()
                state.keep(ok, text, now, miss)
                state.count, state.decided = 1, True
            elif not state.decided:
                self._close(probe, state)
            if state.here is not None:
                state.text = probe.position_text(state.here)
            outcomes[e.id] = _outcome(e, state)
        for e in self.realtime:
            factor = simulated_s / wall_s if wall_s > 0 else math.inf
            ok = factor >= e.params["min"]
            # the measured factor varies from run to run: it is shown only when it fails (reports stay identical)
            text = (
                f"real-time factor at least {e.params['min']:g}"
                if ok
                else f"real-time factor {factor:.2f} ({simulated_s:g} s simulated in {wall_s:.3f} s wall-clock)"
            )
            outcomes[e.id] = _outcome(e, _State(True, ok, text, None, e.params["min"] - factor))
        order = [e.id for e in (*(p.e for p in self.probes), *self.realtime)]
        return [outcomes[i] for i in order]


def _outcome(e: Expectation, state: _State) -> Outcome:
    at = f" at t = {state.time:.3f} s" if state.time is not None else ""
    if state.passed:
        if e.mode == "always" and e.kind != "realtime":
            held = f"held at all {state.count} observations, t = {state.first:.3f}-{state.last:.3f} s"
            detail = f"{held}; closest: {state.text}{at}" if e.kind in _MEASURED else held
        else:
            detail = f"{state.text}{at}"
        return Outcome(e.id, e.kind, e.message, e.file, e.line, True, detail, state.time, None)
    miss = state.miss
    by = f"; missed by {miss:.4g}{_UNITS[e.kind]}" if math.isfinite(miss) else ""
    return Outcome(e.id, e.kind, e.message, e.file, e.line, False, f"{state.text}{at}{by}", state.time, miss)


_UNITS = {
    "position": " m",
    "region": " m",
    "heading": " degrees",
    "sensor": "",
    "joint": "",
    "no_contact": " m (penetration)",
    "finite": "",
    "no_warnings": " warning(s)",
    "realtime": "",
}
