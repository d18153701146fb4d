"""One command from a mesh file to a MuJoCo model (issue 31, item 3).

``obj2bin X.obj --mjcf OUT/`` and ``meshtool mjcf X.obj`` write the MJCF folder; a simrun scene takes a mesh
file as an ``[assets]`` entry (packed on the fly, cached); a mesh file where only a pack can go says what to
run. Ground truth: MuJoCo loading the written folder alone, trimesh reading the same OBJ.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest
import trimesh

from meshtool.cli.main import main as meshtool_main
from meshtool.cli.mesh_commands import obj2bin
from simrun.scene.scene_file import load_scene
from simrun.world.assets import pack_cache

OBJ2BIN = [sys.executable, "-c", "from meshtool.cli.main import obj2bin; obj2bin()"]
# An L-shaped prism (12 vertices, concave), modelled in millimetres, Z up: 40 x 30 x 10 mm.
L_SHAPE = """\
v 0 0 0
v 40 0 0
v 40 10 0
v 10 10 0
v 10 30 0
v 0 30 0
v 0 0 10
v 40 0 10
v 40 10 10
v 10 10 10
v 10 30 10
v 0 30 10
f 1 6 5 4 3 2
f 7 8 9 10 11 12
f 1 2 8 7
f 2 3 9 8
f 3 4 10 9
f 4 5 11 10
f 5 6 12 11
f 6 1 7 12
"""


@pytest.fixture
def l_obj(tmp_path: Path) -> Path:
    path = tmp_path / "src" / "L part.obj"
    path.parent.mkdir()
    path.write_text(L_SHAPE)
    return path


def _reference(obj: Path) -> tuple[int, np.ndarray]:
    """trimesh's vertex count and bounds (metres) of the OBJ."""
    mesh = trimesh.load(obj, force="mesh", process=True)
    return len(mesh.vertices), np.asarray(mesh.bounds) * 0.001


def _visual_world_vertices(model: mujoco.MjModel) -> np.ndarray:
    """Every vertex of the visual (group 2) mesh geoms in world coordinates, metres."""
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    points = []
    for g in range(model.ngeom):
        if model.geom_type[g] != mujoco.mjtGeom.mjGEOM_MESH or model.geom_group[g] != 2:
            continue
        m = model.geom_dataid[g]
        verts = model.mesh_vert[model.mesh_vertadr[m] : model.mesh_vertadr[m] + model.mesh_vertnum[m]]
        points.append(verts @ data.geom_xmat[g].reshape(3, 3).T + data.geom_xpos[g])
    return np.concatenate(points)


def _load_alone(folder: Path, tmp_path: Path) -> mujoco.MjModel:
    """MuJoCo loads the model from a copy of its folder alone (nothing else beside it)."""
    alone = tmp_path / "alone" / folder.name
    shutil.copytree(folder, alone)
    (xml,) = alone.glob("*.xml")
    return mujoco.MjModel.from_xml_path(str(xml))


def test_obj2bin_writes_an_mjcf_folder_that_loads_alone_and_matches_trimesh(
    l_obj: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as done:
        obj2bin.main([str(l_obj), "--units", "mm", "--up", "z", "--mjcf", str(tmp_path / "mjcf")])
    assert done.value.code == 0
    folder = tmp_path / "mjcf" / "l_part"
    assert f"wrote {folder / 'l_part.xml'}" in capsys.readouterr().out
    assert not list(tmp_path.glob("*.mbin")) and not list(Path.cwd().glob("*.mbin"))  # no -o: the model only
    model = _load_alone(folder, tmp_path)
    count, bounds = _reference(l_obj)
    points = _visual_world_vertices(model)
    assert len(np.unique(points.round(9), axis=0)) == count == 12
    np.testing.assert_allclose([points.min(0), points.max(0)], bounds, atol=1e-6)
    # the collision hull is the convex hull of the L: the body's mass is its volume at 1000 kg/m^3
    hull = trimesh.load(l_obj, force="mesh").convex_hull
    assert model.body_mass[1] == pytest.approx(hull.volume * 1e-9 * 1000.0, rel=1e-6)


def test_obj2bin_mjcf_with_output_also_writes_the_same_pack_obj2bin_writes(l_obj: Path, tmp_path: Path) -> None:
    both = subprocess.run(
        [*OBJ2BIN, str(l_obj), "--units", "mm", "--mjcf", str(tmp_path / "m"), "-o", str(tmp_path / "a.mbin")],
        capture_output=True,
        text=True,
        check=False,
    )
    assert both.returncode == 0, both.stderr
    alone = subprocess.run(
        [*OBJ2BIN, str(l_obj), "--units", "mm", "-o", str(tmp_path / "b.mbin")], capture_output=True, check=False
    )
    assert alone.returncode == 0
    assert (tmp_path / "a.mbin").read_bytes() == (tmp_path / "b.mbin").read_bytes()
    assert (tmp_path / "m" / "l_part" / "l_part.xml").is_file()


def test_meshtool_mjcf_takes_a_mesh_file(l_obj: Path, tmp_path: Path) -> None:
    with pytest.raises(SystemExit) as done:
        meshtool_main(["mjcf", str(l_obj), "--units", "mm", "--up", "z", "-o", str(tmp_path / "out"), "--mass", "2"])
    assert done.value.code == 0
    model = _load_alone(tmp_path / "out" / "l_part", tmp_path)
    assert model.body_mass[1] == pytest.approx(2.0)
    _, bounds = _reference(l_obj)
    points = _visual_world_vertices(model)
    np.testing.assert_allclose([points.min(0), points.max(0)], bounds, atol=1e-6)


@pytest.mark.parametrize("command", [["info"], ["mjcf", "-o", "out"]])
def test_a_mesh_file_where_a_pack_goes_says_what_to_run(
    l_obj: Path, command: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    """``meshtool info X.obj`` used to say ``byte 0: bad magic number: not an .mbin``."""
    renamed = l_obj.with_suffix(".mbin") if command == ["mjcf", "-o", "out"] else l_obj
    if renamed != l_obj:
        shutil.copy(l_obj, renamed)
        target = renamed
    else:
        target = l_obj
    with pytest.raises(SystemExit) as done:
        meshtool_main([command[0], str(target), *command[1:]])
    assert done.value.code == 1
    err = capsys.readouterr().err
    if target.suffix == ".obj":
        assert f"{target}: a mesh file, not an .mbin (pack it first: obj2bin '{target}';" in err
        assert "bad magic" not in err
    else:  # an OBJ's text under an .mbin name: not a mesh file by its name, so the plain error
        assert "bad magic number: not an .mbin" in err


SCENE = """\
[assets]
part = "{obj}"

[[entities]]
type = "Ground"
name = "ground"

[[entities]]
type = "MeshEntity"
name = "a"
asset = "part"
scale = 0.001
pose = {{ position = [0.0, 0.0, 0.5] }}

[[entities]]
type = "MeshEntity"
name = "b"
asset = "part"
scale = 0.001
pose = {{ position = [1.0, 0.0, 0.5] }}
"""


def test_a_scene_takes_a_mesh_file_as_an_asset_packed_once_and_cached(l_obj: Path, tmp_path: Path) -> None:
    scene = tmp_path / "scene.toml"
    scene.write_text(SCENE.format(obj=l_obj.relative_to(tmp_path).as_posix()))
    model, _ = load_scene(scene).compile()
    count, bounds = _reference(l_obj)
    # packed as obj2bin packs it by default: metres (scale 0.001 makes them millimetres again) and --up auto,
    # which without evidence reads the OBJ as Y-up and turns it Z-up: (x, y, z) -> (x, -z, y)
    turned = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])
    corners = np.array([[x, y, z] for x in bounds[:, 0] for y in bounds[:, 1] for z in bounds[:, 2]]) @ turned.T
    points = _visual_world_vertices(model)
    first = points[: len(points) // 2]
    assert len(np.unique(first.round(9), axis=0)) == count
    np.testing.assert_allclose(first.min(0) - [0, 0, 0.5], corners.min(0), atol=1e-6)
    np.testing.assert_allclose(first.max(0) - [0, 0, 0.5], corners.max(0), atol=1e-6)
    assert model.nmesh == 2  # one visual and one hull mesh, shared by both entities
    cache = list(pack_cache().glob("*.pack"))  # this test's own user cache folder (conftest)
    assert len(cache) == 1 and str(pack_cache()).startswith(os.environ["XDG_CACHE_HOME"])
    stamp = cache[0].stat().st_mtime_ns
    again, _ = load_scene(scene).compile()  # from the cache: the entry is not rewritten
    assert cache[0].stat().st_mtime_ns == stamp and again.nmesh == 2
    l_obj.write_text(L_SHAPE.replace("v 40 0 10", "v 50 0 10"))  # the mesh changed: packed again
    changed, _ = load_scene(scene).compile()
    assert _visual_world_vertices(changed)[:, 0].max() == pytest.approx(1.0 + 0.050, abs=1e-6)
