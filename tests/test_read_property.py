"""Property: the same geometry written by trimesh as STL (binary, ASCII), PLY (binary, ASCII), OBJ, GLB, glTF
and COLLADA converts to the same ``.mbin`` position and index arrays.

Coordinates are multiples of 1/8 so that every format (float32 binary, decimal text) stores them exactly;
vertices are ordered by first use, the order in which STL (which has no shared vertices) defines them.
"""

from pathlib import Path

import numpy as np
import trimesh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from meshtool.packfile import load
from meshtool.pipeline import ConvertOptions, convert
from meshtool.repair.normalise import NormaliseOptions

WRITERS = {
    "binary.stl": {"file_type": "stl"},
    "ascii.stl": {"file_type": "stl_ascii"},
    "binary.ply": {"file_type": "ply", "encoding": "binary"},
    "ascii.ply": {"file_type": "ply", "encoding": "ascii"},
    "mesh.obj": {"file_type": "obj"},
    "mesh.glb": {"file_type": "glb"},
    "mesh.gltf": {"file_type": "gltf"},
    "mesh.dae": {"file_type": "dae"},
}

eighths = st.integers(-64, 64).map(lambda k: k / 8)
extents = st.integers(1, 32).map(lambda k: k / 8)


@st.composite
def geometry(draw: st.DrawFn) -> trimesh.Trimesh:
    """One to three axis-aligned boxes at offsets, apart from each other (STL cannot keep coincident corners of
    two shells apart: it has no shared vertices, only coordinates)."""
    parts = []
    for k in range(draw(st.integers(1, 3))):
        box = trimesh.creation.box(extents=[draw(extents) for _ in range(3)])
        box.apply_translation([draw(eighths) + 30 * k, draw(eighths), draw(eighths)])
        parts.append(box)
    mesh = trimesh.util.concatenate(parts)
    flat = mesh.faces.reshape(-1)
    _, first = np.unique(flat, return_index=True)
    order = flat[np.sort(first)]
    remap = np.empty(len(mesh.vertices), dtype=np.int64)
    remap[order] = np.arange(order.size)
    return trimesh.Trimesh(mesh.vertices[order], remap[mesh.faces], process=False)


def write_all(mesh: trimesh.Trimesh, folder: Path) -> list[Path]:
    paths = []
    for name, options in WRITERS.items():
        kw = dict(options)
        out = mesh.export(file_type=kw.pop("file_type"), **kw)
        sub = folder / name.replace(".", "_")
        sub.mkdir(parents=True)
        if isinstance(out, dict):  # .gltf: the JSON and its buffer
            for file, data in out.items():
                (sub / file).write_bytes(data)
            paths.append(sub / "model.gltf")
        else:
            (sub / name).write_bytes(out if isinstance(out, bytes) else out.encode("utf-8"))
            paths.append(sub / name)
    return paths


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(mesh=geometry())
def test_every_format_packs_to_the_same_arrays(mesh, tmp_path_factory):
    folder = tmp_path_factory.mktemp("formats")
    options = ConvertOptions(NormaliseOptions(units="m", up="y"))
    arrays = {}
    for src in write_all(mesh, folder):
        out = folder / f"{src.parent.name}.mbin"
        convert(src, out, options)
        with load(out) as packed:
            arrays[src.parent.name] = (np.array(packed.positions), np.array(packed.indices))
    reference_positions, reference_indices = arrays["binary_stl"]
    # ground truth from trimesh's own geometry: metres, Y-up rotated to Z-up ((x, y, z) -> (x, -z, y))
    expected = np.stack([mesh.vertices[:, 0], -mesh.vertices[:, 2], mesh.vertices[:, 1]], axis=1)
    np.testing.assert_array_equal(reference_positions, expected.astype(np.float32))
    for name, (positions, indices) in arrays.items():
        np.testing.assert_array_equal(positions, reference_positions, err_msg=name)
        np.testing.assert_array_equal(indices, reference_indices, err_msg=name)
