"""Consumers found where projects keep them (issue 38): the vendor layout, MuJoCo's own reading of the MJCF.

``fixtures/vendor/`` (``scripts/make_vendor_fixtures.py``): an MJCF two and three folders above its OBJ
meshes (``robots/gripper/robot.xml`` over ``meshes/PART/part.obj`` and ``meshes/convex/PART/part.obj``,
``<compiler meshdir="../../meshes"/>``), OBJs with Blender's exporter header (Y-up by default) that the
model uses Z-up, as they are. Ground truth: MuJoCo's compiled model of the MJCF (each mesh geom's vertices
in the world frame). ``obj2bin`` FILE and DIR and ``meshtool validate`` must keep every mesh in that frame,
whether the vendor folder is a repository (``.git``), named with ``--model-root``, or read in place.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import mujoco
import numpy as np
import pytest
from click.testing import CliRunner
from conftest import FIXTURES

from meshtool.cli.main import main as meshtool_main
from meshtool.cli.main import obj2bin
from meshtool.findings import Severity
from meshtool.frame import consumer_index, consumers
from meshtool.frame.consumers import ConsumerIndex, find_consumers, find_index_root
from meshtool.packfile.read import parse
from meshtool.repair.normalise import NormaliseOptions, prepare
from meshtool.validate.task import AssetTask, check_asset, read_asset

VENDOR = FIXTURES / "vendor"
MODEL = "robots/gripper/robot.xml"
MESHES = [
    "meshes/base/base.obj",
    "meshes/finger/finger.obj",
    "meshes/convex/base/base.obj",
    "meshes/convex/finger/finger.obj",
]


def _mujoco_vertices(xml: Path) -> dict[str, np.ndarray]:
    """Mesh file (relative to the vendor folder) -> MuJoCo's compiled vertices of its geom, world frame (m)."""
    model = mujoco.MjModel.from_xml_path(str(xml))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    files = {
        "base": MESHES[0],
        "finger": MESHES[1],
        "base_convex": MESHES[2],
        "finger_convex": MESHES[3],
    }
    out = {}
    for g in range(model.ngeom):
        mesh = int(model.geom_dataid[g])
        first, count = int(model.mesh_vertadr[mesh]), int(model.mesh_vertnum[mesh])
        local = np.asarray(model.mesh_vert[first : first + count], dtype=float)
        out[files[model.mesh(mesh).name]] = local @ data.geom_xmat[g].reshape(3, 3).T + data.geom_xpos[g]
    return out


def _same_points(got: np.ndarray, want: np.ndarray, what: str, atol: float = 2e-6) -> None:
    distance = np.linalg.norm(np.asarray(got, float)[:, None, :] - np.asarray(want, float)[None, :, :], axis=2)
    worst = max(float(distance.min(axis=1).max()), float(distance.min(axis=0).max()))
    assert worst <= atol, f"{what}: {worst:.3g} m from MuJoCo's compiled vertices\n{got}\nvs\n{want}"


def _pack_vertices(mbin: Path) -> np.ndarray:
    packed = parse(mbin.read_bytes(), mbin.name)
    return np.asarray(packed.positions, dtype=float)


def _vendor(tmp_path: Path, layout: str) -> tuple[Path, list[str]]:
    """The vendor folder: a repository clone (``.git``), named by ``--model-root``, a bare copy, or in place."""
    if layout == "in-place":
        return VENDOR, []
    folder = tmp_path / "vendor"
    shutil.copytree(VENDOR, folder)
    if layout == "repository":
        (folder / ".git").mkdir()
        return folder, []
    if layout == "bare":  # no root: the nearby search climbs to the first folder holding description files
        return folder, []
    return folder, ["--model-root", str(folder)]


@pytest.mark.parametrize("layout", ["repository", "model-root", "bare", "in-place"])
def test_obj2bin_and_validate_keep_the_frame_mujoco_gives_each_mesh(tmp_path: Path, layout: str) -> None:
    vendor, extra = _vendor(tmp_path, layout)
    truth = _mujoco_vertices(vendor / MODEL)
    runner = CliRunner()
    for rel in MESHES:
        out = tmp_path / "file" / (rel.replace("/", "_") + ".mbin")
        result = runner.invoke(obj2bin, [str(vendor / rel), "-o", str(out), "--no-check", *extra])
        assert result.exit_code == 0, result.output
        _same_points(_pack_vertices(out), truth[rel], f"{layout}: obj2bin FILE {rel}")
    result = runner.invoke(obj2bin, [str(vendor / "meshes"), "-o", str(tmp_path / "dir"), "--no-check", *extra])
    assert result.exit_code == 0, result.output
    for rel in MESHES:
        packed = tmp_path / "dir" / Path(rel).relative_to("meshes").with_suffix(".mbin")
        _same_points(_pack_vertices(packed), truth[rel], f"{layout}: obj2bin DIR {rel}")
    if extra:
        return  # validate has no --model-root: it finds repositories, packages and Python packages itself
    for rel in MESHES:
        read = read_asset(AssetTask(vendor / rel, rel))
        assert read.asset is not None, [f.one_line() for f in read.result.findings]
        _same_points(read.asset.mesh.positions, truth[rel], f"{layout}: validate {rel}")


def test_without_the_consumer_the_blender_header_turns_the_mesh(tmp_path: Path) -> None:
    """The trap the fixture sets: alone, the OBJ is read Y-up (Blender's default) and turned 90 degrees."""
    (tmp_path / "alone").mkdir()
    shutil.copy(VENDOR / MESHES[1], tmp_path / "alone" / "finger.obj")
    truth = _mujoco_vertices(VENDOR / MODEL)[MESHES[1]]
    asset = prepare(tmp_path / "alone" / "finger.obj", NormaliseOptions())
    turned = np.stack([truth[:, 0], -truth[:, 2], truth[:, 1]], axis=1)  # +90 degrees about X
    _same_points(asset.mesh.positions, turned, "a lone Blender OBJ")
    assert asset.manifest["transform"]["up_rule"] == "exporter"


def test_the_missing_mtl_is_a_warning_for_an_mjcf_consumer_and_an_error_alone(tmp_path: Path) -> None:
    result = check_asset(AssetTask(VENDOR / MESHES[0], "base.obj"))
    (s002,) = [f for f in result.findings if f.code == "S002"]
    assert s002.severity is Severity.WARNING
    assert "not read by its consumer ../../robots/gripper/robot.xml (MJCF" in s002.message
    assert not [f for f in result.findings if f.severity is Severity.ERROR], [f.one_line() for f in result.findings]
    (tmp_path / "alone").mkdir()
    shutil.copy(VENDOR / MESHES[0], tmp_path / "alone" / "base.obj")
    alone = check_asset(AssetTask(tmp_path / "alone" / "base.obj", "base.obj"))
    assert [f.severity for f in alone.findings if f.code == "S002"] == [Severity.ERROR]


def test_a_urdf_consumer_keeps_the_missing_mtl_an_error(tmp_path: Path) -> None:
    """simrun's UrdfRobot imports meshes with meshtool urdf, which reads the MTL: the error stays."""
    pkg = tmp_path / "arm_description"
    (pkg / "meshes").mkdir(parents=True)
    shutil.copy(VENDOR / MESHES[0], pkg / "meshes" / "base.obj")
    (pkg / "package.xml").write_text("<package><name>arm_description</name></package>\n")
    (pkg / "urdf").mkdir()
    (pkg / "urdf" / "arm.urdf").write_text(
        '<robot name="arm"><link name="base"><visual><geometry>'
        '<mesh filename="package://arm_description/meshes/base.obj"/></geometry></visual></link></robot>\n'
    )
    result = check_asset(AssetTask(pkg / "meshes" / "base.obj", "base.obj"))
    assert [f.severity for f in result.findings if f.code == "S002"] == [Severity.ERROR]


def _age(folder: Path) -> None:
    """Set every file's and folder's times an hour back (older than the index's racy window)."""
    past = os.stat(folder).st_mtime - 3600
    for path in sorted(folder.rglob("*"), key=lambda p: -len(p.parts)):
        os.utime(path, (past, past), follow_symlinks=False)
    os.utime(folder, (past, past))


def test_every_description_file_is_read_once_for_every_mesh_of_a_run(tmp_path: Path) -> None:
    vendor, _ = _vendor(tmp_path, "repository")
    for other in ("other.xml", "other2.xml"):  # two models sharing one <include> fragment
        (vendor / "robots" / other).write_text('<mujoco><include file="common.xml"/></mujoco>\n')
    (vendor / "robots" / "common.xml").write_text("<mujocoinclude><asset/></mujocoinclude>\n")
    _age(vendor)
    index = ConsumerIndex()
    for rel in MESHES:
        (ref,) = find_consumers(vendor / rel, None, index)
        assert ref.format == "mjcf" and ref.file.endswith("robots/gripper/robot.xml")
    assert index.parsed == 4  # robot.xml, other.xml, other2.xml, common.xml: once each, for four meshes
    (vendor / "robots" / "gripper" / "robot.xml").write_text(
        (VENDOR / MODEL).read_text().replace('file="base/base.obj"', 'file="base/base.obj" scale="0.001 0.001 0.001"')
    )
    (ref,) = find_consumers(vendor / MESHES[0], None, index)  # a changed file is read again
    assert ref.scale == (0.001, 0.001, 0.001)


def test_the_index_root_is_where_projects_keep_their_models(tmp_path: Path) -> None:
    vendor, _ = _vendor(tmp_path, "repository")
    deep = vendor / "meshes" / "convex" / "base"
    assert find_index_root(deep).folder == vendor.resolve() and find_index_root(deep).kind == "repository"
    site = tmp_path / "venv" / "lib" / "site-packages" / "vendor_models"
    shutil.copytree(VENDOR, site)
    root = find_index_root(site / "meshes" / "base")
    assert (root.folder, root.kind) == (site.resolve(), "python")
    (site / "package.xml").write_text("<package><name>vendor_models</name></package>\n")
    assert find_index_root(site / "meshes" / "base").kind == "ros"
    bare = tmp_path / "bare"
    shutil.copytree(VENDOR, bare)
    root = find_index_root(bare / "meshes" / "base")  # no root: the folder above the mesh's first, as before
    assert (root.folder, root.kind, root.depth) == ((bare / "meshes").resolve(), "nearby", 1)
    (ref,) = find_consumers(bare / MESHES[2], None, ConsumerIndex())  # then up to 3 levels, 3 folders deep
    assert ref.file == "../../../robots/gripper/robot.xml"
    deeper = tmp_path / "far" / "a" / "b" / "c" / "d"
    deeper.mkdir(parents=True)
    shutil.copy(VENDOR / MESHES[0], deeper / "base.obj")
    (tmp_path / "far" / "robot.xml").write_text('<mujoco><asset><mesh file="a/b/c/d/base.obj"/></asset></mujoco>\n')
    assert find_consumers(deeper / "base.obj", None, ConsumerIndex()) == []  # 4 folders up: out of reach
    (tmp_path / "far" / "a" / "robot.xml").write_text('<mujoco><asset><mesh file="b/c/d/base.obj"/></asset></mujoco>\n')
    assert [r.file for r in find_consumers(deeper / "base.obj", None, ConsumerIndex())] == ["../../../robot.xml"]


def test_mjcf_includes_assetdir_and_default_scales_as_mujoco_reads_them(tmp_path: Path) -> None:
    """``<include>`` relative to the main file, ``assetdir``, a default class's scale: MuJoCo compiles it."""
    vendor, _ = _vendor(tmp_path, "repository")
    (vendor / "robots" / "gripper" / "parts").mkdir()
    (vendor / "robots" / "gripper" / "parts" / "assets.xml").write_text(
        '<mujocoinclude><compiler assetdir="../../meshes"/>'
        '<default><default class="mm"><mesh scale="0.5 0.5 0.5"/></default></default>'
        '<asset><mesh name="f" class="mm" file="finger/finger.obj"/></asset></mujocoinclude>\n'
    )
    xml = vendor / "robots" / "gripper" / "scene.xml"
    xml.write_text(
        '<mujoco><include file="parts/assets.xml"/><worldbody><geom type="mesh" mesh="f"/></worldbody></mujoco>\n'
    )
    model = mujoco.MjModel.from_xml_path(str(xml))  # MuJoCo finds the mesh where the index says
    assert model.nmesh == 1
    refs = [r for r in find_consumers(vendor / MESHES[1], None, ConsumerIndex()) if r.file.endswith("scene.xml")]
    assert [(r.format, r.scale) for r in refs] == [("mjcf", (0.5, 0.5, 0.5))]
    asset = prepare(vendor / MESHES[1], NormaliseOptions())
    conflict = [f for f in asset.findings if f.code == "consumer-frames-differ"]
    assert len(conflict) == 1 and conflict[0].severity is Severity.WARNING
    assert "robot.xml uses it Z-up, scale 1 1 1" in conflict[0].message
    assert "scene.xml uses it Z-up, scale 0.5 0.5 0.5" in conflict[0].message
    result = check_asset(AssetTask(vendor / MESHES[1], "finger.obj"))
    assert "S014" in {f.code for f in result.findings}


def test_a_package_reference_names_its_own_package_only(tmp_path: Path) -> None:
    """Two packages in one repository, each with ``meshes/link.obj``: each URDF is the consumer of its own."""
    repo = tmp_path / "repo"
    (repo / ".git").mkdir(parents=True)
    for name, scale in (("left", "0.001"), ("right", "0.01")):
        pkg = repo / name
        (pkg / "meshes").mkdir(parents=True)
        shutil.copy(VENDOR / MESHES[1], pkg / "meshes" / "link.obj")
        (pkg / "urdf").mkdir()
        (pkg / "urdf" / "r.urdf").write_text(
            f'<robot name="{name}"><link name="l"><visual><geometry><mesh filename="package://{name}/meshes/link.obj"'
            f' scale="{scale} {scale} {scale}"/></geometry></visual></link></robot>\n'
        )
    for name, factor in (("left", 0.001), ("right", 0.01)):
        (ref,) = find_consumers(repo / name / "meshes" / "link.obj", None, ConsumerIndex())
        assert (ref.file, ref.scale) == ("../urdf/r.urdf", (factor, factor, factor))
    (repo / "other" / "urdf").mkdir(parents=True)  # an unknown package: its tail matches, but not its folder
    (repo / "other" / "urdf" / "o.urdf").write_text(
        '<robot name="o"><link name="l"><visual><geometry><mesh filename="package://gone/meshes/link.obj"/>'
        "</geometry></visual></link></robot>\n"
    )
    assert len(find_consumers(repo / "left" / "meshes" / "link.obj", None, ConsumerIndex())) == 1
    (repo / "left" / "urdf" / "own.urdf").write_text(  # a renamed package's own file: matched by its tail
        '<robot name="own"><link name="l"><visual><geometry><mesh filename="package://renamed/meshes/link.obj"/>'
        "</geometry></visual></link></robot>\n"
    )
    refs = find_consumers(repo / "left" / "meshes" / "link.obj", None, ConsumerIndex())
    assert sorted(r.file for r in refs) == ["../urdf/own.urdf", "../urdf/r.urdf"]


def test_an_index_stopped_by_a_limit_says_so(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    vendor, _ = _vendor(tmp_path, "repository")
    (vendor / "a_first.xml").write_text("<mujoco/>\n")  # read before robots/gripper/robot.xml
    monkeypatch.setattr(consumer_index, "MAX_FILES", 1)  # the index reads its bounds from its own module
    consumers.INDEX.clear()
    asset = prepare(vendor / MESHES[0], NormaliseOptions())
    (limit,) = [f for f in asset.findings if f.code == "consumer-index-limit"]
    assert "more than 1 description files (MAX_FILES)" in limit.message and limit.severity is Severity.WARNING
    result = check_asset(AssetTask(vendor / MESHES[0], "base.obj"))
    assert "S015" in {f.code for f in result.findings}
    consumers.INDEX.clear()


def test_a_model_root_that_does_not_hold_the_mesh_is_refused(tmp_path: Path) -> None:
    vendor, _ = _vendor(tmp_path, "model-root")
    (tmp_path / "elsewhere").mkdir()
    result = CliRunner().invoke(
        meshtool_main,
        [
            "normalize",
            str(vendor / MESHES[0]),
            "-o",
            str(tmp_path / "out"),
            "--model-root",
            str(tmp_path / "elsewhere"),
        ],
    )
    assert result.exit_code != 0
    assert "does not hold the mesh's folder" in result.output


@pytest.mark.parametrize("beside_main", [True, False], ids=["main-folder", "including-folder"])
def test_nested_includes_resolve_where_mujoco_finds_them(tmp_path: Path, beside_main: bool) -> None:
    """``sub/a.xml`` includes ``b.xml``: MuJoCo takes the main file's folder first, else the including file's."""
    (tmp_path / ".git").mkdir()
    (tmp_path / "sub").mkdir()
    for folder in (tmp_path, tmp_path / "sub"):
        shutil.copy(VENDOR / MESHES[1], folder / "m.obj")
    (tmp_path / "main.xml").write_text(
        '<mujoco><include file="sub/a.xml"/><worldbody><geom type="mesh" mesh="m"/></worldbody></mujoco>\n'
    )
    (tmp_path / "sub" / "a.xml").write_text('<mujocoinclude><include file="b.xml"/></mujocoinclude>\n')
    (tmp_path / "sub" / "b.xml").write_text(
        '<mujocoinclude><asset><mesh name="m" file="m.obj"/></asset></mujocoinclude>\n'
    )
    if beside_main:
        (tmp_path / "b.xml").write_text(
            '<mujocoinclude><asset><mesh name="m" file="sub/m.obj"/></asset></mujocoinclude>\n'
        )
    model = mujoco.MjModel.from_xml_path(str(tmp_path / "main.xml"))
    paths = bytes(model.paths)
    loaded = (tmp_path / paths[: paths.index(b"\0")].decode()).resolve()
    assert loaded == (tmp_path / ("sub/m.obj" if beside_main else "m.obj")).resolve()
    for mesh in (tmp_path / "m.obj", tmp_path / "sub" / "m.obj"):
        users = [r.file for r in find_consumers(mesh, None, ConsumerIndex()) if r.file.endswith("main.xml")]
        assert bool(users) == (mesh.resolve() == loaded), (mesh, users)
