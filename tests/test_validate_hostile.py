"""``meshtool validate`` on the hostile files of issue 27: the reader's own error (S001), never X001 (internal).

One small generated file per reader and kind of break; each is validated in a child with a time and memory
bound, and the JSON report names the file, the location and the reader's message.
"""

from __future__ import annotations

import json
import struct
from pathlib import Path

import pytest
from bounded import run_bounded

_PLY_HEAD = (
    "ply\nformat {fmt} 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
    "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
)
_TRIANGLE = struct.pack("<9f", 0, 0, 0, 1, 0, 0, 0, 1, 0)


def _gltf(doc: dict[str, object]) -> bytes:
    return json.dumps({"asset": {"version": "2.0"}, **doc}).encode()


_ZERO_FILLED = _gltf(
    {
        "accessors": [{"count": 16_777_215, "componentType": 5126, "type": "VEC3"}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "nodes": [{"mesh": 0}],
        "scenes": [{"nodes": [0]}],
    }
)
_COLLADA_NEGATIVE = b"""<?xml version="1.0"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
<library_geometries><geometry id="g"><mesh>
<source id="p"><float_array id="pa" count="9">0 0 0 1 0 0 0 1 0</float_array>
<technique_common><accessor source="#pa" count="3" stride="3">
<param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/></accessor>
</technique_common></source>
<vertices id="v"><input semantic="POSITION" source="#p"/></vertices>
<triangles count="1"><input semantic="VERTEX" source="#v" offset="0"/><p>0 1 -1</p></triangles>
</mesh></geometry></library_geometries>
<library_visual_scenes><visual_scene id="s"><node id="n"><instance_geometry url="#g"/></node></visual_scene>
</library_visual_scenes><scene><instance_visual_scene url="#s"/></scene>
</COLLADA>
"""

CASES = {
    "ply-index-out-of-range.ply": (_PLY_HEAD.format(fmt="ascii") + "0 0 0\n1 0 0\n0 1 0\n3 0 1 9\n").encode(),
    "ply-truncated.ply": (_PLY_HEAD.format(fmt="binary_little_endian")).encode() + _TRIANGLE[:20],
    "ply-wrong-byte-order.ply": _PLY_HEAD.format(fmt="binary_big_endian").encode()
    + _TRIANGLE
    + struct.pack("<B3i", 3, 0, 1, 2),
    "stl-underscore.stl": b"solid s\nfacet normal 0 0 1\nouter loop\nvertex 1_0 0 0\nvertex 1 0 0\n"
    b"vertex 0 1 0\nendloop\nendfacet\nendsolid s\n",
    "gltf-zero-filled.gltf": _ZERO_FILLED,
    "collada-negative-index.dae": _COLLADA_NEGATIVE,
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_validate_reports_the_readers_error_not_an_internal_one(tmp_path: Path, name: str) -> None:
    path = tmp_path / name
    path.write_bytes(CASES[name])
    out = run_bounded(["meshtool", "validate", str(path), "--format", "json", "-j", "1"], seconds=90)
    assert out.code == 1, out.err
    report = json.loads(out.out)
    (asset,) = report["assets"]
    rules = [f["rule"] for f in asset["findings"]]
    assert rules == ["S001"], asset["findings"]
    (finding,) = asset["findings"]
    assert finding["file"] == str(path) and "Traceback" not in out.err
    assert finding["line"] is not None or "byte" in finding["message"] or "accessor" in finding["message"]
