"""meshtool.files.mjcf_xml: the one MJCF reading (includes, asset folders, confinement) simrun and meshtool share.

Ground truth is MuJoCo's own load from the files (``mujoco.MjModel.from_xml_path``): a decoy that is no mesh lies
where a wrong rule would look, so MuJoCo compiling proves which file it read. Both users of the module must
then name that file: the consumer index (``meshtool.frame.consumer_index``) and simrun's model reader.
"""

from __future__ import annotations

import os
from pathlib import Path

import mujoco
import pytest

from meshtool.files.mjcf_xml import (
    MjcfReadError,
    XmlNode,
    find_include,
    parse_xml,
    refuse_declarations,
    root_holding,
    splice_includes,
    tagged,
    to_nodes,
)
from meshtool.frame.consumer_index import ConsumerIndex, IndexRoot
from simrun.robots.mjcf_read import read_mjcf

TETRA = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
GEOM = '<worldbody><geom type="mesh" mesh="m"/></worldbody>'


def _write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def _agree(model: Path, mesh: Path, decoy: Path, root: Path) -> None:
    """MuJoCo, the consumer index and simrun's reader all take ``mesh`` (not ``decoy``) for the model's mesh."""
    loaded = mujoco.MjModel.from_xml_path(str(model))  # the decoy is no mesh: MuJoCo would refuse it
    assert loaded.nmeshvert == 4
    index = ConsumerIndex()
    iroot = IndexRoot(Path(os.path.realpath(root)), "explicit", "--model-root")
    uses, _ = index.lookup(mesh, iroot)
    assert [u.file for u in uses] == [model]
    assert index.lookup(decoy, iroot)[0] == []
    read = read_mjcf(model, [root])
    assert [f.real for f in read.read if f.kind == "mesh"] == [Path(os.path.realpath(mesh))]


def test_a_later_assetdir_overrides_an_earlier_meshdir(tmp_path: Path) -> None:
    """Per <compiler> element: assetdir sets the mesh folder, then meshdir (the consumer index read meshdir first)."""
    mesh = _write(tmp_path / "b" / "m.obj", TETRA)
    decoy = _write(tmp_path / "a" / "m.obj", "not a mesh\n")
    model = _write(
        tmp_path / "rule.xml",
        f'<mujoco><compiler meshdir="a"/><compiler assetdir="b"/><asset><mesh name="m" file="m.obj"/></asset>{GEOM}'
        "</mujoco>",
    )
    _agree(model, mesh, decoy, tmp_path)


def test_strippath_keeps_the_file_name(tmp_path: Path) -> None:
    mesh = _write(tmp_path / "meshes" / "m.obj", TETRA)
    decoy = _write(tmp_path / "meshes" / "x" / "y" / "m.obj", "not a mesh\n")
    model = _write(
        tmp_path / "strip.xml",
        '<mujoco><compiler meshdir="meshes" strippath="true"/><asset><mesh name="m" file="x/y/m.obj"/></asset>'
        f"{GEOM}</mujoco>",
    )
    _agree(model, mesh, decoy, tmp_path)


def test_an_included_assets_file_is_read_beside_the_include(tmp_path: Path) -> None:
    """Not under the model's folder: MuJoCo reads the mesh beside the included file that names it."""
    mesh = _write(tmp_path / "parts" / "p.obj", TETRA)
    _write(
        tmp_path / "parts" / "assets.xml", '<mujocoinclude><asset><mesh name="m" file="p.obj"/></asset></mujocoinclude>'
    )
    model = _write(tmp_path / "main.xml", f'<mujoco><include file="parts/assets.xml"/>{GEOM}</mujoco>')
    _agree(model, mesh, tmp_path / "p.obj", tmp_path)


def test_a_file_beside_the_model_wins_over_one_beside_the_include(tmp_path: Path) -> None:
    mesh = _write(tmp_path / "p.obj", TETRA)
    decoy = _write(tmp_path / "parts" / "p.obj", "not a mesh\n")
    _write(
        tmp_path / "parts" / "assets.xml", '<mujocoinclude><asset><mesh name="m" file="p.obj"/></asset></mujocoinclude>'
    )
    model = _write(tmp_path / "main.xml", f'<mujoco><include file="parts/assets.xml"/>{GEOM}</mujoco>')
    _agree(model, mesh, decoy, tmp_path)


def test_includes_are_spliced_in_mujocos_order(tmp_path: Path) -> None:
    """Nested includes (one found only beside its including file) come in where they stand: MuJoCo's geom order."""
    _write(tmp_path / "parts" / "inner.xml", '<i><geom name="g2" size="0.1"/><geom name="g3" size="0.1"/></i>')
    _write(
        tmp_path / "parts" / "outer.xml",
        '<i><geom name="g1" size="0.1"/><include file="inner.xml"/><geom name="g4" size="0.1"/></i>',
    )
    model = _write(
        tmp_path / "order.xml",
        '<mujoco><worldbody><geom name="g0" size="0.1"/><include file="parts/outer.xml"/>'
        '<geom name="g5" size="0.1"/></worldbody></mujoco>',
    )
    loaded = mujoco.MjModel.from_xml_path(str(model))
    expected = [loaded.geom(i).name for i in range(loaded.ngeom)]
    assert expected == [f"g{i}" for i in range(6)]

    root = to_nodes(parse_xml(model.read_bytes(), str(model)), 0, None, str(model))

    def include(node: XmlNode, depth: int) -> list[XmlNode] | None:
        found = find_include(tmp_path, node.include_dir or tmp_path, node.attrib["file"])
        assert found is not None
        return to_nodes(parse_xml(found.read_bytes(), str(found)), 1, found.parent, str(found)).children

    splice_includes(root, include)
    assert [n.attrib["name"] for n in tagged(root, "geom")] == expected
    assert not list(tagged(root, "include"))


def test_declarations_and_namespaces_are_refused(tmp_path: Path) -> None:
    with pytest.raises(MjcfReadError, match="DOCTYPE or ENTITY"):
        refuse_declarations(b'<!DOCTYPE m [<!ENTITY e "x">]><mujoco>&e;</mujoco>', "m.xml")
    utf16 = "<!DOCTYPE mujoco><mujoco/>".encode("utf-16")
    refuse_declarations(utf16, "m.xml")  # the bytes hide it ...
    with pytest.raises(MjcfReadError, match="DOCTYPE or ENTITY"):
        parse_xml(utf16, "m.xml")  # ... the parsed document does not
    with pytest.raises(MjcfReadError, match="namespaces"):
        to_nodes(parse_xml(b'<mujoco xmlns:x="u"><x:body/></mujoco>', "m.xml"), 0, None, "m.xml")
    with pytest.raises(MjcfReadError, match="not well-formed") as caught:
        parse_xml(b"<mujoco>\n<body>\n</mujoco", "m.xml")
    assert caught.value.path == "m.xml"


def test_root_holding_follows_links(tmp_path: Path) -> None:
    inside = tmp_path / "root"
    outside = _write(tmp_path / "elsewhere" / "m.obj", TETRA)
    inside.mkdir()
    (inside / "link.obj").symlink_to(outside)
    roots = [Path(os.path.realpath(inside))]
    assert root_holding(Path(os.path.realpath(inside / "link.obj")), roots) is None
    assert root_holding(Path(os.path.realpath(inside)) / "m.obj", roots) == roots[0]
