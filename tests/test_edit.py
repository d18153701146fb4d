"""simrun.world.edit: edits of a running world keep every untouched body's state; refused edits change nothing.

Ground truth is MuJoCo's own: the MjData arrays before and after, a second world that was never edited,
and a plain MjModel compiled from MJCF with the friction an edit set.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import pytest

from simrun.run.session import prepare
from simrun.scene.scene_file import load_scene
from simrun.world import edit
from simrun.world.edit import EditError
from simrun.world.edit_bindings import add_sensor, change_sensor, change_service, remove_sensor
from simrun.world.edit_push import apply_force

SCENES = Path(__file__).resolve().parent.parent / "fixtures" / "scenes"
BOEBOT = SCENES / "boebot_sensors.toml"


def _running(seconds: float = 0.6):
    world = load_scene(BOEBOT)
    prepare(world, seed=3)
    world.service("DriveService", "boebot").drive_distance(-0.5)
    world.run(seconds)
    return world


def _joint_state(world, name):
    model, data = world.model, world.data
    j = model.joint(name)
    nq, nv = {0: (7, 6), 1: (4, 3), 2: (1, 1), 3: (1, 1)}[int(j.type[0])]
    a, d = int(j.qposadr[0]), int(j.dofadr[0])
    return data.qpos[a : a + nq].copy(), data.qvel[d : d + nv].copy()


JOINTS = ("boebot/free", "boebot/left_wheel", "boebot/right_wheel", "box/free")


def test_insert_keeps_every_untouched_body_bit_identical():
    world = _running()
    before = {j: _joint_state(world, j) for j in JOINTS}
    time, ctrl = world.time, world.data.ctrl.copy()
    noise = world.sensors["laser"].rng.bit_generator.state
    names = edit.insert(world, {"type": "Box", "name": "crate", "dimensions": [0.1, 0.1, 0.1], "free": True,
                                "pose": {"position": [3.0, 3.0, 0.05]}})  # fmt: skip
    assert names == ["crate"]
    for j in JOINTS:
        q, v = _joint_state(world, j)
        assert q.tobytes() == before[j][0].tobytes() and v.tobytes() == before[j][1].tobytes(), j
    assert world.time == time and world.data.ctrl.tobytes() == ctrl.tobytes()
    assert world.sensors["laser"].rng.bit_generator.state == noise
    assert world.model.body("crate").id > 0
    assert world.data.body("crate").xpos.tolist() == [3.0, 3.0, 0.05]


def test_an_edit_that_changes_no_physics_continues_exactly_as_an_unedited_world():
    edited, plain = _running(), _running()
    edit.change(edited, "box", {"color": [1.0, 0.0, 0.0, 1.0]})  # a recompile, same physics
    assert edited.model.geom("box/geom").rgba.tolist() == [1.0, 0.0, 0.0, 1.0]
    edited.run(1.0)
    plain.run(1.0)
    assert edited.data.qpos.tobytes() == plain.data.qpos.tobytes()
    assert edited.data.qvel.tobytes() == plain.data.qvel.tobytes()
    assert edited.service("DriveService", "boebot").snapshot() == plain.service("DriveService", "boebot").snapshot()
    assert edited.sensors["laser"].reading.ranges.tobytes() == plain.sensors["laser"].reading.ranges.tobytes()


@pytest.mark.parametrize(
    ("call", "field"),
    [
        (lambda w: edit.insert(w, {"type": "Boxx", "name": "x"}), "entity.type"),
        (lambda w: edit.insert(w, {"type": "Box", "name": "box"}), "entity.name"),
        (
            lambda w: edit.insert(w, {"type": "Box", "name": "k", "kinematic": True, "parent": "boebot"}),
            "entity.parent",
        ),
        (lambda w: edit.insert(w, {"type": "Box", "name": "n", "mass": float("nan")}), "entity.mass"),
        (lambda w: edit.insert(w, {"type": "Box", "name": "n", "dimensions": [1, 2]}), "entity.dimensions"),
        (lambda w: edit.insert(w, [{"type": "Box", "name": f"b{k}"} for k in range(edit.MAX_BATCH + 1)]), "entities"),
        (lambda w: edit.insert(w, {"type": "MeshEntity", "name": "m", "asset": "../../../etc/x.mbin"}), "entity.asset"),
        (lambda w: edit.insert(w, {"type": "Ground", "name": "g", "texture": "/etc/hostname"}), "entity.texture"),
        (lambda w: edit.change(w, "box", {"mass": -1.0}), None),
        (lambda w: edit.change(w, "box", {"material": {"restitution": 5.0}}), "material"),
        (lambda w: edit.change(w, "box", {"pose": {"orientation": [2.0, 0, 0, 0]}}), "pose"),
        (lambda w: edit.change(w, "box", {"name": "other"}), "name"),
        (lambda w: edit.change(w, "nobody", {"mass": 1.0}), "name"),
        (lambda w: edit.change(w, "boebot", {"wheel_radius": 0.0}), None),
        (lambda w: edit.remove(w, "nobody"), "name"),
        (lambda w: edit.teleport(w, "box", [float("inf"), 0, 0]), "position"),
        (lambda w: apply_force(w, "box", force=[1e9, 0, 0]), "force"),
        (lambda w: apply_force(w, "ground", force=[1, 0, 0]), "name"),
        (lambda w: change_sensor(w, "laser", {"rate": -1.0}), "rate"),
        (lambda w: change_sensor(w, "laser", {"entity": "box"}), "entity"),
        (lambda w: change_service(w, "DriveService", "boebot", {"rate": 0.0}), None),
        (lambda w: edit.set_gravity(w, [0, 0]), "gravity"),
    ],
)
def test_a_refused_edit_changes_nothing(call, field):
    world = _running()
    model, data = world.model, world.data
    state, entities = edit.state_bytes(world), list(world)
    controllers, services = list(world.controllers), [dict(s) for s in world.services]
    snapshots = [c.snapshot() for c in world.controllers]
    with pytest.raises(EditError) as refused:
        call(world)
    if field is not None:
        assert refused.value.key is not None and refused.value.key.startswith(field), refused.value
    assert "\n" not in str(refused.value)
    assert world.model is model and world.data is data
    assert edit.state_bytes(world) == state
    assert list(world) == entities and world.services == services
    assert world.controllers == controllers and [c.snapshot() for c in world.controllers] == snapshots
    world.run(0.1)  # and it still runs


def test_remove_takes_the_bindings_along_and_a_camera_sensor_blocks_nothing_else():
    world = _running()
    gone = edit.remove(world, "boebot")
    assert gone == {"entities": ["boebot"], "services": ["DriveService:boebot"], "sensors": ["laser"]}
    assert "boebot" not in [world.model.body(b).name for b in range(world.model.nbody)]
    assert list(world.sensors) == ["view_cam"] and world.services == []
    world.run(0.1)


def test_change_pose_puts_the_entity_there_at_rest_and_mass_keeps_its_state():
    world = _running()
    apply_force(world, "box", force=[0.0, 0.0, 200.0], duration=0.05)
    world.run(0.05)
    q, v = _joint_state(world, "box/free")
    assert v[2] > 0.5  # flying up
    edit.change(world, "box", {"mass": 2.0})
    assert world.model.body("box").mass[0] == pytest.approx(2.0)
    q2, v2 = _joint_state(world, "box/free")
    assert q2.tobytes() == q.tobytes() and v2.tobytes() == v.tobytes()
    edit.change(world, "box", {"pose": {"position": [2.5, 0.5, 0.1]}})
    q3, v3 = _joint_state(world, "box/free")
    assert q3[:3].tolist() == [2.5, 0.5, 0.1] and not v3.any()
    assert world.entity("box").pose.position == (2.5, 0.5, 0.1)


def test_teleport_a_free_body_without_a_recompile():
    world = _running()
    model, others = world.model, _joint_state(world, "boebot/free")
    moved = edit.teleport(world, "box", [2.0, 2.0, 0.1], [1.0, 0.0, 0.0, 0.0])
    assert not moved["recompiled"] and world.model is model
    assert moved["pose"] == [2.0, 2.0, 0.1, 1.0, 0.0, 0.0, 0.0]
    q, v = _joint_state(world, "boebot/free")
    assert q.tobytes() == others[0].tobytes() and v.tobytes() == others[1].tobytes()
    assert edit.teleport(world, "sun", [0.0, 0.0, 3.0]) is not None  # a light has no body
    assert world.entity("sun").pose.position == (0.0, 0.0, 3.0)


def test_services_and_sensors_change_in_place_and_keep_their_state():
    world = _running()
    laser = world.sensors["laser"]
    noise, samples = laser.rng.bit_generator.state, laser.samples
    index = world.controllers.index(laser)
    change_sensor(world, "laser", {"rate": 20.0, "noise": 0.01})
    new = world.sensors["laser"]
    assert new is not laser and new.period == pytest.approx(0.05) and new.noise == 0.01
    assert new.rng.bit_generator.state == noise and new.samples == samples
    assert world.controllers[index] is new and list(world.sensors) == ["laser", "view_cam"]
    drive = world.service("DriveService", "boebot")
    snapshot = drive.snapshot()
    change_service(world, "DriveService", "boebot", {"limits": {"max_linear": 0.2}})
    assert world.service("DriveService", "boebot").limits.max_linear == 0.2
    assert world.service("DriveService", "boebot").snapshot() == snapshot
    add_sensor(world, {"type": "Bumper", "name": "bump", "entity": "boebot"})
    assert world.sensors["bump"].period == pytest.approx(0.02)
    remove_sensor(world, "bump")
    assert "bump" not in world.sensors
    world.run(0.2)


def _slide(mu: float, force: float, seconds: float, plain: bool, tmp_path: Path) -> float:
    """How far a 5 kg box pushed with ``force`` N along +X for ``seconds`` slides in 1.5 s on a floor of friction mu."""
    if plain:  # MuJoCo's own model of the same box, floor and push, written by hand
        xml = f"""<mujoco><option timestep="0.002" integrator="implicitfast" gravity="0 0 -9.81"/>
        <worldbody><geom name="floor" type="plane" size="10 10 0.1" friction="{mu} 0.005 0.0001" priority="1"
        solref="0.02 1"/><body name="box" pos="0 0 0.1"><freejoint/><geom type="box" size="0.1 0.1 0.1"
        mass="5"/></body></worldbody></mujoco>"""
        model = mujoco.MjModel.from_xml_string(xml)
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        start = data.body("box").xpos[0]
        b = model.body("box").id
        steps = round(seconds / 0.002)
        for k in range(round(1.5 / 0.002)):
            data.xfrc_applied[b, 0] = force if k < steps else 0.0
            mujoco.mj_step(model, data)
        return float(data.body("box").xpos[0] - start)
    scene = tmp_path / "slide.toml"
    scene.write_text(
        '[world]\ntimestep = 0.002\n[[entities]]\ntype = "Ground"\nname = "floor"\n'
        '[[entities]]\ntype = "Box"\nname = "box"\nmass = 5.0\nfree = true\ndimensions = [0.2, 0.2, 0.2]\n'
        "pose = { position = [0.0, 0.0, 0.1] }\n"
    )
    world = load_scene(scene)
    world.run(0.0)
    edit.change(world, "floor", {"material": {"dynamic_friction": mu}})
    start = float(world.data.body("box").xpos[0])
    apply_force(world, "box", force=[force, 0.0, 0.0], duration=seconds)
    world.run(1.5)
    return float(world.data.body("box").xpos[0] - start)


def test_floor_friction_edit_slides_the_box_as_mujocos_own_model_predicts(tmp_path):
    slides = {}
    for mu in (0.2, 0.5):
        slides[mu] = _slide(mu, 40.0, 0.5, False, tmp_path)
        assert slides[mu] == pytest.approx(_slide(mu, 40.0, 0.5, True, tmp_path), abs=1e-9), mu
    assert slides[0.2] > 2 * slides[0.5] > 0.05  # the edit changed the sliding distance, as the physics says


def test_gravity_edit_keeps_the_state():
    world = _running()
    before = {j: _joint_state(world, j) for j in JOINTS}
    edit.set_gravity(world, [0.0, 0.0, -1.62])
    assert world.model.opt.gravity.tolist() == [0.0, 0.0, -1.62]
    for j in JOINTS:
        assert _joint_state(world, j)[0].tobytes() == before[j][0].tobytes()


def test_schemas_come_from_the_registry():
    from simrun.world.edit_schema import types_schema

    kinds = types_schema()
    box = next(t for t in kinds["entities"] if t["type"] == "Box")
    keys = {k["name"]: k for k in box["keys"]}
    assert list(keys)[:5] == ["name", "parent", "pose", "free", "kinematic"]
    assert keys["mass"]["unit"] == "kg" and keys["dimensions"]["type"] == "3 numbers"
    assert [f["name"] for f in keys["material"]["fields"]] == [
        "material.restitution",
        "material.dynamic_friction",
        "material.static_friction",
    ]
    assert {t["type"] for t in kinds["sensors"]} >= {"Bumper", "LaserRangeFinder", "Webcam"}
    world = _running()
    listed = edit.describe_all(world)
    assert [e["name"] for e in listed] == [n for n, _ in world]
    box_now = next(e for e in listed if e["name"] == "box")
    assert box_now["values"]["mass"] == 5.0 and len(box_now["pose"]) == 7


def test_only_the_files_an_edit_names_must_be_inside_the_scene_folder(tmp_path):
    import shutil

    shutil.copy(SCENES / "globe.png", tmp_path / "globe.png")
    (tmp_path / "scene").mkdir()
    scene = tmp_path / "scene" / "outside.toml"
    scene.write_text('[[entities]]\ntype = "Ground"\nname = "ground"\ntexture = "../globe.png"\n')
    world = load_scene(scene)
    world.run(0.01)
    edit.change(world, "ground", {"size": 5.0})  # the scene's own file stays the scene's business
    assert world.model.geom("ground/plane").size[0] == 5.0
    with pytest.raises(EditError) as refused:
        edit.change(world, "ground", {"texture": "../globe.png"})
    assert refused.value.key == "texture" and "outside the scene's folder" in str(refused.value)


ROBOT_SCENES = ["boebot.toml", "arm_on_base.toml", "mjcf_arm_on_base.toml", "urdf_arm.toml"]


@pytest.mark.parametrize("name", ROBOT_SCENES, ids=[n.removesuffix(".toml") for n in ROBOT_SCENES])
def test_every_robot_kind_keeps_its_state_across_an_edit_and_continues_as_an_unedited_one(name):
    """Built-in, arm on a base, MJCF and URDF robots: every joint bit-identical across an insert far away."""
    edited, plain = load_scene(SCENES / name), load_scene(SCENES / name)
    for world in (edited, plain):
        prepare(world)
        world.run(0.3)
    joints = [edited.model.joint(j).name for j in range(edited.model.njnt)]
    before = {j: _joint_state(edited, j) for j in joints}
    edit.change(edited, "ground", {"size": 9.0})  # a recompile; same physics (the size is only drawn)
    edit.insert(edited, {"type": "Sphere", "name": "far_ball", "radius": 0.05, "pose": {"position": [50, 50, 5]}})
    for j in joints:
        q, v = _joint_state(edited, j)
        assert q.tobytes() == before[j][0].tobytes() and v.tobytes() == before[j][1].tobytes(), j
    edited.run(0.5)
    plain.run(0.5)
    for j in joints:  # a welded ball 50 m away changes nothing of the robots' motion
        assert _joint_state(edited, j)[0].tobytes() == _joint_state(plain, j)[0].tobytes(), j
    assert [c.snapshot() for c in edited.controllers] == [c.snapshot() for c in plain.controllers]


@pytest.mark.parametrize(
    ("call", "table", "key", "reason"),
    [
        ("service", ["DriveService"], "service", "invalid"),
        ("service", {"type": "WarpDrive", "entity": "boebot"}, "type", "invalid"),
        ("service", {"type": "DriveService", "entity": "nobody"}, "entity", "missing"),
        ("service", {"type": "DriveService", "entity": "boebot"}, "entity", "conflict"),  # bound by the scene
        ("sensor", "Bumper", "sensor", "invalid"),
        ("sensor", {"type": "Bumpr", "name": "b", "entity": "boebot"}, "type", "invalid"),
        ("sensor", {"type": "Bumper", "entity": "boebot"}, "name", "invalid"),
        ("sensor", {"type": "Bumper", "name": "laser", "entity": "boebot"}, "name", "conflict"),
        ("sensor", {"type": "Bumper", "name": "b", "entity": "nobody"}, "entity", "missing"),
    ],
)
def test_a_refused_service_or_sensor_table_names_its_field_and_changes_nothing(call, table, key, reason):
    from simrun.world.edit_bindings import add_service

    world = _running(0.1)
    model, data, services, sensors = world.model, world.data, list(world.services), list(world.sensors)
    qpos = data.qpos.copy()
    with pytest.raises(EditError) as refused:
        (add_service if call == "service" else add_sensor)(world, table)
    assert (refused.value.key, refused.value.reason) == (key, reason), refused.value
    assert world.model is model and world.data is data and (data.qpos == qpos).all()
    assert list(world.services) == services and list(world.sensors) == sensors
