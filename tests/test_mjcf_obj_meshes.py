"""Exported MJCF meshes are Wavefront OBJ that other tools read: trimesh reads back exactly the spec's arrays.

Ground truth: the world's own spec (``uservert``/``userface`` of each mesh given as arrays, or the in-memory
``.msh`` file MuJoCo compiles, decoded by its documented layout), against the OBJ
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


def _msh_arrays(data: bytes) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (n, 3) float32 and faces (m, 3) of a MuJoCo binary ``.msh`` file, read as MuJoCo documents it:
    four int32 counts (vertices, normals, texture coordinates, faces), then the float32 and int32 arrays."""
    nv, nn, nt, nf = np.frombuffer(data[:16], dtype="<i4")
    floats = np.frombuffer(data[16 : 16 + 4 * (3 * nv + 3 * nn + 2 * nt)], dtype="<f4")
    faces = np.frombuffer(data[16 + 4 * (3 * nv + 3 * nn + 2 * nt) :], dtype="<i4")
    assert faces.size == 3 * nf
    return floats[: 3 * nv].reshape(-1, 3), faces.reshape(-1, 3)


@pytest.mark.parametrize("scene", ["head_on_table", "urdf_arm"])
def test_exported_meshes_are_obj_files_other_tools_read_exactly(scene, tmp_path):
    world = load_scene(SCENES / f"{scene}.toml")
    written = export_world_mjcf(world, tmp_path / "scene.xml")
    assert {p.suffix for p in written} <= {".xml", ".obj", ".png"} and not list(tmp_path.glob("*.msh"))
    files = world.spec.assets  # the in-memory files MuJoCo compiles (.mbin meshes as .msh)
    given = [m for m in world.spec.meshes if not m.file or m.file in files]
    objs = sorted(p for p in written if p.suffix == ".obj")
    assert len(objs) == len(given) > 0
    sources = [
        _msh_arrays(files[m.file])
        if m.file
        else (np.asarray(m.uservert, dtype=np.float32).reshape(-1, 3), np.asarray(m.userface).reshape(-1, 3))
        for m in given
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
