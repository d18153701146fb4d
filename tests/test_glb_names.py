"""GLB export: each material of the pack keeps its own glTF material, even when two share a name."""

import json
import struct
from pathlib import Path

from click.testing import CliRunner
from PIL import Image

from meshtool.cli.main import obj2bin
from meshtool.packfile import load
from meshtool.packfile.export import to_glb


def _gltf(glb: bytes) -> dict:
    """The JSON chunk of a GLB (glTF 2.0 binary: 12-byte header, then chunk length, type, data)."""
    length, kind = struct.unpack_from("<II", glb, 12)
    assert kind == 0x4E4F534A  # "JSON"
    return json.loads(glb[20 : 20 + length])


def _two_normal_mapped_parts(tmp_path: Path) -> Path:
    """Two tetrahedra, materials ``p`` (``-bm 0.5``, red) and ``q`` (``-bm 0.25``, green), one normal map."""
    Image.new("RGB", (4, 4), (128, 128, 255)).save(tmp_path / "n.png")
    verts = ["v 0 0 0", "v 1 0 0", "v 0 1 0", "v 0 0 1", "v 2 0 0", "v 3 0 0", "v 2 1 0", "v 2 0 1"]
    uvs = ["vt 0 0", "vt 1 0", "vt 0 1", "vt 1 1"] * 2
    tris = [(1, 2, 3), (1, 2, 4), (1, 3, 4), (2, 3, 4)]
    lines = ["mtllib m.mtl", *verts, *uvs, "usemtl p"]
    lines += ["f " + " ".join(f"{i}/{i}" for i in t) for t in tris]
    lines += ["usemtl q"] + ["f " + " ".join(f"{i + 4}/{i + 4}" for i in t) for t in tris]
    (tmp_path / "m.obj").write_text("\n".join(lines) + "\n")
    mtl = "newmtl p\nKd 1 0 0\nmap_Bump -bm 0.5 n.png\nnewmtl q\nKd 0 1 0\nmap_Bump -bm 0.25 n.png\n"
    (tmp_path / "m.mtl").write_text(mtl)
    out = tmp_path / "m.mbin"
    result = CliRunner().invoke(obj2bin, [str(tmp_path / "m.obj"), "-o", str(out), "--no-check"])
    assert result.exit_code == 0, result.output
    return out


def test_materials_with_one_name_keep_their_own_colour_and_normal_strength(tmp_path):
    with load(_two_normal_mapped_parts(tmp_path)) as packed:
        assert [m["name"] for m in packed.materials] == ["p", "q"]
        packed.materials[1]["name"] = "p"  # a pack written by another tool: two materials, one name
        tree = _gltf(to_glb(packed))
    materials = tree["materials"]
    assert [m["name"] for m in materials] == ["p", "p_2"]
    by_x = {}
    for mesh in tree["meshes"]:
        (primitive,) = mesh["primitives"]
        position = tree["accessors"][primitive["attributes"]["POSITION"]]
        entry = materials[primitive["material"]]
        by_x[position["min"][0]] = (entry["pbrMetallicRoughness"]["baseColorFactor"], entry["normalTexture"]["scale"])
    # the MTL's own numbers: p is red at -bm 0.5, q green at -bm 0.25
    assert by_x == {0.0: ([1.0, 0.0, 0.0, 1.0], 0.5), 2.0: ([0.0, 1.0, 0.0, 1.0], 0.25)}
