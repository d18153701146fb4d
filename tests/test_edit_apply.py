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


UNDOABLE = [
    ("insert", {"tables": CRATE}),
    (
        "change",
        {"name": "box", "changes": {"mass": 2.0, "color": [1.0, 0.0, 0.0, 1.0], "pose": {"position": [2, 2, 1]}}},
    ),
    ("change", {"name": "ground", "changes": {"material": {"dynamic_friction": 0.3}}}),
    ("remove", {"name": "boebot"}),
    ("teleport", {"name": "box", "position": [0.0, 2.0, 0.5]}),
    ("set_gravity", {"gravity": [0.0, 0.0, -1.6]}),
    ("change_service", {"kind": "DriveService", "entity": "boebot", "settings": {"rate": 25.0}}),
    ("remove_service", {"kind": "DriveService", "entity": "boebot"}),
    ("add_sensor", {"table": {"type": "Bumper", "name": "bump", "entity": "boebot"}}),
]


@pytest.mark.parametrize(("kind", "args"), UNDOABLE, ids=[f"{k}-{i}" for i, (k, _) in enumerate(UNDOABLE)])
def test_every_undo_brings_the_world_back(kind, args):
    from simrun.world import edit
    from simrun.world.edit_apply import inverse, undo_of

    world = load_scene(SCENE)
    prepare(world)
    world.run(0.3)
    model = world.model
    tables = edit.entity_tables(world)
    services, sensors = [dict(s) for s in world.services], [dict(s) for s in world.sensor_specs]
    before = inverse(world, kind, args)
    result = apply_edit(world, kind, args)
    undo = undo_of(world.time, kind, args, result, before)
    assert undo, kind
    for record in undo:
        record.apply(world)
    now = edit.entity_tables(world)
    if kind == "remove":  # loaded back where it was when removed (its pose now), at rest
        assert now["boebot"].pop("pose") != tables["boebot"].pop("pose")
    assert now == tables
    if kind == "change_service":  # the old value again, written out: the binding's default
        assert world.services == [{**services[0], "rate": 50.0}]
        assert world.service("DriveService", "boebot").period == pytest.approx(0.02)
    else:
        assert world.services == services
    assert world.sensor_specs == sensors
    again = world.model
    for field in ("body_mass", "geom_size", "geom_rgba", "geom_friction", "body_pos", "opt.gravity"):
        if kind == "remove":  # the robot came back where it was when removed, last in the entity order
            break
        a = model.opt.gravity if field == "opt.gravity" else getattr(model, field)
        b = again.opt.gravity if field == "opt.gravity" else getattr(again, field)
        assert a.tobytes() == b.tobytes(), field
    if kind == "remove":
        masses = {model.body(b).name: model.body_mass[b] for b in range(model.nbody)}
        assert masses == {again.body(b).name: again.body_mass[b] for b in range(again.nbody)}
    world.run(0.1)


def test_a_push_has_no_undo():
    from simrun.world.edit_apply import inverse

    world = load_scene(SCENE)
    assert inverse(world, "apply_force", {"name": "box", "force": [1.0, 0.0, 0.0]}) is None


SENSORS = SCENE.with_name("boebot_sensors.toml")
#: Edits of a world with two Boe-Bots, each with a DriveService (``bot2``'s added by an edit), and two sensors.
SECOND = [
    ("change_sensor", {"name": "laser", "settings": {"rate": 5.0, "max_range": 2.0}}),
    ("remove_sensor", {"name": "laser"}),
    ("change_service", {"kind": "DriveService", "entity": "bot2", "settings": {"rate": 25.0}}),
    ("remove_service", {"kind": "DriveService", "entity": "bot2"}),
    ("add_service", {"table": {"type": "DriveService", "entity": "bot3"}}),
    ("change", {"name": "bot2", "changes": {"pose": {"position": [1.0, -1.0, 0.001]}}}),
]


def _two_robots():  # type: ignore[no-untyped-def]
    world = load_scene(SENSORS)
    prepare(world)
    for name, y in (("bot2", 1.0), ("bot3", -1.5)):
        apply_edit(world, "insert", {"tables": {"type": "BoeBot", "name": name, "pose": {"position": [1.0, y, 0.001]}}})
    apply_edit(world, "add_service", {"table": {"type": "DriveService", "entity": "bot2"}})
    world.run(0.2)
    return world


@pytest.mark.parametrize(("kind", "args"), SECOND, ids=[k for k, _ in SECOND])
def test_undo_of_a_sensor_or_a_second_robots_edit_is_at_its_time_and_touches_nothing_else(kind, args):
    from simrun.world import edit
    from simrun.world.edit_apply import inverse, undo_of

    world = _two_robots()
    tables = edit.entity_tables(world)
    services, sensors = [dict(s) for s in world.services], [dict(s) for s in world.sensor_specs]
    periods = {name: sensor.period for name, sensor in world.sensors.items()}
    t = float(world.data.time)
    before = inverse(world, kind, args)
    result = apply_edit(world, kind, args)
    assert edit.entity_tables(world) != tables or world.services != services or world.sensor_specs != sensors
    undo = undo_of(t, kind, args, result, before)
    assert undo and all(record.t == t for record in undo), undo  # at the instant of the edit
    for record in undo:
        record.apply(world)
    assert edit.entity_tables(world) == tables
    assert {name: sensor.period for name, sensor in world.sensors.items()} == pytest.approx(periods)
    if kind == "change_service":  # the old value written out: the binding's default rate
        assert world.services == [services[0], {**services[1], "rate": 50.0}]
    else:
        assert world.services == services
    if kind == "change_sensor":  # every value the change named comes back as it was
        assert [s["name"] for s in world.sensor_specs] == [s["name"] for s in sensors]
        laser = next(s for s in world.sensor_specs if s["name"] == "laser")
        assert (laser["rate"], laser["max_range"]) == (10.0, 4.0) and laser == {**sensors[0], **laser}
    elif kind == "remove_sensor":  # back, last in the order
        assert sorted(world.sensor_specs, key=str) == sorted(sensors, key=str)
    else:
        assert world.sensor_specs == sensors
    world.run(0.05)


@pytest.mark.parametrize(
    ("kind", "args"),
    [
        ("change", {"name": "nobody", "changes": {"mass": 1.0}}),
        ("change", {"name": "box", "changes": [1.0]}),
        ("remove", {"name": "nobody"}),
        ("teleport", {"name": "nobody", "position": [0.0, 0.0, 1.0]}),
        ("change_service", {"kind": "DriveService", "entity": "bot3", "settings": {"rate": 5.0}}),
        ("remove_service", {"kind": "JointService", "entity": "bot2"}),
        ("change_sensor", {"name": "nothing", "settings": {"rate": 5.0}}),
        ("remove_sensor", {"name": "nothing"}),
        ("explode", {}),
    ],
)
def test_an_edit_that_cannot_apply_has_no_undo(kind, args):
    from simrun.world.edit_apply import inverse

    assert inverse(_two_robots(), kind, args) is None


def test_records_are_canonical_json_and_every_refusal_is_one_line_naming_its_field():
    record = EditRecord(0.5, "teleport", {"position": [0.0, 1.0, 0.1], "name": "box"})
    assert record.to_json() == '[0.5,"teleport",{"name":"box","position":[0.0,1.0,0.1]}]'  # keys sorted, no spaces
    with pytest.raises(ValueError):
        EditRecord(0.5, "teleport", {"name": "box", "position": [float("nan"), 0.0, 0.0]}).to_json()
    world = load_scene(SCENE)
    refusals = [
        (lambda: apply_edit(world, "explode", {}), "kind", "unknown edit 'explode' (known: insert, change, remove,"),
        (lambda: apply_edit(world, "remove", ["box"]), "args", "expected an object of the edit's arguments"),
        (lambda: apply_edit(world, "remove", {"nam": "x"}), "nam", "remove takes no argument 'nam' (arguments: name)"),
        (lambda: apply_edit(world, "remove", {}), "name", "remove needs 'name'"),
        (lambda: EditRecord.from_json("[0, "), "edit", "not JSON ("),
        (lambda: EditRecord.from_json("[0, 1]"), "edit", "expected [t, kind, args]"),
        (lambda: EditRecord.from_json('[true, "remove", {}]'), "t", "expected a time >= 0, got True"),
        (lambda: EditRecord.from_json('[NaN, "remove", {}]'), "t", "expected a time >= 0, got nan"),
        (lambda: EditRecord.from_json('["1", "remove", {}]'), "t", "expected a time >= 0, got '1'"),
        (lambda: EditRecord.from_json('[1, "explode", {}]'), "kind", "unknown edit 'explode'"),
        (lambda: EditRecord.from_json('[1, "remove", []]'), "args", "expected an object of arguments"),
    ]
    for call, key, message in refusals:
        with pytest.raises(EditError) as refused:
            call()
        assert refused.value.key == key and str(refused.value).startswith(f"{key}: {message}"), str(refused.value)
        assert "\n" not in str(refused.value)
    assert EditRecord.from_json('[2, "remove", {"name": "box"}]') == EditRecord(2.0, "remove", {"name": "box"})


def test_the_undo_of_a_first_pose_is_the_origin_at_rest():
    """An entity whose table gives no pose (the ground) is at the origin: its undo names that pose."""
    from simrun.world.edit_apply import inverse

    world = _two_robots()
    (undo,) = inverse(world, "change", {"name": "ground", "changes": {"pose": {"position": [0.0, 0.0, -0.5]}}})
    assert undo.args == {
        "name": "ground", "changes": {"pose": {"position": [0.0, 0.0, 0.0], "orientation": [1.0, 0.0, 0.0, 0.0]}}
    }  # fmt: skip
