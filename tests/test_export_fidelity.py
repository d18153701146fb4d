"""Exports keep what an MJCF model says (issue 37 item 5): compiler settings, world geoms, ``.msh`` meshes,
one-joint equalities, GLB rotations.

Ground truth: MuJoCo's own load of the model (``MjModel.from_xml_path`` of the fixture, and of the exported
MJCF after its folder is moved), pxr for USD, trimesh for the OBJ written for a ``.msh``, the Khronos glTF
validator for GLB (skipped where it is not installed). Fixture: fixtures/mjcf/exports/
(scripts/make_export_fixtures.py).
"""

from __future__ import annotations

import json
import shutil
import struct
import subprocess
from pathlib import Path

import mujoco
import numpy as np
import pytest
import trimesh

from meshtool.mjcf.model_desc import ModelError
from simrun.export.glb import world_to_glb
from simrun.export.mjcf_builder import export_world_mjcf, folder_files, msh_arrays
from simrun.export.usd import export_world_usd
from simrun.scene.scene_file import load_scene
from simrun.world.world import World

ROOT = Path(__file__).resolve().parent.parent
FIXTURE = ROOT / "fixtures" / "mjcf" / "exports"
VALIDATOR = ROOT / "tools" / "gltf-validator" / "node_modules" / "gltf-validator"
BODIES = ("base", "tip", "turned")
INERTIAL = ("body_mass", "body_inertia", "body_ipos", "body_iquat")


def _world(folder: Path = FIXTURE) -> World:
    world = load_scene(folder / "settings.toml")
    world.compile()
    return world


def _moved_export(world: World, tmp_path: Path) -> mujoco.MjModel:
    """The world exported as MJCF, the folder moved elsewhere, loaded there by MuJoCo."""
    export_world_mjcf(world, tmp_path / "out" / "scene.xml")
    shutil.move(tmp_path / "out", tmp_path / "moved")
    return mujoco.MjModel.from_xml_path(str(tmp_path / "moved" / "scene.xml"))


def test_mjcf_export_keeps_compiler_bounds_and_world_geoms(tmp_path: Path) -> None:
    """The moved export's bodies weigh what MuJoCo's own load of the model says; the world slab weighs nothing."""
    own = mujoco.MjModel.from_xml_path(str(FIXTURE / "settings.xml"))
    assert own.body("tip").mass[0] == 0.05  # boundmass raised the 2 g tip (MuJoCo's rule, not ours)
    world = _world()
    loaded = _moved_export(world, tmp_path)
    for name in BODIES:
        for field in INERTIAL:
            ours = getattr(loaded, field)[loaded.body(f"robot/{name}").id]
            theirs = getattr(own, field)[own.body(name).id]
            assert np.allclose(ours, theirs, rtol=1e-9, atol=1e-12), (name, field, ours, theirs)
    # the world body carries no mass in MuJoCo's load; attached, its slab is the entity's static body's
    assert own.body_mass[0] == 0.0
    assert world.model.body("robot").mass[0] == 0.0 and loaded.body("robot").mass[0] == 0.0


#: One compiler setting that changes the compiled model per case, with a body it changes.
SETTINGS = {
    "boundmass": ('boundmass="0.3"', ""),
    "boundinertia": ('boundinertia="0.01"', ""),
    "balanceinertia": ('balanceinertia="true"', '<inertial pos="0 0 0" mass="1" diaginertia="0.001 0.001 0.01"/>'),
    "inertiafromgeom-false": ('inertiafromgeom="false"', '<inertial pos="0.01 0 0" mass="0.7" diaginertia="1 2 3"/>'),
    "inertiagrouprange": ('inertiagrouprange="1 2"', ""),
    "angle-degree": ('angle="degree"', ""),
    "eulerseq": ('eulerseq="ZYX" angle="radian"', ""),
    "settotalmass": ('settotalmass="3"', ""),
    "fusestatic": ('fusestatic="true"', ""),
    "discardvisual": ('discardvisual="true"', ""),
    "alignfree": ('alignfree="true"', ""),
}


@pytest.mark.parametrize("case", sorted(SETTINGS))
def test_every_compiler_setting_survives_a_moved_mjcf_export(case: str, tmp_path: Path) -> None:
    setting, inertial = SETTINGS[case]
    model = f"""<mujoco><compiler {setting}/><worldbody>
  <body name="arm" pos="0 0 1" euler="0.3 0.2 0.1"><freejoint/>{inertial}
    <geom type="box" size="0.1 0.05 0.02" mass="0.2"/>
    <geom type="sphere" size="0.03" pos="0.1 0 0" group="2" mass="0.01"/>
    <geom type="sphere" size="0.02" pos="-0.1 0 0" contype="0" conaffinity="0" mass="0.02"/>
    <body name="plate" pos="-0.1 0 0.05"><geom type="box" size="0.02 0.02 0.005" mass="0.03"/></body>
    <body name="hand" pos="0.2 0 0">{inertial}<joint name="wrist" axis="0 1 0" range="-30 30"/>
      <geom type="capsule" size="0.01 0.05" group="1" mass="0.05"/></body>
  </body></worldbody></mujoco>"""
    (tmp_path / "m.xml").write_text(model, encoding="utf-8")
    (tmp_path / "s.toml").write_text('[[entities]]\ntype = "MjcfRobot"\nname = "r"\nfile = "m.xml"\n', encoding="utf-8")
    own = mujoco.MjModel.from_xml_path(str(tmp_path / "m.xml"))
    world = load_scene(tmp_path / "s.toml")
    world.compile()
    loaded = _moved_export(world, tmp_path)
    for name in ("arm", "hand"):
        for field in (*INERTIAL, "body_pos", "body_quat"):
            ours = getattr(loaded, field)[loaded.body(f"r/{name}").id]
            theirs = getattr(own, field)[own.body(name).id]
            assert np.allclose(ours, theirs, rtol=1e-9, atol=1e-12), (case, name, field, ours, theirs)
    assert np.allclose(loaded.joint("r/wrist").range, own.joint("wrist").range, rtol=1e-12)
    assert loaded.joint("r/wrist").limited[0] == own.joint("wrist").limited[0]


def test_refusal_names_the_body_and_the_field() -> None:
    """Without the compiled inertials the written folder loses ``boundmass``: the refusal says where and what."""
    world = _world()
    with pytest.raises(ModelError) as raised:
        folder_files(world.spec, "scene.xml", base_dir=world.base_dir)
    message = raised.value.one_line()
    assert "body 'robot/tip' body_mass 0.002 where the model has 0.05" in message, message


def test_msh_mesh_is_written_as_obj(tmp_path: Path) -> None:
    """No ``.msh`` in the export; its OBJ holds the tetrahedron MuJoCo read from the ``.msh`` (trimesh reads it)."""
    own = mujoco.MjModel.from_xml_path(str(FIXTURE / "settings.xml"))
    written = export_world_mjcf(_world(), tmp_path / "out" / "scene.xml")
    assert not [p for p in written if p.suffix.lower() == ".msh"]
    objs = [p for p in written if p.suffix == ".obj"]
    assert len(objs) == 1
    mesh = trimesh.load(objs[0], force="mesh", process=False)
    assert isinstance(mesh, trimesh.Trimesh) and len(mesh.faces) == 4
    raw = (FIXTURE / "tet.msh").read_bytes()
    counts = struct.unpack("<4i", raw[:16])
    assert np.allclose(mesh.vertices, np.frombuffer(raw, "<f4", 3 * counts[0], 16).reshape(-1, 3))
    shutil.move(tmp_path / "out", tmp_path / "moved")
    loaded = mujoco.MjModel.from_xml_path(str(tmp_path / "moved" / "scene.xml"))
    for field in ("mesh_vert", "mesh_face", "mesh_normal", "mesh_texcoord"):
        assert np.array_equal(getattr(loaded, field), getattr(own, field)), field


@pytest.mark.parametrize(
    "data", [b"", b"\x04\0\0\0" * 4, struct.pack("<4i", 4, 0, 0, 1) + b"\0" * 48 + struct.pack("<3i", 0, 1, 9)]
)
def test_a_damaged_msh_is_refused_with_its_name(data: bytes) -> None:
    with pytest.raises(ModelError, match=r"'parts/x\.msh' is not a MuJoCo \.msh mesh"):
        msh_arrays(data, "parts/x.msh")


def test_usd_export_takes_a_one_joint_equality(tmp_path: Path) -> None:
    pxr = pytest.importorskip("pxr")
    out = tmp_path / "scene.usda"
    unmapped = export_world_usd(_world(), out)
    assert "equality robot/hold: joint robot/swing held at 0; no UsdPhysics counterpart" in unmapped
    stage = pxr.Usd.Stage.Open(str(out))
    assert stage.GetRootLayer().customLayerData["simrun:unmapped"] == unmapped
    masses = {
        prim.GetAttribute("simrun:name").Get(): prim.GetAttribute("physics:mass").Get()
        for prim in stage.Traverse()
        if prim.HasAttribute("physics:mass")
    }
    assert masses["robot"] == 0.0 and masses["robot/tip"] == pytest.approx(0.05)  # world slab and bound kept


def _glb_json(glb: bytes) -> dict:  # type: ignore[type-arg]
    length = struct.unpack_from("<I", glb, 12)[0]
    parsed: dict = json.loads(glb[20 : 20 + length])  # type: ignore[type-arg]
    return parsed


def test_glb_rotations_are_unit_and_in_range(tmp_path: Path) -> None:
    """The composed identity MuJoCo returns as w = 1.0000000000000002 is written as a valid glTF rotation."""
    world = _world()
    data = mujoco.MjData(world.model)
    mujoco.mj_forward(world.model, data)
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, data.geom_xmat[world.model.geom("robot/straight").id])
    assert quat.max() > 1.0  # the case itself: MuJoCo's own conversion passes 1
    glb = world_to_glb(world, collision=True)
    rotations = [node["rotation"] for node in _glb_json(glb)["nodes"] if "rotation" in node]
    assert rotations and all(max(abs(c) for c in r) <= 1.0 for r in rotations)
    assert all(abs(float(np.linalg.norm(r)) - 1.0) < 1e-12 for r in rotations)
    out = tmp_path / "scene.glb"
    out.write_bytes(glb)
    node = shutil.which("node")
    if node is None:
        pytest.skip("node is not installed (the Khronos glTF validator runs on Node.js)")
    if not VALIDATOR.is_dir():
        pytest.skip("gltf-validator is not installed: run scripts/install_gltf_validator.sh")
    run = subprocess.run([node, str(ROOT / "scripts" / "gltf_validate.cjs"), str(out)], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    issues = json.loads(run.stdout)["issues"]
    shown = [(m["code"], m["pointer"], m["message"]) for m in issues["messages"]]
    assert (issues["numErrors"], issues["numWarnings"], issues["numInfos"], issues["numHints"]) == (0, 0, 0, 0), shown


def test_a_model_without_joints_and_a_capsule_with_three_sizes_exports(tmp_path: Path) -> None:
    """No joints (dm_control's props), a capsule given a third size it does not use (dm_control's rodent)."""
    model = """<mujoco><worldbody><body name="prop" pos="0 0 0.1">
  <geom name="c" type="capsule" size="0.01 0.02 0.005"/><geom name="s" type="sphere" size="0.02 0.5 0.5"/>
</body></worldbody></mujoco>"""
    (tmp_path / "m.xml").write_text(model, encoding="utf-8")
    (tmp_path / "s.toml").write_text('[[entities]]\ntype = "MjcfRobot"\nname = "r"\nfile = "m.xml"\n', encoding="utf-8")
    own = mujoco.MjModel.from_xml_path(str(tmp_path / "m.xml"))
    world = load_scene(tmp_path / "s.toml")
    world.compile()
    loaded = _moved_export(world, tmp_path)
    assert loaded.njnt == 0
    assert np.array_equal(loaded.geom("r/c").size[:2], own.geom("c").size[:2])
    assert loaded.geom("r/s").size[0] == own.geom("s").size[0]
    assert np.allclose(loaded.body("r/prop").mass, own.body("prop").mass, rtol=1e-12)


def test_msh_texture_coordinates_near_zero_read_back_within_a_float32_step(tmp_path: Path) -> None:
    """A ``.msh`` v of 0.06472757 cannot come back exactly through OBJ's ``1 - v`` (float32): within 2^-23."""
    vertices = np.array([(0, 0, 0), (0.04, 0, 0), (0, 0.03, 0), (0, 0, 0.02)], "<f4")
    uvs = np.array([(0.0, 0.06472757), (1.0, 0.0647275), (0.0, 0.3), (0.5, 1e-9)], "<f4")
    faces = np.array([(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)], "<i4")
    data = struct.pack("<4i", 4, 0, 4, 4) + vertices.tobytes() + uvs.tobytes() + faces.tobytes()
    (tmp_path / "t.msh").write_bytes(data)
    (tmp_path / "m.xml").write_text(
        '<mujoco><asset><mesh name="t" file="t.msh"/></asset><worldbody><body name="b"><geom type="mesh" mesh="t"/>'
        "</body></worldbody></mujoco>",
        encoding="utf-8",
    )
    (tmp_path / "s.toml").write_text('[[entities]]\ntype = "MjcfRobot"\nname = "r"\nfile = "m.xml"\n', encoding="utf-8")
    own = mujoco.MjModel.from_xml_path(str(tmp_path / "m.xml"))
    world = load_scene(tmp_path / "s.toml")
    world.compile()
    loaded = _moved_export(world, tmp_path)
    assert np.array_equal(loaded.mesh_vert, own.mesh_vert)
    assert np.abs(loaded.mesh_texcoord - own.mesh_texcoord).max() <= 2.0**-23
