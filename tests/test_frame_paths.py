"""One frame for one mesh file, whatever path reads it (issue 26): the same vertices in the same frame.

Each format (OBJ, STL, PLY, glTF, GLB, COLLADA declaring ``Y_UP`` as Assimp and MeshLab write whatever they
hold) holds the same asymmetric solid, in a ROS package whose URDF uses it. ``meshtool normalize``,
``obj2bin`` on the file and on its folder, and ``meshtool urdf`` must give the same vertex set (metres, Z-up);
the URDF's collision box, placed by MuJoCo's own compile, must enclose the same extent. Without the URDF
the file's own evidence decides (a glTF is Y-up by its specification), which is tested for glTF too.

The remaining entry paths, with and without the consumer URDF: ``meshtool validate`` (the vertices it
checks and the extent it reports), ``meshtool mjcf FILE`` and simrun loading the file (a ``MeshEntity``
whose asset is the mesh file, and a ``UrdfRobot`` of the URDF), the last two read from MuJoCo's compiled
model in the world frame.
"""

from __future__ import annotations

import json
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


def _package(tmp_path: Path, fmt: str, consumer: bool) -> tuple[Path, Path | None]:
    """The wedge in ``fmt`` in a ROS package whose URDF uses it (``consumer``), or alone in a folder."""
    pkg = tmp_path / "wedge_description"
    mesh = _write(pkg / "meshes", fmt)
    if not consumer:
        return mesh, None
    (pkg / "package.xml").write_text("<package><name>wedge_description</name></package>\n")
    urdf = pkg / "urdf" / "wedge.urdf"
    urdf.parent.mkdir()
    urdf.write_text(
        '<robot name="wedge"><link name="base">\n'
        f'<visual><geometry><mesh filename="package://wedge_description/meshes/{mesh.name}"/></geometry></visual>\n'
        '<collision><origin xyz="0.15 0.1 0.05"/><geometry><box size="0.3 0.2 0.1"/></geometry></collision>\n'
        "</link></robot>\n"
    )
    return mesh, urdf


@pytest.mark.parametrize("fmt", FORMATS)
def test_every_path_gives_the_same_vertices_for_a_mesh_a_urdf_uses(tmp_path: Path, fmt: str) -> None:
    mesh, urdf = _package(tmp_path, fmt, consumer=True)
    assert urdf is not None
    pkg = mesh.parent.parent
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


# -- validate and simrun (issue 26, deliver 3: every entry path) ------------------------------------------

#: Formats read as Y-up when no consumer file says otherwise (docs/formats.md: OBJ by its convention, PLY by
#: default, COLLADA by its declared ``Y_UP``); STL falls back to CAD's Z-up, glTF is Y-up by its specification.
LOOSE_Y_UP = ("obj", "ply", "dae")

#: Where the scene puts the mesh entity: 1 m along x, -2 m along y, 0.5 m up, turned 90 degrees about Z.
POSE_POSITION = np.array([1.0, -2.0, 0.5])
POSE_QUAT = np.array([np.sqrt(0.5), 0.0, 0.0, np.sqrt(0.5)])


def _assert_same_points(got: np.ndarray, want: np.ndarray, what: str, atol: float = 2e-6) -> None:
    """Every point of ``got`` lies within ``atol`` of one of ``want`` and the other way round (metres)."""
    distance = np.linalg.norm(np.asarray(got, float)[:, None, :] - np.asarray(want, float)[None, :, :], axis=2)
    worst = max(float(distance.min(axis=1).max()), float(distance.min(axis=0).max()))
    assert worst <= atol, f"{what}: {worst:.3g} m from the other paths' vertices\n{got}\nvs\n{want}"


def _mesh_geoms_in_world(model: mujoco.MjModel, data: mujoco.MjData, group: int) -> np.ndarray:
    """MuJoCo's compiled vertices of every mesh geom in ``group``, in the world frame (metres)."""
    points = []
    for g in range(model.ngeom):
        if model.geom_type[g] != mujoco.mjtGeom.mjGEOM_MESH or model.geom_group[g] != group:
            continue
        mesh = int(model.geom_dataid[g])
        first, count = int(model.mesh_vertadr[mesh]), int(model.mesh_vertnum[mesh])
        local = np.asarray(model.mesh_vert[first : first + count], dtype=float)
        points.append(local @ data.geom_xmat[g].reshape(3, 3).T + data.geom_xpos[g])
    assert points, f"no mesh geom in group {group}"
    return np.concatenate(points)


@pytest.mark.parametrize("consumer", [True, False], ids=["urdf", "loose"])
@pytest.mark.parametrize("fmt", FORMATS)
def test_validate_mjcf_and_simrun_see_the_vertices_every_other_path_sees(
    tmp_path: Path, fmt: str, consumer: bool
) -> None:
    """obj2bin FILE and DIR, normalize, ``meshtool mjcf``, validate and simrun agree on the vertices.

    validate is read twice: the vertices it checks and the extent its JSON report gives (for the file and
    for its pack); ``meshtool mjcf`` and simrun through MuJoCo's compiled model.

    The reference is ``obj2bin FILE``; with a consumer URDF (and for glTF, Y-up by its specification, without
    one) it is the wedge as modelled, Z-up. Without one the file's own evidence decides (:data:`LOOSE_Y_UP`),
    and every path must decide the same. simrun's side is read from MuJoCo's compiled model: each mesh geom's vertices
    through its world pose (``geom_xpos``/``geom_xmat`` after ``mj_forward``), the entity posed away from
    the origin so a frame dropped on the way shows.
    """
    from click.testing import CliRunner

    from meshtool.cli.main import main as meshtool_main
    from meshtool.cli.main import obj2bin
    from meshtool.validate.task import AssetTask, read_asset
    from simrun import UrdfRobot, World
    from simrun.scene.scene_file import load_scene

    mesh, urdf = _package(tmp_path, fmt, consumer)
    runner = CliRunner()
    single = tmp_path / "packs" / "single.mbin"
    result = runner.invoke(obj2bin, [str(mesh), "-o", str(single), "--no-check"])
    assert result.exit_code == 0, result.output
    reference = _vertices(single)
    truth = np.unique(np.round(np.asarray(WEDGE.vertices, dtype=float), 6), axis=0)
    expected = truth
    if not consumer and fmt in LOOSE_Y_UP:  # (x, y, z) -> (x, -z, y), docs/conventions.md
        expected = np.stack([truth[:, 0], -truth[:, 2], truth[:, 1]], axis=1)
    _assert_same_points(reference, expected, f"{fmt}: obj2bin FILE")
    result = runner.invoke(obj2bin, [str(mesh.parent), "-o", str(tmp_path / "folder"), "--no-check"])
    assert result.exit_code == 0, result.output
    _assert_same_points(_vertices(next((tmp_path / "folder").rglob("*.mbin"))), reference, f"{fmt}: obj2bin DIR")
    result = runner.invoke(meshtool_main, ["normalize", str(mesh), "-o", str(tmp_path / "norm")])
    assert result.exit_code == 0, result.output
    normalised = trimesh.load(next((tmp_path / "norm").rglob("*.obj")), force="mesh").vertices
    _assert_same_points(normalised, reference, f"{fmt}: meshtool normalize")

    # meshtool mjcf FILE: the model it writes, as MuJoCo compiles it (visual group 2, hull group 3)
    result = runner.invoke(meshtool_main, ["mjcf", str(mesh), "-o", str(tmp_path / "mjcf")])
    assert result.exit_code == 0, result.output
    model = mujoco.MjModel.from_xml_path(str(next((tmp_path / "mjcf").rglob("*.xml"))))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    _assert_same_points(_mesh_geoms_in_world(model, data, 2), reference, f"{fmt}: meshtool mjcf (visual)")
    _assert_same_points(_mesh_geoms_in_world(model, data, 3), reference, f"{fmt}: meshtool mjcf (hull)", 1e-5)

    # meshtool validate: the vertices it checks, and the extent its report gives for the file and the pack
    read = read_asset(AssetTask(mesh, mesh.name))
    assert read.asset is not None, [f.one_line() for f in read.result.findings]
    _assert_same_points(read.asset.mesh.positions, reference, f"{fmt}: meshtool validate (checked vertices)")
    args = ["validate", str(mesh), str(single), "--json", "--no-cache", "-j", "1", "--no-thumbnails"]
    result = runner.invoke(meshtool_main, args)
    assert result.exit_code == 0, result.output
    report = json.loads(result.output)
    assert len(report["assets"]) == 2
    for asset in report["assets"]:
        box = asset["stats"]["bbox"]
        np.testing.assert_allclose(box["min"], reference.min(axis=0), atol=1e-6, err_msg=f"{fmt}: {asset['path']}")
        np.testing.assert_allclose(box["max"], reference.max(axis=0), atol=1e-6, err_msg=f"{fmt}: {asset['path']}")

    # simrun: the mesh file as a scene asset, packed on the fly, its entity posed away from the origin
    scene = tmp_path / "scene.toml"
    position, quat = (", ".join(repr(float(v)) for v in values) for values in (POSE_POSITION, POSE_QUAT))
    scene.write_text(
        f'[assets]\nwedge = "{mesh.relative_to(tmp_path).as_posix()}"\n\n'
        '[[entities]]\ntype = "MeshEntity"\nname = "wedge"\nasset = "wedge"\n'
        f"pose = {{ position = [{position}], orientation = [{quat}] }}\n"
    )
    model, _ = load_scene(scene).compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    rotation = np.zeros(9)
    mujoco.mju_quat2Mat(rotation, POSE_QUAT)
    placed = reference @ rotation.reshape(3, 3).T + POSE_POSITION
    _assert_same_points(_mesh_geoms_in_world(model, data, 2), placed, f"{fmt}: simrun MeshEntity (visual)")
    # the one convex hull of a convex wedge is the wedge: the collision geom has the same corners
    _assert_same_points(_mesh_geoms_in_world(model, data, 3), placed, f"{fmt}: simrun MeshEntity (hull)", 1e-5)
    if urdf is None:
        return
    world = World(base_dir=tmp_path)
    world.insert(UrdfRobot(name="wedge", urdf=str(urdf.relative_to(tmp_path))))
    model, _ = world.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    _assert_same_points(_mesh_geoms_in_world(model, data, 2), truth, f"{fmt}: simrun UrdfRobot (visual)")


@pytest.mark.parametrize("fmt", LOOSE_Y_UP)
def test_a_urdf_outside_a_ros_package_is_seen_by_every_path(tmp_path: Path, fmt: str) -> None:
    """``robot/urdf/w.urdf`` using ``../meshes/wedge.*`` with no ``package.xml``: obj2bin FILE vs simrun's URDF."""
    from click.testing import CliRunner

    from meshtool.cli.main import obj2bin
    from simrun import UrdfRobot, World

    mesh = _write(tmp_path / "robot" / "meshes", fmt)
    urdf = tmp_path / "robot" / "urdf" / "w.urdf"
    urdf.parent.mkdir()
    urdf.write_text(
        f'<robot name="w"><link name="base"><visual><geometry><mesh filename="../meshes/{mesh.name}"/>'
        "</geometry></visual></link></robot>\n"
    )
    world = World(base_dir=tmp_path)
    world.insert(UrdfRobot(name="w", urdf="robot/urdf/w.urdf"))
    model, _ = world.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    truth = np.asarray(WEDGE.vertices, dtype=float)
    _assert_same_points(_mesh_geoms_in_world(model, data, 2), truth, f"{fmt}: simrun UrdfRobot")
    result = CliRunner().invoke(obj2bin, [str(mesh), "-o", str(tmp_path / "w.mbin"), "--no-check"])
    assert result.exit_code == 0, result.output
    _assert_same_points(_vertices(tmp_path / "w.mbin"), truth, f"{fmt}: obj2bin FILE")


# -- a vendor's MJCF two and three folders above its meshes (issue 38) -------------------------------------


@pytest.mark.parametrize("part", ["meshes/finger/finger.obj", "meshes/convex/base/base.obj"])
def test_every_path_keeps_a_vendor_mesh_where_mujoco_puts_it(tmp_path: Path, part: str) -> None:
    """fixtures/vendor/ cloned (``.git``): a Blender OBJ its MJCF uses Z-up from two or three folders above.

    Each path (obj2bin FILE and DIR, normalize, ``meshtool mjcf``, validate, simrun's ``MeshEntity``) must give
    the vertices MuJoCo's own compile of the vendor's MJCF gives that mesh (the part's geom sits at the
    world origin, so its world vertices are the mesh's as MuJoCo reads it).
    """
    import shutil

    from click.testing import CliRunner
    from conftest import FIXTURES

    from meshtool.cli.main import main as meshtool_main
    from meshtool.cli.main import obj2bin
    from meshtool.validate.task import AssetTask, read_asset
    from simrun import load_scene

    vendor = tmp_path / "vendor"
    shutil.copytree(FIXTURES / "vendor", vendor)
    (vendor / ".git").mkdir()
    mesh = vendor / part
    model = mujoco.MjModel.from_xml_path(str(vendor / "robots" / "gripper" / "robot.xml"))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    name = {"meshes/finger/finger.obj": "finger", "meshes/convex/base/base.obj": "base_convex"}[part]
    (geom,) = [g for g in range(model.ngeom) if model.mesh(int(model.geom_dataid[g])).name == name]
    dataid = int(model.geom_dataid[geom])
    first, count = int(model.mesh_vertadr[dataid]), int(model.mesh_vertnum[dataid])
    local = np.asarray(model.mesh_vert[first : first + count], dtype=float)
    truth = local @ data.geom_xmat[geom].reshape(3, 3).T + data.geom_xpos[geom]

    runner = CliRunner()
    single = tmp_path / "single.mbin"
    assert runner.invoke(obj2bin, [str(mesh), "-o", str(single), "--no-check"]).exit_code == 0
    _assert_same_points(_vertices(single), truth, f"{part}: obj2bin FILE")
    result = runner.invoke(obj2bin, [str(mesh.parent), "-o", str(tmp_path / "folder"), "--no-check"])
    assert result.exit_code == 0, result.output
    _assert_same_points(_vertices(next((tmp_path / "folder").rglob("*.mbin"))), truth, f"{part}: obj2bin DIR")
    result = runner.invoke(meshtool_main, ["normalize", str(mesh), "-o", str(tmp_path / "norm")])
    assert result.exit_code == 0, result.output
    normalised = trimesh.load(next((tmp_path / "norm").rglob("*.obj")), force="mesh").vertices
    _assert_same_points(normalised, truth, f"{part}: meshtool normalize")
    result = runner.invoke(meshtool_main, ["mjcf", str(mesh), "-o", str(tmp_path / "mjcf")])
    assert result.exit_code == 0, result.output
    written = mujoco.MjModel.from_xml_path(str(next((tmp_path / "mjcf").rglob("*.xml"))))
    written_data = mujoco.MjData(written)
    mujoco.mj_forward(written, written_data)
    _assert_same_points(_mesh_geoms_in_world(written, written_data, 2), truth, f"{part}: meshtool mjcf")
    read = read_asset(AssetTask(mesh, mesh.name))
    assert read.asset is not None, [f.one_line() for f in read.result.findings]
    _assert_same_points(read.asset.mesh.positions, truth, f"{part}: meshtool validate")
    scene = tmp_path / "scene.toml"
    scene.write_text(
        f'[assets]\npart = "{mesh.relative_to(tmp_path).as_posix()}"\n\n'
        '[[entities]]\ntype = "MeshEntity"\nname = "part"\nasset = "part"\n'
    )
    loaded, _ = load_scene(scene).compile()
    loaded_data = mujoco.MjData(loaded)
    mujoco.mj_forward(loaded, loaded_data)
    _assert_same_points(_mesh_geoms_in_world(loaded, loaded_data, 2), truth, f"{part}: simrun MeshEntity")
