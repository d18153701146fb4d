"""Hostile COLLADA files (issue 27): fan-out, cycles, deep chains, lying counts, bad indices, non-finite numbers.

Every input is generated here, small, one element per line so that the line an error names is known.
Refusals go through the CLI in a child process with a time and memory bound (:mod:`bounded`): exit 1, one
``error: FILE:LINE: ...`` line. Genuine files (a small fan-out, a 1,000-deep chain, a broken
``<instance_material>``) convert, checked against the analytic triangle count and trimesh's own load.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh
from bounded import Outcome, run_bounded

from meshtool.errors import FormatError
from meshtool.read import collada_xml
from meshtool.read.collada import read_collada

NS = 'xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1"'
CUBE_POS = "0 0 0 1 0 0 1 1 0 0 1 0 0 0 1 1 0 1 1 1 1 0 1 1"
CUBE_P = "0 2 1 0 3 2 4 5 6 4 6 7 0 1 5 0 5 4 3 7 6 3 6 2 0 4 7 0 7 3 1 2 6 1 6 5"
MATERIALS = """<library_effects>
<effect id="fx"><profile_COMMON><technique sid="c"><phong>
<diffuse><color>0.1 0.2 0.7 1</color></diffuse>
</phong></technique></profile_COMMON></effect>
</library_effects>
<library_materials>
<material id="blue" name="blue"><instance_effect url="#fx"/></material>
<material id="orphan" name="orphan"><instance_effect url="#no-such-effect"/></material>
</library_materials>"""


def cube(
    *,
    gid: str = "cube",
    pos: str = CUBE_POS,
    pcount: int | str = 24,
    acount: int = 8,
    stride: int = 3,
    prim: str | None = None,
) -> str:
    """A unit cube ``<geometry>``; ``prim`` replaces its ``<triangles>``."""
    triangles = f"""<triangles count="12" material="sym">
<input semantic="VERTEX" source="#{gid}-vtx" offset="0"/>
<p>{CUBE_P}</p>
</triangles>"""
    return f"""<geometry id="{gid}" name="{gid}"><mesh>
<source id="{gid}-pos">
<float_array id="{gid}-arr" count="{pcount}">{pos}</float_array>
<technique_common>
<accessor source="#{gid}-arr" count="{acount}" stride="{stride}">
<param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/>
</accessor>
</technique_common>
</source>
<vertices id="{gid}-vtx"><input semantic="POSITION" source="#{gid}-pos"/></vertices>
{triangles if prim is None else prim}
</mesh></geometry>"""


def document(scene: str, *, library: str = "", geometry: str | None = None, materials: str = "") -> str:
    """A COLLADA 1.4.1 document instancing ``scene`` (``<node>`` elements) of a cube (or ``geometry``)."""
    return f"""<?xml version="1.0" encoding="utf-8"?>
<COLLADA {NS}>
<asset><unit name="meter" meter="1"/><up_axis>Z_UP</up_axis></asset>
{materials}
<library_geometries>
{cube() if geometry is None else geometry}
</library_geometries>
<library_nodes>
{library}
</library_nodes>
<library_visual_scenes>
<visual_scene id="s">
{scene}
</visual_scene>
</library_visual_scenes>
<scene><instance_visual_scene url="#s"/></scene>
</COLLADA>
"""


def fanout(depth: int, width: int = 10) -> str:
    """Node ``n{k}`` instances ``n{k-1}`` ``width`` times; ``n0`` holds the cube: ``width ** depth`` cubes."""
    nodes = ['<node id="n0"><instance_geometry url="#cube"/></node>']
    for k in range(1, depth + 1):
        nodes.append(f'<node id="n{k}">' + f'<instance_node url="#n{k - 1}"/>' * width + "</node>")
    return document(f'<node id="root"><instance_node url="#n{depth}"/></node>', library="\n".join(nodes))


PLAIN = '<node id="root"><instance_geometry url="#cube"/></node>'


def line_of(text: str, needle: str) -> int:
    """1-based line of the first ``needle`` in ``text``."""
    return text[: text.index(needle)].count("\n") + 1


def cli(tmp_path: Path, text: str, env: dict[str, str] | None = None) -> Outcome:
    """``meshtool normalize`` on ``text`` in a child: 30 s and 1,500 MiB at most (else TimeoutExpired/MemoryError)."""
    src = tmp_path / "hostile.dae"
    src.write_text(text)
    return run_bounded(
        ["meshtool", "normalize", str(src), "-o", str(tmp_path / "out")], seconds=30, memory_mb=1500, env=env
    )


def refused(tmp_path: Path, text: str, needle: str, message: str, env: dict[str, str] | None = None) -> str:
    """Run the CLI on ``text``: exit 1, one error line at ``needle``'s line containing ``message``."""
    done = cli(tmp_path, text, env)
    assert done.code == 1, done.err
    assert "Traceback" not in done.err
    errors = [line for line in done.err.splitlines() if line.startswith("error:")]
    assert len(errors) == 1, done.err
    assert f"hostile.dae:{line_of(text, needle)}: " in errors[0], errors[0]
    assert message in errors[0], errors[0]
    return errors[0]


# 1. amplification: <instance_node> fan-out


@pytest.mark.parametrize("depth", [6, 7])  # 2.8 KB (a million cubes) and 3.1 KB (ten million)
def test_instance_node_fanout_is_refused_before_expanding(tmp_path, depth):
    text = fanout(depth)
    assert len(text) < 3300
    line = refused(tmp_path, text, '<node id="root">', "the visual scene expands to more than 100,000 node and")
    assert "with node 'root'" in line and "MESHTOOL_MAX_INSTANCES" in line


def test_deep_fanout_counts_with_big_integers(tmp_path):
    # 10 ** 300 instances: counted per node (memoised, saturating at 2 ** 62), never walked
    refused(tmp_path, fanout(300), '<node id="root">', "instances (at least 4,611,686,018,427,387,904 with")


def test_fanout_under_the_limits_converts_to_the_right_triangle_count(tmp_path):
    text = fanout(1, 4)
    (tmp_path / "four.dae").write_text(text)
    mesh = read_collada(text.encode(), "four.dae")
    assert mesh.face_sizes.size == 4 * 12 == len(trimesh.load(tmp_path / "four.dae", force="mesh").faces)
    assert mesh.record["instances"] == 4
    done = cli(tmp_path, fanout(3))  # a thousand cubes: 12,000 triangles
    assert done.code == 0, done.err
    assert "12000 triangles" in done.out


def test_environment_raises_and_lowers_the_limits(tmp_path):
    text = fanout(3)  # 1,000 cubes: 12,000 triangles, 2,222 node and primitive instances
    refused(tmp_path, text, '<node id="root">', "more than 1,000 node and", {"MESHTOOL_MAX_INSTANCES": "1000"})
    line = refused(
        tmp_path, text, '<node id="root">', "more than 10,000 triangles", {"MESHTOOL_MAX_TRIANGLES": "10000"}
    )
    assert "MESHTOOL_MAX_TRIANGLES" in line
    done = cli(tmp_path, fanout(4), {"MESHTOOL_MAX_INSTANCES": "30000"})  # 22,222 instances
    assert done.code == 0, done.err
    assert "120000 triangles" in done.out


def test_cycle_is_refused_naming_the_node(tmp_path):
    library = '<node id="a">\n<instance_node url="#b"/>\n</node>\n<node id="b">\n<instance_node url="#a"/>\n</node>'
    text = document('<node id="root"><instance_node url="#a"/></node>', library=library)
    line = refused(tmp_path, text, '<instance_node url="#a"/>\n</node>', "instances node 'a'")
    assert "cycle" in line


def test_node_instancing_itself_is_a_cycle(tmp_path):
    text = document('<node id="self">\n<instance_geometry url="#cube"/>\n<instance_node url="#self"/>\n</node>')
    refused(tmp_path, text, '<instance_node url="#self"/>', "instances node 'self'")


def test_thousand_deep_chains_convert_without_recursion():
    chain = [f'<node id="c{k}"><translate>1 0 0</translate><instance_node url="#c{k + 1}"/></node>' for k in range(999)]
    chain.append('<node id="c999"><translate>1 0 0</translate><instance_geometry url="#cube"/></node>')
    text = document('<node id="root"><instance_node url="#c0"/></node>', library="\n".join(chain))
    mesh = read_collada(text.encode(), "chain.dae")
    assert mesh.face_sizes.size == 12
    np.testing.assert_allclose(mesh.positions.min(axis=0), [1000, 0, 0])
    nested = "".join(f'<node id="d{k}"><translate>0 1 0</translate>' for k in range(1000))
    nested += '<instance_geometry url="#cube"/>' + "</node>" * 1000
    mesh = read_collada(document(nested).encode(), "nested.dae")
    np.testing.assert_allclose(mesh.positions.min(axis=0), [0, 1000, 0])


def test_nesting_beyond_libxml2s_limit_is_one_error(tmp_path):
    text = document('<node id="x">' * 2100 + "</node>" * 2100)
    refused(tmp_path, text, '<node id="x">', "nested more than 2,048 deep")


def test_element_limit(monkeypatch):
    monkeypatch.setattr(collada_xml, "MAX_ELEMENTS", 10)
    with pytest.raises(FormatError, match="more than 10 XML elements") as caught:
        read_collada(document(PLAIN).encode(), "many.dae")
    assert caught.value.code == "expansion-limit" and caught.value.line


def test_doctype_in_utf16_is_refused():
    text = document(PLAIN).replace('encoding="utf-8"?>', 'encoding="utf-16"?>\n<!DOCTYPE COLLADA [<!ENTITY e "x">]>')
    with pytest.raises(FormatError, match="DOCTYPE or ENTITY"):
        read_collada(text.encode("utf-16"), "u16.dae")


# 2. silent wrong geometry: indices, counts, strides, non-finite numbers

_BAD_P = {
    "negative": (CUBE_P.replace("0 2 1", "0 -1 1", 1), "index -1 of input VERTEX is negative"),
    "past-end": (
        CUBE_P.replace("0 2 1", "0 99 1", 1),
        "index 99 of input VERTEX is past the end of <source id='cube-pos'> (8 entries)",
    ),
    "not-multiple": (CUBE_P + " 4", "<p> holds 37 index(es), not a multiple of 3"),
    "not-a-number": (CUBE_P.replace("0 2 1", "0 x 1", 1), "holds 'x', which is not a whole number"),
}


@pytest.mark.parametrize("case", sorted(_BAD_P))
def test_bad_triangle_indices(tmp_path, case):
    p, message = _BAD_P[case]
    text = document(PLAIN).replace(f"<p>{CUBE_P}</p>", f"<p>{p}</p>")
    refused(tmp_path, text, "<p>", message)


def test_triangles_count_lying(tmp_path):
    text = document(PLAIN).replace('<triangles count="12"', '<triangles count="1000000"')
    refused(tmp_path, text, "<triangles", 'count="1000000" but <p> holds 12 triangle(s)')


def polylist(vcount: str, p: str, count: int = 2) -> str:
    return f"""<polylist count="{count}">
<input semantic="VERTEX" source="#cube-vtx" offset="0"/>
<vcount>{vcount}</vcount>
<p>{p}</p>
</polylist>"""


@pytest.mark.parametrize(
    ("vcount", "p", "message"),
    [
        ("4 1000000", "0 1 2 3 4 5 6 7", "<vcount> adds up to 1000004 vertices but <p> holds 8"),
        ("4 -4", "0 1 2 3 4 5 6 7", "<vcount> holds a negative count -4"),
    ],
)
def test_polylist_vcount_against_p(tmp_path, vcount, p, message):
    text = document(PLAIN, geometry=cube(prim=polylist(vcount, p)))
    refused(tmp_path, text, "<vcount>", message)


def test_polylist_reads_quads():
    mesh = read_collada(document(PLAIN, geometry=cube(prim=polylist("4 4", "0 3 2 1 4 5 6 7"))).encode(), "q.dae")
    assert mesh.face_sizes.size == 4


@pytest.mark.parametrize(
    ("geometry", "needle", "message"),
    [
        (cube(pcount=30), "<float_array", "<float_array id='cube-arr'> count=\"30\" but it holds 24 number(s)"),
        (cube(pcount="many"), "<float_array", "count='many' is not a whole number"),
        (cube(acount=9), "<accessor", '<accessor> count="9" x stride="3" from offset 0 needs 27 number(s)'),
        (cube(stride=0), "<accessor", '<accessor> stride="0" is not a positive whole number'),
        (cube(stride=-3), "<accessor", '<accessor> stride="-3" is not a positive whole number'),
        (cube(stride=2, acount=12), "<source id=", "<source id='cube-pos'> has 2 value(s) per entry; 3 are needed"),
        (
            cube(pos=CUBE_POS.replace("1 1 1", "1 nan 1")),
            "<triangles",
            "uses position 6 of <source id='cube-pos'>, which is not finite",
        ),
        (cube(pos=CUBE_POS.replace("1 1 1", "1 1e39 1")), "<triangles", "which is not finite"),
        (cube(pos=CUBE_POS.replace("1 1 1", "1 1,5 1")), "<float_array", "holds '1,5', which is not a number"),
    ],
    ids=[
        "float-count",
        "count-text",
        "accessor-count",
        "stride-0",
        "stride-negative",
        "stride-short",
        "nan",
        "inf",
        "bad-float",
    ],
)
def test_damaged_sources(tmp_path, geometry, needle, message):
    refused(tmp_path, document(PLAIN, geometry=geometry), needle, message)


@pytest.mark.parametrize(
    ("transform", "message"),
    [
        ("<matrix>1 0 0 nan 0 1 0 0 0 0 1 0 0 0 0 1</matrix>", "<matrix> holds a non-finite number"),
        ("<translate>1e39 0 0</translate>", "<translate> holds a non-finite number"),
        ("<scale>1 1</scale>", "<scale> holds 2 number(s); it needs 3"),
    ],
)
def test_bad_transforms(tmp_path, transform, message):
    text = document(f'<node id="root">\n{transform}\n<instance_geometry url="#cube"/>\n</node>')
    refused(tmp_path, text, transform[:8], message)


def test_transforms_overflowing_when_composed(tmp_path):
    scene = (
        '<node id="big">\n<scale>1e30 1e30 1e30</scale>\n<node id="bigger">\n<scale>1e30 1e30 1e30</scale>\n'
        '<instance_geometry url="#cube"/>\n</node>\n</node>'
    )
    refused(tmp_path, document(scene), '<node id="bigger">', "node 'bigger' is placed by a non-finite transform")


def test_placed_coordinates_overflowing_float32(tmp_path):
    geometry = cube(pos=CUBE_POS.replace("1 1 1", "1e20 1 1"))
    text = document(
        '<node id="root">\n<scale>1 1 1e20</scale>\n<instance_geometry url="#cube"/>\n</node>', geometry=geometry
    )
    refused(
        tmp_path, text, '<instance_geometry url="#cube"/>', "geometry 'cube' placed here has non-finite coordinates"
    )


def test_cycle_closed_by_an_inline_child(tmp_path):
    # parent contains child inline; child instances parent; the walk may reach child first through the library
    scene = (
        '<node id="root"><instance_node url="#child"/></node>\n'
        '<node id="parent">\n<node id="child">\n<instance_node url="#parent"/>\n</node>\n</node>'
    )
    with pytest.raises(FormatError, match=r"node 'child' .* is placed inside itself: node 'parent' contains it"):
        read_collada(document(scene).encode(), "cycle.dae")


# 3. broken references keep the rest (issue 29: one broken <instance_material> dropped a whole mesh)


@pytest.mark.parametrize(("target", "why"), [("#nowhere", "is not in the file"), ("#orphan", "cannot be read")])
def test_broken_instance_material_keeps_the_geometry(target, why):
    bind = (
        '<bind_material><technique_common><instance_material symbol="sym" target="{}"/>'
        "</technique_common></bind_material>"
    )
    scene = (
        f'<node id="a"><instance_geometry url="#cube">{bind.format(target)}</instance_geometry></node>\n'
        f'<node id="b"><translate>3 0 0</translate><instance_geometry url="#cube">{bind.format("#blue")}'
        "</instance_geometry></node>"
    )
    text = document(scene, materials=MATERIALS)
    mesh = read_collada(text.encode(), "foot.dae")
    assert mesh.face_sizes.size == 24
    missing = [f for f in mesh.findings if f.code == "collada-material-missing"]
    assert len(missing) == 1 and why in missing[0].message
    where = line_of(text, '<node id="a">')
    assert f"line {where}" in missing[0].message
    assert target[1:] in missing[0].message
    assert "blue" in [m.name for m in mesh.materials]


def test_missing_instance_targets_are_skipped_with_a_warning():
    scene = (
        '<node id="root"><instance_geometry url="#cube"/><instance_geometry url="#gone"/>'
        '<instance_node url="#nobody"/></node>'
    )
    mesh = read_collada(document(scene).encode(), "refs.dae")
    assert mesh.face_sizes.size == 12
    messages = [f.message for f in mesh.findings if f.code == "collada-instance-missing"]
    assert len(messages) == 2 and "'#gone'" in messages[0] and "'#nobody'" in messages[1]


def test_unreadable_effect_keeps_the_geometry_without_materials():
    bind = '<instance_material symbol="sym" target="#blue"/>'
    scene = (
        '<node id="a"><instance_geometry url="#cube"><bind_material><technique_common>'
        f"{bind}</technique_common></bind_material></instance_geometry></node>"
    )
    mesh = read_collada(document(scene, materials=MATERIALS.replace("0.1 0.2 0.7 1", "0.1 0.2 x 1")).encode(), "e.dae")
    assert mesh.face_sizes.size == 12
    unreadable = [f.message for f in mesh.findings if f.code == "collada-materials-unreadable"]
    assert len(unreadable) == 1 and "Corrupted color" in unreadable[0]
