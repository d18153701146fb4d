"""simrun's world-to-GLB export: load it back with trimesh and compare with the compiled model."""

from __future__ import annotations

import io
import json
import struct
from pathlib import Path

import mujoco
import numpy as np
import pytest
import trimesh
from click.testing import CliRunner

from simrun.cli.main import main
from simrun.errors import SimrunError
from simrun.export.glb import Z_UP_TO_Y_UP, export_world_glb, world_to_glb
from simrun.scene.scene_file import load_scene

SCENES = Path(__file__).resolve().parent.parent / "fixtures" / "scenes"


def _world(scene: str):  # type: ignore[no-untyped-def]
    world = load_scene(SCENES / scene)
    world.compile()
    return world


def test_every_geom_is_a_named_node_in_its_world_pose() -> None:
    world = _world("head_on_table.toml")
    model = world.model
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    scene = trimesh.load(io.BytesIO(world_to_glb(world)), file_type="glb")
    shown = [g for g in range(model.ngeom) if model.geom_group[g] < 3]  # collision geoms are not drawn
    assert set(scene.graph.nodes_geometry) == {model.geom(g).name for g in shown}
    back = np.linalg.inv(Z_UP_TO_Y_UP)
    for g in shown:
        name = model.geom(g).name
        transform, geometry = scene.graph[name]
        pose = back @ transform
        np.testing.assert_allclose(pose[:3, 3], data.geom_xpos[g], atol=1e-9)
        np.testing.assert_allclose(pose[:3, :3], data.geom_xmat[g].reshape(3, 3), atol=1e-9)
        colour = scene.geometry[geometry].visual.material.baseColorFactor
        np.testing.assert_array_equal(colour, np.round(np.asarray(model.geom_rgba[g]) * 255).astype(np.uint8))
        if model.geom_type[g] == int(mujoco.mjtGeom.mjGEOM_MESH):
            mesh_id = int(model.geom_dataid[g])
            assert len(scene.geometry[geometry].faces) == int(model.mesh_facenum[mesh_id])
            assert len(scene.geometry[geometry].vertices) == int(model.mesh_vertnum[mesh_id])


def test_collision_geoms_are_left_out_by_default_and_hidden_on_request() -> None:
    world = _world("head_on_table.toml")
    model = world.model
    visible = {model.geom(g).name for g in range(model.ngeom) if model.geom_group[g] < 3}
    hulls = {model.geom(g).name for g in range(model.ngeom) if model.geom_group[g] >= 3}
    assert visible and hulls
    plain = trimesh.load(io.BytesIO(world_to_glb(world)), file_type="glb")
    assert set(plain.graph.nodes_geometry) == visible
    tree = _gltf_json(world_to_glb(world, collision=True))
    scenes = tree["scenes"]
    assert tree["scene"] == 0 and [s["name"] for s in scenes] == ["visual", "visual+collision"]
    collision = next(i for i, n in enumerate(tree["nodes"]) if n["name"] == "collision")
    assert collision not in _reachable(tree, scenes[0]["nodes"])
    assert {tree["nodes"][i]["name"] for i in tree["nodes"][collision]["children"]} == {f"collision/{n}" for n in hulls}
    shown = {tree["nodes"][i].get("name") for i in _reachable(tree, scenes[1]["nodes"])}
    assert visible | {f"collision/{n}" for n in hulls} <= shown


def _gltf_json(glb: bytes) -> dict:  # type: ignore[type-arg]
    length = struct.unpack_from("<I", glb, 12)[0]
    document: dict = json.loads(glb[20 : 20 + length])  # type: ignore[type-arg]
    return document


def _reachable(tree: dict, roots: list[int]) -> set[int]:  # type: ignore[type-arg]
    seen: set[int] = set()
    stack = list(roots)
    while stack:
        node = stack.pop()
        seen.add(node)
        stack.extend(tree["nodes"][node].get("children", []))
    return seen


def test_cli_writes_byte_identical_glb(tmp_path: Path) -> None:
    out = tmp_path / "room.glb"
    result = CliRunner().invoke(main, ["export", str(SCENES / "pioneer_room.toml"), "--glb", str(out)])
    assert result.exit_code == 0, result.output
    assert out.read_bytes() == world_to_glb(_world("pioneer_room.toml"))
    assert out.read_bytes()[:4] == b"glTF"


def test_wrong_extension_is_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(SimrunError, match=r"must end in \.glb"):
        export_world_glb(_world("basic.toml"), tmp_path / "x.gltf")
    assert list(tmp_path.iterdir()) == []
