"""simrun.world.edit_save: a saved edited world passes `simrun check` and compiles to the running model.

Ground truth: MuJoCo's compiled models (bodies, geoms, masses, inertias, poses) and MjData of the running world
and of the saved scene loaded again; `simrun check` run as the user runs it (a subprocess).
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest

from simrun.run.session import prepare
from simrun.scene.scene_file import load_scene
from simrun.world import edit
from simrun.world.edit import EditError
from simrun.world.edit_save import entities_text, load_entities, load_entities_text, save_entities, save_world

SCENES = Path(__file__).resolve().parent.parent / "fixtures" / "scenes"


def _copy(tmp_path: Path, name: str) -> Path:
    folder = tmp_path / "scene"
    folder.mkdir(exist_ok=True)
    for item in ("boebot_sensors.toml", "head_on_table.toml", "head.mbin"):
        shutil.copy(SCENES / item, folder / item)
    return folder / name


def _edited(scene: Path):
    world = load_scene(scene)
    prepare(world)
    world.run(0.4)
    return world


def _check(path: Path) -> None:
    done = subprocess.run(
        [str(Path(sys.executable).parent / "simrun"), "check", str(path)], capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stdout + done.stderr


def _same_model(a: mujoco.MjModel, b: mujoco.MjModel, poses: bool = True) -> None:
    assert [a.body(i).name for i in range(a.nbody)] == [b.body(i).name for i in range(b.nbody)]
    assert [a.geom(i).name for i in range(a.ngeom)] == [b.geom(i).name for i in range(b.ngeom)]
    for field in ("body_mass", "body_inertia", "geom_type", "geom_size", "geom_friction", "geom_rgba", "jnt_type"):
        assert np.array_equal(getattr(a, field), getattr(b, field)), field
    if poses:
        for field in ("body_pos", "body_quat", "geom_pos", "geom_quat"):
            assert np.array_equal(getattr(a, field), getattr(b, field)), field


def test_saved_edited_world_checks_and_compiles_to_the_running_model(tmp_path):
    world = _edited(_copy(tmp_path, "boebot_sensors.toml"))
    edit.insert(world, {"type": "Sphere", "name": "ball", "radius": 0.05, "free": True, "color": [1.0, 0.2, 0.2, 1.0],
                        "pose": {"position": [2.0, 2.0, 0.3]}})  # fmt: skip
    edit.insert(world, {"type": "Box", "name": "lid", "parent": "box", "dimensions": [0.05, 0.05, 0.02],
                        "pose": {"position": [0.0, 0.0, 0.11]}})  # fmt: skip
    edit.change(world, "ground", {"material": {"dynamic_friction": 0.4}})
    edit.change(world, "box", {"mass": 3.0})
    world.service("DriveService", "boebot").drive_distance(-0.3)
    world.run(0.5)
    out = tmp_path / "out" / "saved.toml"
    out.parent.mkdir()
    save_world(world, out)
    _check(out)
    loaded = load_scene(out)
    _same_model(world.model, loaded.model, poses=False)
    mujoco.mj_forward(world.model, world.data)  # xpos of the state now (a step leaves the one before it)
    for body in ("boebot", "box", "box/lid", "ball"):  # free bodies and a child: where they are now
        assert np.allclose(loaded.data.body(body).xpos, world.data.body(body).xpos, atol=1e-12, rtol=0), body
        assert np.allclose(loaded.data.body(body).xquat, world.data.body(body).xquat, atol=1e-12, rtol=0), body
    assert not loaded.data.qvel.any()
    current = tmp_path / "out" / "current.toml"
    save_world(world, current, state="current")  # the running model exactly, and its state
    _check(current)
    again = load_scene(current)
    prepare(again)
    _same_model(world.model, again.model)
    assert again.data.qpos.tobytes() == world.data.qpos.tobytes()
    world.run(0.3)
    again.run(0.3)
    assert again.data.qpos.tobytes() == world.data.qpos.tobytes()


def test_asset_paths_stay_relative_as_in_the_source_scene(tmp_path):
    world = _edited(_copy(tmp_path, "head_on_table.toml"))
    edit.insert(world, {"type": "MeshEntity", "name": "head2", "asset": "head.mbin", "free": True, "mass": 1.0,
                        "pose": {"position": [0.3, 0.0, 1.0]}})  # fmt: skip
    out = tmp_path / "scene" / "saved.toml"
    save_world(world, out)
    text = out.read_text()
    assert 'head = "head.mbin"' in text and 'asset = "head.mbin"' in text and str(tmp_path) not in text
    _check(out)
    _same_model(world.model, load_scene(out).model, poses=False)
    deeper = tmp_path / "scene" / "sub" / "saved.toml"
    deeper.parent.mkdir()
    save_world(world, deeper)
    assert 'head = "../head.mbin"' in deeper.read_text()
    _check(deeper)


def test_entities_copied_between_worlds_keep_their_poses_relative_to_the_parent(tmp_path):
    source = _edited(_copy(tmp_path, "boebot_sensors.toml"))
    edit.insert(source, {"type": "Box", "name": "lid", "parent": "box", "dimensions": [0.05, 0.05, 0.02],
                         "pose": {"position": [0.0, 0.03, 0.11], "orientation": [0.6, 0.8, 0.0, 0.0]}})  # fmt: skip
    edit.insert(source, {"type": "Sphere", "name": "knob", "parent": "box/lid", "radius": 0.01,
                         "pose": {"position": [0.0, 0.0, 0.02]}})  # fmt: skip
    file = tmp_path / "scene" / "lid.toml"
    save_entities(source, ["box/lid"], file)
    _check(file)
    target = load_scene(tmp_path / "scene" / "head_on_table.toml")
    target.run(0.2)
    table_before = target.data.qpos.copy()
    added = load_entities(target, file, parent="table")
    assert added["entities"] == ["table/lid", "table/lid/knob"]
    assert target.data.qpos.tobytes() == table_before.tobytes()  # the head keeps falling where it was

    def relative(world, child, parent):
        m = world.model
        c, p = m.body(child).id, m.body(parent).id
        assert m.body_parentid[c] == p
        return m.body_pos[c].copy(), m.body_quat[c].copy()

    for child, parent in (("lid", "box"), ("lid/knob", "lid")):
        a = relative(source, f"box/{child}", f"box/{parent}" if parent != "box" else "box")
        b = relative(target, f"table/{child}", f"table/{parent}" if parent != "box" else "table")
        assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1]), child
    text = entities_text(source, ["boebot"])
    other = load_scene(tmp_path / "scene" / "head_on_table.toml")
    got = load_entities_text(other, text)
    assert got == {"entities": ["boebot"], "services": ["DriveService:boebot"], "sensors": ["laser"]}
    other.service("DriveService", "boebot").drive_distance(0.1)
    other.run(0.2)


@pytest.mark.parametrize(
    ("text", "field"),
    [
        ('[[entities]]\ntype = "Box"\nname = "table"\n', "entities[0].name"),
        ('[[entities]]\ntype = "Nope"\nname = "x"\n', "entities[0].type"),
        ('[[entities]]\ntype = "MeshEntity"\nname = "m"\nasset = "../../x.mbin"\n', "entities[0].asset"),
        ("[[entities]\n", "text"),
        ("[bogus]\nx = 1\n", "bogus"),
        ('[assets]\nhead = "other.mbin"\n', "assets.head"),
    ],
)
def test_a_refused_load_adds_nothing(tmp_path, text, field):
    world = load_scene(_copy(tmp_path, "head_on_table.toml"))
    world.run(0.1)
    model, state, names = world.model, edit.state_bytes(world), list(world)
    with pytest.raises(EditError) as refused:
        load_entities_text(world, text)
    assert refused.value.key == field
    assert world.model is model and edit.state_bytes(world) == state and list(world) == names
