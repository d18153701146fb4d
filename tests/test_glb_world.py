"""simrun's world-to-GLB export: load it back with trimesh and compare with the compiled model."""

from __future__ import annotations

import io
from pathlib import Path

import mujoco
import numpy as np
import pytest
import trimesh
from click.testing import CliRunner

from simrun.cli import main
from simrun.errors import SimrunError
from simrun.glb_export import Z_UP_TO_Y_UP, export_world_glb, world_to_glb
from simrun.scene import load_scene

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
    names = {model.geom(g).name for g in range(model.ngeom)}
    assert set(scene.graph.nodes_geometry) == names
    back = np.linalg.inv(Z_UP_TO_Y_UP)
    for g in range(model.ngeom):
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
