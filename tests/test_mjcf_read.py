"""The one MJCF reader (simrun/robots/mjcf_read.py): it finds the files MuJoCo would read, and only those.

Ground truth is MuJoCo's own load of the same files by path (``MjModel.from_xml_path``): the model the reader
hands MuJoCo as bytes must compile to the same arrays (meshes' vertices, textures' pixels, masses, options).
Each layout below makes MuJoCo choose between candidate files that differ, so reading the wrong one shows.
"""

from __future__ import annotations

import shutil
import struct
import zlib
from pathlib import Path

import mujoco
import numpy as np
import pytest

from simrun.errors import EntityError
from simrun.robots.mjcf_limits import Limits
from simrun.robots.mjcf_read import MjcfReadError, read_mjcf
from simrun.robots.mjcf_robot import MjcfRobot
from simrun.world.world import World

ROOT = Path(__file__).resolve().parent.parent
INCLUDED = ROOT / "fixtures" / "mjcf" / "included"


def _write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")
    return path


def _mesh(path: Path, size: float) -> None:
    """A tetrahedron OBJ of edge ``size`` (each candidate file gets its own size, so MuJoCo's choice shows)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(f"v 0 0 0\nv {size} 0 0\nv 0 {size} 0\nv 0 0 {size}\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")


def _png(path: Path, grey: int, width: int = 2, height: int = 2) -> None:
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    rows = b"".join(b"\x00" + bytes([grey, grey, grey]) * width for _ in range(height))
    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    body = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b"")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(body)


def _same_as_mujoco(path: Path) -> mujoco.MjModel:
    """The reader's model compiled, checked against MuJoCo's own load of ``path``."""
    reference = mujoco.MjModel.from_xml_path(str(path))
    mine = read_mjcf(path).spec().compile()
    for name in ("mesh_vert", "mesh_face", "tex_data", "hfield_data", "body_mass", "geom_size", "geom_rgba"):
        assert np.array_equal(getattr(mine, name), getattr(reference, name)), name
    assert (mine.nmesh, mine.ntex, mine.nhfield, mine.opt.timestep) == (
        reference.nmesh,
        reference.ntex,
        reference.nhfield,
        reference.opt.timestep,
    )
    return mine


def test_assets_of_included_files_are_found_as_mujoco_finds_them(tmp_path: Path) -> None:
    """Under meshdir when there, else beside the included file (not beside it under meshdir): MuJoCo's rule."""
    _write(
        tmp_path / "main.xml",
        '<mujoco><compiler meshdir="m" texturedir="t"/><include file="a/x.xml"/><worldbody>'
        '<geom type="mesh" mesh="p1"/><geom type="mesh" mesh="p2"/><geom type="mesh" mesh="p3" material="mat"/>'
        "</worldbody></mujoco>",
    )
    _write(
        tmp_path / "a" / "x.xml",
        '<mujoco><include file="b/y.xml"/><asset><mesh name="p1" file="p.obj"/></asset></mujoco>',
    )
    _write(
        tmp_path / "a" / "b" / "y.xml",
        '<mujoco><asset><mesh name="p2" file="q.obj"/><mesh name="p3" file="r.obj"/>'
        '<texture name="tx" type="2d" file="g.png"/><material name="mat" texture="tx"/></asset></mujoco>',
    )
    _mesh(tmp_path / "m" / "p.obj", 1.0)  # p1: under meshdir
    _mesh(tmp_path / "a" / "p.obj", 2.0)  # ...not beside its include
    _mesh(tmp_path / "a" / "b" / "q.obj", 3.0)  # p2: not under meshdir, so beside its include
    _mesh(tmp_path / "a" / "b" / "m" / "q.obj", 4.0)  # ...never meshdir beside the include
    _mesh(tmp_path / "m" / "r.obj", 5.0)
    _png(tmp_path / "a" / "b" / "g.png", 40)  # the texture: beside its include
    _same_as_mujoco(tmp_path / "main.xml")
    read = read_mjcf(tmp_path / "main.xml").read
    kinds = {(f.kind, f.real.relative_to(tmp_path).as_posix()) for f in read}
    assert ("mesh", "m/p.obj") in kinds and ("mesh", "a/b/q.obj") in kinds and ("texture", "a/b/g.png") in kinds
    assert [f.kind for f in read[:3]] == ["model", "include", "include"]


def test_compiler_folders_strippath_and_unnamed_assets(tmp_path: Path) -> None:
    """assetdir then meshdir per <compiler>, the last one winning; strippath; names MuJoCo gives unnamed assets."""
    _write(
        tmp_path / "main.xml",
        '<mujoco><compiler meshdir="first"/><compiler assetdir="A" texturedir="T"/><compiler strippath="true"/>'
        '<asset><mesh file="deep/er/cube.obj"/><texture type="2d" file="x/skin.png"/><material name="mat" '
        'texture="skin"/><hfield file="x/hill.png" size="1 1 0.1 0.1"/></asset><worldbody><geom type="mesh" '
        'mesh="cube" material="mat"/><geom type="hfield" hfield="hill"/></worldbody></mujoco>',
    )
    _mesh(tmp_path / "A" / "cube.obj", 1.5)
    _mesh(tmp_path / "first" / "cube.obj", 2.5)
    _mesh(tmp_path / "A" / "deep" / "er" / "cube.obj", 3.5)
    _png(tmp_path / "T" / "skin.png", 70)
    _png(tmp_path / "A" / "skin.png", 90)
    _png(tmp_path / "A" / "hill.png", 110)
    model = _same_as_mujoco(tmp_path / "main.xml")
    assert model.mesh("cube").id == 0 and model.texture("skin").id == 0 and model.hfield("hill").id == 0


def test_an_included_files_error_names_that_file_and_line(tmp_path: Path) -> None:
    shutil.copytree(INCLUDED, tmp_path / "arm")
    link = tmp_path / "arm" / "parts" / "link.xml"
    link.write_text(link.read_text().replace("<joint ", "<joint bogus='1' "), encoding="utf-8")
    world = World(base_dir=tmp_path / "arm")
    world.insert(MjcfRobot(name="arm", file="robot.xml"))
    with pytest.raises(EntityError, match=r"parts/link\.xml:3: <joint>: .*unrecognized attribute") as info:
        world.compile()
    assert "\n" not in str(info.value)


def test_counts_are_mujocos(tmp_path: Path) -> None:
    model = read_mjcf(INCLUDED / "robot.xml")
    compiled = mujoco.MjModel.from_xml_path(str(INCLUDED / "robot.xml"))
    counts = model.counts
    assert (counts["bodies"], counts["geoms"], counts["meshes"], counts["keyframes"]) == (
        compiled.nbody - 1,
        compiled.ngeom,
        compiled.nmesh,
        compiled.nkey,
    )
    assert counts["includes"] == 3 and model.sources() == {Path(f.real) for f in model.read}
    _write(
        tmp_path / "r.xml",
        "<mujoco><worldbody><replicate count='4' offset='1 0 0'><replicate count='3' offset='0 1 0'>"
        "<body><geom size='.1'/><geom size='.05' pos='0 0 .1'/></body></replicate></replicate></worldbody></mujoco>",
    )
    compiled = mujoco.MjModel.from_xml_path(str(tmp_path / "r.xml"))
    counts = read_mjcf(tmp_path / "r.xml").counts
    assert (counts["bodies"], counts["geoms"]) == (compiled.nbody - 1, compiled.ngeom) == (12, 24)


def test_names_that_read_as_numbers_are_not_numbers(tmp_path: Path) -> None:
    """A joint called ``inf`` and a body called ``nan`` load (only numeric attributes are checked)."""
    _write(
        tmp_path / "m.xml",
        "<mujoco><asset><material name='Inf'/></asset><worldbody><body name='nan'><joint name='inf'/>"
        "<geom size='.1' material='Inf'/></body></worldbody><actuator><motor joint='inf' name='NaN'/></actuator>"
        "<custom><text name='t' data='nan inf'/></custom></mujoco>",
    )
    model = read_mjcf(tmp_path / "m.xml").spec().compile()
    assert model.joint("inf").id == 0 and model.body("nan").id == 1


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("<mujoco><asset><model name='x' file='other.xml'/></asset></mujoco>", "<model>: a <model> asset"),
        ("<mujoco><worldbody><geom file='x.obj' size='1'/></worldbody></mujoco>", "<geom>: attribute 'file' names"),
        ("<mujoco><INCLUDE file='x.xml'/></mujoco>", "<INCLUDE>: MuJoCo reads an include"),
        ('<!DOCTYPE m [<!ENTITY e SYSTEM "/etc/passwd">]><mujoco>&e;</mujoco>', "DOCTYPE or ENTITY"),
        ("<mujoco xmlns:a='urn:x'><a:body/></mujoco>", "XML namespaces are not MJCF"),
        ("<mujoco><include file='m.xml'/></mujoco>", "already included"),
        ("<mujoco><include file='nothere.xml'/></mujoco>", "nothere.xml does not exist"),
        ("<mujoco><include file='e.xml'/></mujoco>", "holds no element inside its root"),
        ("<mujoco><include file='e.xml'><body/></include></mujoco>", "cannot have children"),
        ("<mujoco><size nuser_geom='100000'/></mujoco>", "nuser_geom = 100,000, more than the limit of 1,000"),
        ("<mujoco><worldbody><body></worldbody></mujoco>", "<body>: XML_ERROR_MISMATCHED_ELEMENT"),
    ],
)
def test_refusals_are_one_line_naming_the_element(tmp_path: Path, text: str, expected: str) -> None:
    _write(tmp_path / "e.xml", "<mujoco/>")
    _write(tmp_path / "m.xml", text)
    with pytest.raises(MjcfReadError) as info:
        read_mjcf(tmp_path / "m.xml")
    message = str(info.value)
    assert "\n" not in message and message.startswith(str(tmp_path / "m.xml")), message
    assert expected in message, message


def test_file_sizes_and_images_are_bounded_before_reading(tmp_path: Path) -> None:
    """The count and the limit are named: a mesh over its size, all assets over the total, a PNG bomb."""
    _mesh(tmp_path / "a.obj", 1.0)
    _mesh(tmp_path / "b.obj", 2.0)
    size = (tmp_path / "a.obj").stat().st_size
    _write(
        tmp_path / "m.xml",
        "<mujoco><asset><mesh file='a.obj'/><mesh file='b.obj'/></asset><worldbody/></mujoco>",
    )
    small = Limits(asset_bytes=(("mesh", size - 1),))
    with pytest.raises(MjcfReadError, match=rf"mesh 'a': cannot read .*a\.obj: is {size} bytes, over the {size - 1}"):
        read_mjcf(tmp_path / "m.xml", limits=small)
    with pytest.raises(MjcfReadError, match=rf"mesh 'b': the model's asset files hold {2 * size:,} bytes, more than"):
        read_mjcf(tmp_path / "m.xml", limits=Limits(total_asset_bytes=size + 1))
    _png(tmp_path / "bomb.png", 0, width=1, height=1)
    data = bytearray((tmp_path / "bomb.png").read_bytes())
    data[16:24] = struct.pack(">II", 100_000, 100_000)  # the header claims 10^10 pixels
    (tmp_path / "bomb.png").write_bytes(bytes(data))
    _write(tmp_path / "t.xml", "<mujoco><asset><texture name='t' type='2d' file='bomb.png'/></asset></mujoco>")
    with pytest.raises(MjcfReadError, match=r"texture 't': .*100000 x 100000 PNG image, more than the limit of"):
        read_mjcf(tmp_path / "t.xml")


@pytest.mark.parametrize(
    ("element", "pixels"),
    [
        ("<hfield name='x' nrow='10' ncol='7' size='1 1 .1 .1'/>", 70),  # nrow x ncol height samples
        ("<texture name='x' type='2d' builtin='checker' width='10' height='7'/>", 70),  # width x height
        ("<texture name='x' type='cube' builtin='checker' width='10' height='1'/>", 600),  # 6 faces of width²
        ("<texture name='x' type='skybox' builtin='flat' width='10'/>", 600),
    ],
)
def test_what_an_element_asks_mujoco_to_allocate_is_bounded(tmp_path: Path, element: str, pixels: int) -> None:
    """Height-field rows x columns and a file-less texture's size are pixels under the image limit, counted as
    MuJoCo allocates them (its own load is the ground truth); at the limit it loads, one under it is refused.

    Found by ``make fuzz`` (target ``mjcf``): an hfield of 65536 x 65536 killed the process (segmentation fault),
    100000 x 100000 raised ``RuntimeError: Caught an unknown exception!`` out of ``MjSpec.from_string``.
    """
    use = "<geom type='hfield' hfield='x'/>" if "hfield" in element else "<geom size='.1'/>"
    path = _write(tmp_path / "m.xml", f"<mujoco><asset>{element}</asset><worldbody>{use}</worldbody></mujoco>")
    reference = mujoco.MjModel.from_xml_path(str(path))
    if reference.nhfield:
        assert int(reference.hfield_nrow[0] * reference.hfield_ncol[0]) == pixels
    else:
        assert int(reference.tex_width[0] * reference.tex_height[0]) == pixels
    assert read_mjcf(path, limits=Limits(image_pixels=pixels)).spec().compile().ntexdata == reference.ntexdata
    with pytest.raises(MjcfReadError) as info:
        read_mjcf(path, limits=Limits(image_pixels=pixels - 1))
    message = str(info.value)
    assert "\n" not in message and message.startswith(f"{path}:1: <"), message
    assert " 'x': " in message and f"{pixels:,} pixels, more than the limit of {pixels - 1:,}" in message, message


def test_a_texture_files_size_is_its_own(tmp_path: Path) -> None:
    """A texture read from a file: its ``width``/``height`` attributes ask for nothing (the PNG's header counts)."""
    _png(tmp_path / "t.png", 9)
    textured = "<texture name='x' type='2d' file='t.png' width='100000' height='100000'/>"
    _write(tmp_path / "f.xml", f"<mujoco><asset>{textured}</asset><worldbody/></mujoco>")
    assert read_mjcf(tmp_path / "f.xml", limits=Limits(image_pixels=4)).spec().compile().tex_width[0] == 2


_TETRA = "vertex='0 0 0 1 0 0 0 1 0 0 0 1'"


@pytest.mark.parametrize(
    ("limits", "main", "included", "expected"),
    [
        (  # <mesh> assets: counted while the file streams, before any tree is kept
            Limits(meshes=3),
            "<mujoco><asset>" + "".join(f"<mesh name='m{k}' {_TETRA}/>" for k in range(4)) + "</asset></mujoco>",
            "",
            "<mesh>: 4 meshes (<mesh>), more than the limit of 3 (docs/limits.md)",
        ),
        (  # meshes of an included file add to the model's
            Limits(meshes=3),
            f"<mujoco><asset><mesh name='a' {_TETRA}/><mesh name='b' {_TETRA}/></asset>"
            "<include file='i.xml'/></mujoco>",
            f"<mujoco><asset><mesh name='c' {_TETRA}/><mesh name='d' {_TETRA}/></asset></mujoco>",
            "i.xml:1: <mesh>: 4 meshes (<mesh>), more than the limit of 3",
        ),
        (  # the model file's own size
            Limits(xml_bytes=100),
            "<mujoco>" + " " * 200 + "</mujoco>",
            "",
            "cannot read the MJCF file: is 217 bytes, over the 100",
        ),
        (  # an included file's size
            Limits(xml_bytes=100),
            "<mujoco><include file='i.xml'/></mujoco>",
            "<mujoco>" + " " * 200 + "<worldbody/></mujoco>",
            "<include file='i.xml'>: cannot read",
        ),
        (  # all XML files together
            Limits(total_xml_bytes=100),
            "<mujoco><include file='i.xml'/>" + " " * 40 + "</mujoco>",
            "<mujoco>" + " " * 40 + "<worldbody/></mujoco>",
            "the model's XML files hold 149 bytes, more than the limit of 100 (docs/limits.md)",
        ),
        (  # included files followed
            Limits(includes=1),
            "<mujoco><include file='i.xml'/><include file='j.xml'/></mujoco>",
            "<mujoco><worldbody/></mujoco>",
            "<include file='j.xml'>: more than 1 included files (the limit; docs/limits.md)",
        ),
        (  # XML elements of the model
            Limits(elements=5),
            "<mujoco><worldbody>" + "<site/>" * 5 + "</worldbody></mujoco>",
            "",
            "more than 5 XML elements in the model (the limit; docs/limits.md)",
        ),
    ],
    ids=["meshes", "meshes_included", "model_bytes", "include_bytes", "total_xml_bytes", "includes", "elements"],
)
def test_counts_and_sizes_over_the_limits_name_both(
    tmp_path: Path, limits: Limits, main: str, included: str, expected: str
) -> None:
    """Issue 42 item 2: each bound of :class:`Limits` refuses with one line naming the count and the limit; the
    same model loads under the default limits (MuJoCo compiles it)."""
    _write(tmp_path / "m.xml", main)
    _write(tmp_path / "i.xml", included or "<mujoco/>")
    _write(tmp_path / "j.xml", "<mujoco><worldbody/></mujoco>")
    with pytest.raises(MjcfReadError) as info:
        read_mjcf(tmp_path / "m.xml", limits=limits)
    message = str(info.value)
    assert "\n" not in message and message.startswith(str(tmp_path)) and expected in message, message
    read_mjcf(tmp_path / "m.xml").spec().compile()


def test_options_only_read_reads_no_asset(tmp_path: Path) -> None:
    shutil.copytree(INCLUDED, tmp_path / "arm")
    model = read_mjcf(tmp_path / "arm" / "robot.xml", assets=False)
    assert model.files and all(data == b"" for data in model.files.values())
    assert model.spec().option.timestep == mujoco.MjModel.from_xml_path(str(INCLUDED / "robot.xml")).opt.timestep


def test_a_flexcomp_file_is_read_by_the_reader(tmp_path: Path) -> None:
    """MuJoCo reads a flexcomp's mesh while parsing: it gets the bytes then too."""
    _mesh(tmp_path / "m" / "tet.obj", 0.3)
    _write(
        tmp_path / "f.xml",
        '<mujoco><compiler meshdir="m"/><worldbody><flexcomp name="f" type="mesh" file="tet.obj" dim="2" '
        'radius="0.01"><edge equality="true"/></flexcomp></worldbody></mujoco>',
    )
    reference = mujoco.MjModel.from_xml_path(str(tmp_path / "f.xml"))
    model = read_mjcf(tmp_path / "f.xml")
    assert [f.kind for f in model.read] == ["model", "flexcomp"]
    compiled = model.spec().compile()
    assert compiled.nflex == reference.nflex == 1
    assert np.array_equal(compiled.flex_vert, reference.flex_vert) and compiled.nbody == reference.nbody
