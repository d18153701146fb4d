"""Exported MJCF meshes are Wavefront OBJ that other tools read: trimesh reads back exactly the spec's arrays.

Ground truth: the world's own spec (``uservert``/``userface`` of each mesh given as arrays), against the OBJ
files as trimesh (not our code) parses them, and MuJoCo loading the folder (``folder_files`` checks that the
compiled mesh arrays are identical).
"""

from pathlib import Path

import numpy as np
import pytest
import trimesh

from simrun import load_scene
from simrun.export.mjcf_builder import export_world_mjcf

SCENES = Path(__file__).resolve().parent.parent / "fixtures" / "scenes"


@pytest.mark.parametrize("scene", ["head_on_table", "urdf_arm"])
def test_exported_meshes_are_obj_files_other_tools_read_exactly(scene, tmp_path):
    world = load_scene(SCENES / f"{scene}.toml")
    written = export_world_mjcf(world, tmp_path / "scene.xml")
    assert {p.suffix for p in written} <= {".xml", ".obj", ".png"} and not list(tmp_path.glob("*.msh"))
    arrays = {m.name: m for m in world.spec.meshes if not m.file}
    objs = sorted(p for p in written if p.suffix == ".obj")
    assert len(objs) == len(arrays) > 0
    sources = [
        (np.asarray(m.uservert, dtype=np.float32).reshape(-1, 3), np.asarray(m.userface).reshape(-1, 3))
        for m in arrays.values()
    ]
    matched = []
    for path in objs:
        mesh = trimesh.load(path, file_type="obj", process=False, maintain_order=True)
        read = mesh.vertices.astype(np.float32), np.asarray(mesh.faces)
        same = [k for k, (v, f) in enumerate(sources) if v.shape == read[0].shape and f.shape == read[1].shape]
        same = [k for k in same if np.array_equal(sources[k][0], read[0]) and np.array_equal(sources[k][1], read[1])]
        assert same, f"{path.name}: trimesh reads arrays that no mesh of the spec has"
        matched.append(same[0])
    assert sorted(matched) == list(range(len(sources)))  # every mesh written once, exactly
