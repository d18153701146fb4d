"""simrun.world.edit_apply: a session of five edits, replayed from its JSON records, is bit-identical.

Ground truth: MuJoCo's whole physics state (mj_getState) of the edited session and of a fresh world of the
same scene that applies the records at the same steps.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from simrun.run.session import prepare
from simrun.scene.scene_file import load_scene
from simrun.world.edit import EditError, state_bytes
from simrun.world.edit_apply import EditRecord, apply_edit

SCENE = Path(__file__).resolve().parent.parent / "fixtures" / "scenes" / "boebot.toml"
CRATE = {
    "type": "Box",
    "name": "crate",
    "dimensions": [0.2, 0.6, 0.2],
    "mass": 20.0,
    "free": True,
    "pose": {"position": [1.35, 1.0, 0.1]},
}
EDITS = [
    (0.2, "insert", {"tables": CRATE}),
    (0.4, "change", {"name": "ground", "changes": {"material": {"dynamic_friction": 0.4}}}),
    (0.6, "apply_force", {"name": "box", "force": [80.0, 0.0, 0.0], "duration": 0.3}),
    (0.9, "teleport", {"name": "crate", "position": [1.35, 2.5, 0.1]}),
    (1.1, "change_service", {"kind": "DriveService", "entity": "boebot", "settings": {"rate": 25.0}}),
]


def _session(records: list[EditRecord] | None) -> tuple[bytes, list[EditRecord], list[bytes]]:
    world = load_scene(SCENE)
    prepare(world)
    world.service("DriveService", "boebot").drive_distance(0.6)
    applied, states = [], []
    todo = list(records) if records is not None else [EditRecord(t, k, a) for t, k, a in EDITS]
    dt = world.model.opt.timestep
    while world.time < 2.0 - dt / 2:
        while todo and todo[0].t <= world.time + dt / 2:
            record = todo.pop(0)
            record.apply(world)
            applied.append(EditRecord(world.time, record.kind, record.args))
            states.append(state_bytes(world))
        world.step(1)
    return state_bytes(world), applied, states


def test_a_session_of_five_edits_replays_bit_identically_from_its_records():
    final, applied, states = _session(None)
    assert len(applied) == 5
    records = [EditRecord.from_json(r.to_json()) for r in applied]  # as a recording would hold them
    assert records == applied
    again, _, again_states = _session(records)
    assert again_states == states and again == final
    unedited, _, _ = _session([])
    assert unedited != final
    unedited, _, _ = _session([])
    assert unedited != final


def test_refused_records_name_the_field():
    world = load_scene(SCENE)
    with pytest.raises(EditError) as refused:
        apply_edit(world, "explode", {})
    assert refused.value.key == "kind"
    with pytest.raises(EditError) as refused:
        apply_edit(world, "teleport", {"name": "box", "position": [0, 0, 0.1], "speed": 3})
    assert refused.value.key == "speed"
    with pytest.raises(EditError) as refused:
        apply_edit(world, "teleport", {"name": "box"})
    assert refused.value.key == "position"
    for text, key in (("[1, 2]", "edit"), ('[-1, "insert", {}]', "t"), ('[0, "x", {}]', "kind"), ("nope", "edit")):
        with pytest.raises(EditError) as refused:
            EditRecord.from_json(text)
        assert refused.value.key == key
