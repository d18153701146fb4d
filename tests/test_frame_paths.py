"""One frame for one mesh file, whatever path reads it (issue 26): the same vertices in the same frame.

Each format (OBJ, STL, PLY, glTF, GLB, COLLADA declaring ``Y_UP`` as Assimp and MeshLab write whatever they
hold) holds the same asymmetric solid, in a ROS package whose URDF uses it. ``meshtool normalize``,
``obj2bin`` on the file and on its folder, and ``meshtool urdf`` must give the same vertex set (metres, Z-up);
the URDF's collision box, placed by MuJoCo's own compile, must enclose the same extent. Without the URDF
the file's own evidence decides (a glTF is Y-up by its specification), which is tested for glTF too.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest
import trimesh
from bounded import run_bounded

from meshtool.packfile.read import parse

#: A wedge, 0.3 x 0.2 x 0.1 m, its highest corner at +x: every axis and sign of it can be told apart.
WEDGE = trimesh.Trimesh(
    vertices=[[0, 0, 0], [0.3, 0, 0], [0.3, 0.2, 0], [0, 0.2, 0], [0.3, 0, 0.1], [0.3, 0.2, 0.1]],
    faces=[[0, 2, 1], [0, 3, 2], [0, 1, 4], [3, 5, 2], [1, 2, 5], [1, 5, 4], [0, 4, 5], [0, 5, 3]],
)
#: Z-up to glTF's Y-up (+90 degrees about X inverted): what a Y-up file holds for the same solid.
Z_TO_Y = np.array([[1, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 0], [0, 0, 0, 1]], dtype=float)


def _write(folder: Path, fmt: str) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    if fmt in ("gltf", "glb"):
        mesh = WEDGE.copy()
        mesh.apply_transform(Z_TO_Y)  # stored Y-up, as the glTF specification says it is
        if fmt == "glb":
            path = folder / "wedge.glb"
            path.write_bytes(mesh.export(file_type="glb"))
        else:
            files = mesh.export(file_type="gltf")
            for name, data in files.items():
                (folder / name.replace("model.gltf", "wedge.gltf")).write_bytes(data)
            path = folder / "wedge.gltf"
        return path
    if fmt == "dae":
        path = folder / "wedge.dae"
        data: bytes = trimesh.exchange.dae.export_collada(WEDGE)  # type: ignore[no-untyped-call]
        text = data.decode()
        if "<up_axis>" in text:
            text = text.replace("<up_axis>Z_UP</up_axis>", "<up_axis>Y_UP</up_axis>")
        else:
            text = text.replace("</asset>", "<up_axis>Y_UP</up_axis></asset>", 1)
        path.write_text(text)  # holds Z-up data but says Y_UP, as Assimp and MeshLab write
        return path
    path = folder / f"wedge.{fmt}"
    exported = WEDGE.export(file_type=fmt)
    path.write_bytes(exported.encode() if isinstance(exported, str) else exported)
    return path


def _vertices(mbin: Path) -> np.ndarray:
    packed = parse(mbin.read_bytes(), mbin.name)
    return np.unique(np.round(np.asarray(packed.positions, dtype=float), 6), axis=0)


FORMATS = ["obj", "stl", "ply", "gltf", "glb", "dae"]


@pytest.mark.parametrize("fmt", FORMATS)
def test_every_path_gives_the_same_vertices_for_a_mesh_a_urdf_uses(tmp_path: Path, fmt: str) -> None:
    pkg = tmp_path / "wedge_description"
    mesh = _write(pkg / "meshes", fmt)
    (pkg / "package.xml").write_text("<package><name>wedge_description</name></package>\n")
    urdf = pkg / "urdf" / "wedge.urdf"
    urdf.parent.mkdir()
    urdf.write_text(
        '<robot name="wedge"><link name="base">\n'
        f'<visual><geometry><mesh filename="package://wedge_description/meshes/{mesh.name}"/></geometry></visual>\n'
        '<collision><origin xyz="0.15 0.1 0.05"/><geometry><box size="0.3 0.2 0.1"/></geometry></collision>\n'
        "</link></robot>\n"
    )
    single = run_bounded(["obj2bin", str(mesh), "-o", str(tmp_path / "single.mbin"), "--no-check"])
    assert single.code == 0, single.err
    folder = run_bounded(["obj2bin", str(pkg / "meshes"), "-o", str(tmp_path / "folder"), "--no-check"])
    assert folder.code == 0, folder.err
    imported = run_bounded(["meshtool", "urdf", str(urdf), "-o", str(tmp_path / "robot")])
    assert imported.code == 0, imported.err
    normalised = run_bounded(["meshtool", "normalize", str(mesh), "-o", str(tmp_path / "norm")])
    assert normalised.code == 0, normalised.err

    truth = np.unique(np.round(np.asarray(WEDGE.vertices, dtype=float), 6), axis=0)  # Z-up, metres
    got = {
        "obj2bin FILE": _vertices(tmp_path / "single.mbin"),
        "obj2bin DIR": _vertices(next((tmp_path / "folder").rglob("*.mbin"))),
        "meshtool urdf": _vertices(next((tmp_path / "robot" / "meshes").glob("*.mbin"))),
        "meshtool normalize": np.unique(
            np.round(trimesh.load(next((tmp_path / "norm").rglob("*.obj")), force="mesh").vertices, 6), axis=0
        ),
    }
    for path, vertices in got.items():
        np.testing.assert_allclose(vertices, truth, atol=2e-6, err_msg=f"{fmt}: {path}")
    model = mujoco.MjModel.from_xml_path(str(tmp_path / "robot" / "wedge.xml"))  # MuJoCo's own frames
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    box = next(g for g in range(model.ngeom) if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX)
    np.testing.assert_allclose(data.geom_xpos[box], [0.15, 0.1, 0.05], atol=1e-9)
    np.testing.assert_allclose(truth.min(axis=0), data.geom_xpos[box] - model.geom_size[box], atol=1e-6)
    np.testing.assert_allclose(truth.max(axis=0), data.geom_xpos[box] + model.geom_size[box], atol=1e-6)


@pytest.mark.parametrize("fmt", ["gltf", "glb"])
def test_a_gltf_without_a_consumer_is_turned_by_its_specification(tmp_path: Path, fmt: str) -> None:
    mesh = _write(tmp_path / "loose", fmt)
    out = run_bounded(["obj2bin", str(mesh), "-o", str(tmp_path / "w.mbin"), "--no-check"])
    assert out.code == 0, out.err
    truth = np.unique(np.round(np.asarray(WEDGE.vertices, dtype=float), 6), axis=0)
    np.testing.assert_allclose(_vertices(tmp_path / "w.mbin"), truth, atol=2e-6)
