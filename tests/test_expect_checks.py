"""The bulk checks of expectations (``_Probe.check``) agree with the full measurement at every state.

``check(data)`` reads MuJoCo's arrays (body rows of ``xpos``, the contact arrays against geom masks, the
warning counters, sums of squares of the state); ``measure()`` is the reference that also writes the
report's words. Ground truth for the states: a ball dropped onto a crate (MuJoCo's own contacts as it
lands), a state made non-finite, MuJoCo's warning counter set, and a world with more geoms than the pair
matrix holds (the two-mask path).
"""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from simrun.scene.scene_file import load_scene
from simrun.scene.tomlpos import key_lines
from simrun.scenetest import observer as observer_module
from simrun.scenetest.expect import parse_expectations
from simrun.scenetest.observer import Observer

SCENE = """
[world]
timestep = 0.002

[[entities]]
type = "Ground"
name = "ground"

[[entities]]
type = "Sphere"
name = "ball"
free = true
mass = 1.0
radius = 0.1
pose = { position = [0.0, 0.0, 0.6] }

[[entities]]
type = "Box"
name = "crate"
free = true
dimensions = [0.2, 0.2, 0.2]
pose = { position = [0.0, 0.0, 0.1] }

[[expect]]
id = "apart"
kind = "no_contact"
between = ["ball", "crate"]

[[expect]]
id = "crate-ground"
kind = "no_contact"
between = ["ground", "crate"]

[[expect]]
id = "near"
kind = "position"
body = "ball"
point = [0.0, 0.0, 0.5]
within = 0.2
always = [0.0, "end"]

[[expect]]
id = "flat"
kind = "position"
body = "ball"
point = [0.0, 0.0]
within = 0.001
always = [0.0, "end"]

[[expect]]
id = "box"
kind = "region"
body = "ball"
min = [-0.1, -0.1, 0.25]
max = [0.1, 0.1, 0.45]
sometime = [0.0, "end"]

[[expect]]
id = "stable"
kind = "finite"

[[expect]]
id = "clean"
kind = "no_warnings"
"""


def _observer(tmp_path: Path, text: str = SCENE) -> Observer:
    import tomllib

    path = tmp_path / "scene.toml"
    path.write_text(text, encoding="utf-8")
    world = load_scene(path)
    found = parse_expectations(tomllib.loads(text), key_lines(text), str(path))
    return Observer(found, world)


def _agree(observer: Observer) -> set[tuple[str, bool]]:
    """Every probe's check equals its measurement now; the (id, ok) pairs seen."""
    data = observer.world.data
    seen = set()
    for probe in observer.probes:
        ok, _, miss = probe.measure()
        fast = probe.check(data)
        assert fast == (ok, miss), (probe.e.id, fast, (ok, miss))
        seen.add((probe.e.id, ok))
    return seen


def test_checks_agree_with_measurement_through_a_landing(tmp_path: Path) -> None:
    observer = _observer(tmp_path)
    seen: set[tuple[str, bool]] = set()
    for _ in range(60):  # 0.6 s: the ball falls 0.3 m onto the crate and rests there
        seen |= _agree(observer)
        observer.world.step(5)
    # both outcomes of the contact and distance checks were met, by MuJoCo's own contacts
    assert {("apart", True), ("apart", False), ("crate-ground", False)} <= seen
    assert {("near", True), ("box", True), ("box", False), ("flat", True)} <= seen


def test_non_finite_state_and_warnings_fall_back_to_the_measurement(tmp_path: Path) -> None:
    observer = _observer(tmp_path)
    data = observer.world.data
    assert ("stable", True) in _agree(observer) and ("clean", True) in _agree(observer)
    data.qvel[2] = math.nan
    assert ("stable", False) in _agree(observer)
    data.qvel[2] = 0.0
    data.qacc[0] = math.inf
    assert ("stable", False) in _agree(observer)
    data.qacc[0] = 0.0
    data.qpos[0] = 1e200  # finite, but its square overflows (numpy says so): the measurement decides (finite)
    with np.errstate(over="ignore"):
        assert ("stable", True) in _agree(observer)
    data.warning[int(mujoco.mjtWarning.mjWARN_BADQACC)].number = 2
    assert ("clean", False) in _agree(observer)
    assert observer.world.warnings() == {"mjWARN_BADQACC": 2}


def test_the_two_mask_path_agrees_above_the_pair_matrix(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(observer_module, "_PAIR_MATRIX_GEOMS", 0)
    observer = _observer(tmp_path)
    probe = next(p for p in observer.probes if p.e.id == "apart")
    assert probe.pair is None
    seen: set[tuple[str, bool]] = set()
    for _ in range(60):
        seen |= _agree(observer)
        observer.world.step(5)
    assert {("apart", True), ("apart", False)} <= seen


def test_checks_follow_a_new_mjdata(tmp_path: Path) -> None:
    observer = _observer(tmp_path)
    world = observer.world
    _agree(observer)
    world.step(100)
    before = world.data
    world.compile()  # a fresh MjData: the probes' views of the state and counters follow it
    assert world.data is not before
    world.data.qvel[0] = math.nan  # only the new MjData is not finite
    assert ("stable", False) in _agree(observer)
    assert np.isfinite(before.qvel).all()


class _Reference(Observer):
    """The observer as it was before the bulk checks: every live expectation measured, words and all."""

    def observe(self) -> None:
        now, half = self.world.time, 0.5 * self.dt
        for probe, state in zip(self.probes, self.state, strict=True):
            e = probe.e
            if state.decided or e.mode == "end" or now < e.start - half:
                continue
            if e.stop is not None and now > e.stop + half:
                self._close(probe, state)
                continue
            ok, text, miss = probe.measure()
            state.count += 1
            state.first = now if state.first is None else state.first
            state.last = now
            if e.mode == "at":
                state.keep(ok, text, now, miss)
                state.decided = True
            elif e.mode == "always":
                if not ok:
                    state.keep(False, text, now, miss)
                    state.decided = True
                elif state.time is None or miss > state.miss:
                    state.keep(True, text, now, miss)
            elif ok:
                state.keep(True, text, now, miss)
                state.decided = True
            elif state.time is None or miss < state.miss:
                state.keep(False, text, now, miss)


WINDOWS = """
[[expect]]
id = "settles"
kind = "position"
body = "crate"
point = "start"
within = 0.01
always = [0.0, 0.4]

[[expect]]
id = "early"
kind = "position"
body = "ball"
point = [0.0, 0.0, 0.6]
within = 0.05
always = [0.0, 0.1]

[[expect]]
id = "lands"
kind = "position"
body = "ball"
point = [0.0, 0.0, 0.3]
within = 0.002
sometime = [0.0, "end"]

[[expect]]
id = "at"
kind = "heading"
body = "crate"
yaw = 0.0
within = 1.0
at = 0.25
"""


def test_outcomes_equal_the_reference_observer(tmp_path: Path) -> None:
    """Same outcomes, words included, as measuring everything at every observation (a landing, 0.6 s)."""
    results = []
    for cls in (Observer, _Reference):
        observer = _observer(tmp_path, SCENE + WINDOWS)
        found = [p.e for p in observer.probes]
        observer = cls(found, observer.world)
        observer.observe()
        for _ in range(60):
            observer.world.step(5)
            observer.observe()
        results.append(observer.finish(0.6, 1.0))
    assert results[0] == results[1]
    assert {o.id for o in results[0] if not o.passed} >= {"apart", "near"}
    assert any("closest" in o.detail for o in results[0])
