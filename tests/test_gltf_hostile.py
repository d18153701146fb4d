"""Hostile glTF/GLB (issue 27): every malformed or amplifying input is one error line naming the file and
where (accessor, bufferView, node, byte), refused quickly and small; a short attribute is dropped with a
warning; genuine files still convert (and agree with trimesh).

Inputs are generated here (JSON with base64 data URIs, or GLB bytes); the CLI runs in a child bounded in time
and memory (``tests/bounded.py``).
"""

from __future__ import annotations

import base64
import json
import struct
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bounded import Outcome, run_bounded

from meshtool.errors import FormatError
from meshtool.files.resolve import Resolver
from meshtool.read.gltf import read_gltf

FIXTURES = Path(__file__).resolve().parent.parent / "fixtures"
#: A tetrahedron: 4 float VEC3 positions (48 bytes), then 12 unsigned short indices (24 bytes): 72 bytes.
POSITIONS = struct.pack("<12f", 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1)
INDICES = (0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3)


def uri(data: bytes) -> str:
    return "data:application/octet-stream;base64," + base64.b64encode(data).decode()


def tetra(indices: tuple[int, ...] = INDICES) -> dict[str, Any]:
    """A valid one-node, one-mesh glTF document with its 72-byte buffer embedded."""
    data = POSITIONS + struct.pack(f"<{len(indices)}H", *indices)
    return {
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "buffers": [{"uri": uri(data), "byteLength": len(data)}],
        "bufferViews": [
            {"buffer": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 2 * len(indices)},
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0] * 3, "max": [1] * 3},
            {"bufferView": 1, "componentType": 5123, "count": len(indices), "type": "SCALAR"},
        ],
    }


def glb(doc: dict[str, Any], binary: bytes) -> bytes:
    """A GLB holding ``doc`` and ``binary`` (buffer 0, no uri); its binary data starts at byte 28 + JSON size."""
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    binary += b"\0" * (-len(binary) % 4)
    body = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(binary), 0x004E4942) + binary
    return b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body


def write(tmp_path: Path, doc: dict[str, Any], name: str = "m.gltf") -> Path:
    path = tmp_path / name
    path.write_text(json.dumps(doc, separators=(",", ":")))
    return path


def normalize(path: Path, env: dict[str, str] | None = None) -> Outcome:
    out = path.parent / "out"
    return run_bounded(["meshtool", "normalize", str(path), "-o", str(out)], seconds=30, memory_mb=1500, env=env)


def refused(outcome: Outcome, name: str, *parts: str) -> str:
    """The one error line of a refusal (exit 1, no traceback), which names the file and contains ``parts``."""
    lines = outcome.err.strip().splitlines()
    assert outcome.code == 1, outcome.err[-3000:]
    assert len(lines) == 1, outcome.err[-3000:]
    assert lines[0].startswith(f"error: {name}: "), lines[0]
    for part in parts:
        assert part in lines[0], lines[0]
    return lines[0]


def read(path: Path) -> Any:
    return read_gltf(path.read_bytes(), path.name, path, Resolver(path.parent))


# -- a short attribute: dropped with a warning --------------------------------------------------------


@pytest.mark.parametrize(("key", "width", "what"), [("NORMAL", "VEC3", "normals"), ("TEXCOORD_0", "VEC2", "texture")])
def test_short_attribute_is_dropped_with_a_warning(tmp_path, key, width, what):
    doc = tetra()
    doc["accessors"].append({"bufferView": 0, "componentType": 5126, "count": 1, "type": width})
    doc["meshes"][0]["primitives"][0]["attributes"][key] = 2
    path = write(tmp_path, doc)
    outcome = normalize(path)
    assert outcome.code == 0, outcome.err
    assert (
        f"warning: m.gltf: mesh 0 primitive 0: {key} (accessor 2) has 1 elements, POSITION (accessor 0) has 4: "
        f"its {what}" in outcome.err
    )
    assert "[gltf-attribute-dropped]" in outcome.err
    mesh = read(path)
    assert mesh.face_sizes.size == 4 and mesh.normals.shape == (0, 3) and mesh.texcoords.shape == (0, 2)


# -- amplification: refused before anything is allocated ----------------------------------------------


def test_zero_filled_accessor_with_a_huge_count_is_refused_fast(tmp_path):
    # 207 bytes: four nodes instancing 16,777,215 zero vertices without a bufferView (80 s and 5.2 GB before)
    doc = {
        "asset": {"version": "2.0"},
        "accessors": [{"componentType": 5126, "count": 16777215, "type": "VEC3"}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "nodes": [{"mesh": 0}] * 4,
    }
    path = write(tmp_path, doc)
    assert path.stat().st_size < 240
    refused(
        normalize(path),
        "m.gltf",
        "places more than 65,536 zero-filled accessor elements",
        "node 0 instancing mesh 0",
    )


def test_zero_filled_indices_are_refused_fast(tmp_path):
    doc = tetra()
    doc["accessors"][1] = {"componentType": 5125, "count": 3 * 10**6, "type": "SCALAR"}
    doc["nodes"] = [{"mesh": 0} for _ in range(8)]
    doc["scenes"] = [{"nodes": list(range(8))}]
    path = write(tmp_path, doc)
    assert path.stat().st_size < 1024
    refused(normalize(path), "m.gltf", "zero-filled accessor elements")


def test_one_buffer_instanced_by_2000_x_2000_primitives_is_refused_fast(tmp_path):
    # a 72-byte buffer, a mesh of 2000 primitives, 2000 nodes instancing it: 4,000,000 primitive instances
    doc = tetra()
    doc["meshes"][0]["primitives"] *= 2000
    doc["nodes"] = [{"mesh": 0} for _ in range(2000)]
    doc["scenes"] = [{"nodes": list(range(2000))}]
    path = write(tmp_path, doc)
    refused(
        normalize(path),
        "m.gltf",
        "places more than 100,000 mesh primitive instances (at least 102,000 with node 50 instancing mesh 0",
        "MESHTOOL_MAX_INSTANCES",
    )


def test_instances_past_the_triangle_budget_are_refused_before_decoding(tmp_path):
    # a triangle strip of 10,000 byte indices (9,998 triangles) instanced by 2,000 nodes: 20 million triangles
    strip = bytes(i % 4 for i in range(10_000))
    doc = tetra()
    doc["buffers"].append({"uri": uri(strip), "byteLength": len(strip)})
    doc["bufferViews"].append({"buffer": 1, "byteLength": len(strip)})
    doc["accessors"][1] = {"bufferView": 2, "componentType": 5121, "count": len(strip), "type": "SCALAR"}
    doc["meshes"][0]["primitives"][0]["mode"] = 5
    doc["nodes"] = [{"mesh": 0} for _ in range(2000)]
    doc["scenes"] = [{"nodes": list(range(2000))}]
    path = write(tmp_path, doc)
    refused(
        normalize(path),
        "m.gltf",
        "expands to more than 16,777,216 triangles",
        "with node 1678 instancing mesh 0 (1 primitive(s))",
        "MESHTOOL_MAX_TRIANGLES",
    )


@pytest.mark.parametrize("stride", [1, 8])
def test_stride_smaller_than_the_element_is_refused(tmp_path, stride):
    # stride 1 over 64 KiB read 65,524 overlapping vertices (1.3 GB for 4 MB); stride 8 read wrong geometry
    blob = bytes(64 << 10)
    (tmp_path / "m.bin").write_bytes(blob)
    doc = {
        "asset": {"version": "2.0"},
        "buffers": [{"uri": "m.bin", "byteLength": len(blob)}],
        "bufferViews": [{"buffer": 0, "byteLength": len(blob), "byteStride": stride}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": (len(blob) - 12) // stride, "type": "VEC3"}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "nodes": [{"mesh": 0}],
    }
    path = write(tmp_path, doc)
    refused(
        normalize(path),
        "m.gltf",
        f"accessor 0 reads 12-byte VEC3 elements from bufferView 0 with byteStride {stride}: elements would overlap",
        "§3.6.2.4",
    )


def test_limits_follow_the_environment(tmp_path):
    doc = tetra()
    doc["nodes"] = [{"mesh": 0} for _ in range(3)]
    doc["scenes"] = [{"nodes": [0, 1, 2]}]
    path = write(tmp_path, doc)  # 3 instances of 4 triangles
    refused(normalize(path, {"MESHTOOL_MAX_TRIANGLES": "11"}), "m.gltf", "expands to more than 11 triangles")
    exact = normalize(path, {"MESHTOOL_MAX_TRIANGLES": "12"})  # exactly at the limit: read, all 12 triangles
    assert exact.code == 0 and ", 12 triangles," in exact.out, exact.err
    refused(normalize(path, {"MESHTOOL_MAX_INSTANCES": "2"}), "m.gltf", "more than 2 mesh primitive instances")
    instances = normalize(path, {"MESHTOOL_MAX_INSTANCES": "3"})
    assert instances.code == 0 and ", 12 triangles," in instances.out, instances.err
    bad = normalize(path, {"MESHTOOL_MAX_INSTANCES": "many"})
    assert bad.code == 1 and bad.err.strip().splitlines() == [
        "error: environment variable MESHTOOL_MAX_INSTANCES='many' is not a positive whole number "
        "(unset MESHTOOL_MAX_INSTANCES or fix it)"
    ]


# -- what is indexed is checked: one error line each ---------------------------------------------------


def _nodes(doc: dict[str, Any], nodes: list[dict[str, Any]], roots: list[int]) -> None:
    doc["nodes"], doc["scenes"] = nodes, [{"nodes": roots}]


CASES: list[tuple[str, Callable[[dict[str, Any]], Any], tuple[str, ...]]] = [
    (
        "accessor-past-view",
        lambda d: d["accessors"][0].update(count=5),
        (
            "accessor 0 runs past its bufferView 0: byteOffset 0 + stride 12 x (5 - 1) + 12-byte element = 60 bytes, "
            "the view has 48",
        ),
    ),
    (
        "accessor-offset-past-view",
        lambda d: d["accessors"][1].update(byteOffset=4),
        ("accessor 1 runs past its bufferView 1",),
    ),
    (
        "view-past-buffer",
        lambda d: d["bufferViews"][1].update(byteLength=100),
        ("bufferView 1 (bytes 48..148) runs past buffer 0 (byteLength 72)",),
    ),
    (
        "buffer-short",
        lambda d: d["buffers"][0].update(byteLength=100),
        ("buffer 0 has 72 bytes, the file says byteLength 100",),
    ),
    (
        "index-beyond-positions",
        lambda d: d["buffers"][0].update(uri=uri(POSITIONS + struct.pack("<12H", 0, 2, 7, *INDICES[3:]))),
        ("mesh 0 primitive 0: index 7 (element 2 of accessor 1) is beyond the 4 vertices of POSITION accessor 0",),
    ),
    (
        "float-indices",
        lambda d: d["accessors"][1].update(componentType=5126, count=6),
        ("accessor 1 (indices of mesh 0 primitive 0) is SCALAR of componentType 5126",),
    ),
    (
        "signed-int-component",
        lambda d: d["accessors"][0].update(componentType=5124),
        ("accessor 0 has componentType 5124 and type 'VEC3'",),
    ),
    ("unknown-type", lambda d: d["accessors"][0].update(type="VEC5"), ("accessor 0 has componentType 5126 and type",)),
    (
        "position-vec2",
        lambda d: d["accessors"][0].update(type="VEC2"),
        ("accessor 0 (POSITION of mesh 0 primitive 0) is VEC2, not VEC3",),
    ),
    (
        "indices-not-multiple-of-3",
        lambda d: d["accessors"][1].update(count=11),
        ("mesh 0 primitive 0 is a triangle list of 11 vertex indices (accessor 1), not a multiple of 3",),
    ),
    ("unknown-mode", lambda d: d["meshes"][0]["primitives"][0].update(mode=9), ("mesh 0 primitive 0 has mode 9",)),
    ("mesh-index", lambda d: d["nodes"][0].update(mesh=5), ("node 0 refers to meshes[5], which does not exist",)),
    ("mesh-index-string", lambda d: d["nodes"][0].update(mesh="0"), ("node 0 refers to meshes['0']",)),
    (
        "accessor-index",
        lambda d: d["meshes"][0]["primitives"][0]["attributes"].update(POSITION=9),
        ("mesh 0 primitive 0 POSITION refers to accessors[9], which does not exist (2 in the file)",),
    ),
    (
        "view-index",
        lambda d: d["accessors"][0].update(bufferView=4),
        ("accessor 0 refers to bufferViews[4], which does not exist",),
    ),
    (
        "buffer-index",
        lambda d: d["bufferViews"][0].update(buffer=1),
        ("bufferView 0 refers to buffers[1], which does not exist",),
    ),
    (
        "material-index",
        lambda d: d["meshes"][0]["primitives"][0].update(material=3),
        ("mesh 0 primitive 0 refers to materials[3], which does not exist (0 in the file)",),
    ),
    ("scene-index", lambda d: d.update(scene=2), ("the default scene refers to scenes[2], which does not exist",)),
    (
        "node-missing",
        lambda d: _nodes(d, [{"mesh": 0, "children": [3]}], [0]),
        ("node 3 is missing: node 0 refers to it, the file has 1 nodes",),
    ),
    (
        "node-cycle",
        lambda d: _nodes(d, [{"mesh": 0, "children": [1]}, {"children": [0]}], [0]),
        ("node 0 is reached twice (again from node 1): the node hierarchy has a cycle", "§3.5.2"),
    ),
    (
        "node-two-parents",
        lambda d: _nodes(d, [{"children": [2]}, {"children": [2]}, {"mesh": 0}], [0, 1]),
        ("node 2 is reached twice (again from node 1)",),
    ),
    (
        "node-depth-10000",
        lambda d: _nodes(d, [{"children": [i + 1]} for i in range(10_000)] + [{"mesh": 0}], [0]),
        ("node 257 is nested more than 256 levels deep",),
    ),
    (
        "matrix-overflow",
        lambda d: _nodes(d, [{"scale": [1e300] * 3, "children": [1]}, {"mesh": 0, "scale": [1e300] * 3}], [0]),
        ("node 1 has a transform that is not finite once combined with its parents'",),
    ),
    ("matrix-nan", lambda d: d["nodes"][0].update(translation=[float("nan"), 0, 0]), ("node 0 has a non-finite",)),
    (
        "matrix-infinite",
        lambda d: d["nodes"][0].update(matrix=[float("inf")] + [0.0] * 15),
        ("node 0 has a non-finite transform",),
    ),
    (
        "sparse-count",
        lambda d: d["accessors"][0].update(
            sparse={"count": 5, "indices": {"bufferView": 1, "componentType": 5123}, "values": {"bufferView": 0}}
        ),
        ("accessor 0 sparse count 5 is more than the accessor's 4 elements",),
    ),
    (
        "sparse-values-past-view",
        lambda d: d["accessors"][0].update(
            sparse={"count": 4, "indices": {"bufferView": 1, "componentType": 5123}, "values": {"bufferView": 1}}
        ),
        ("accessor 0 sparse values runs past bufferView 1: 0 + 4 x 12 bytes, the view has 24",),
    ),
]


@pytest.mark.parametrize(("change", "parts"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_malformed_input_is_one_error_line(tmp_path, change, parts):
    doc = tetra()
    change(doc)
    path = write(tmp_path, doc)
    refused(normalize(path), "m.gltf", *parts)
    with pytest.raises(FormatError):  # the library raises the same, never a RecursionError or IndexError
        read(path)


def test_sparse_index_out_of_range_names_the_glb_byte(tmp_path):
    doc = tetra()
    del doc["buffers"][0]["uri"]
    binary = POSITIONS + struct.pack("<12H", *INDICES) + struct.pack("<H", 9) + bytes(2) + bytes(12)
    doc["buffers"][0]["byteLength"] = len(binary)
    doc["bufferViews"] += [{"buffer": 0, "byteOffset": 72, "byteLength": 4}, {"buffer": 0, "byteOffset": 76,
                                                                            "byteLength": 12}]  # fmt: skip
    doc["accessors"][0]["sparse"] = {
        "count": 1,
        "indices": {"bufferView": 2, "componentType": 5123},
        "values": {"bufferView": 3},
    }
    data = glb(doc, binary)
    start = len(data) - len(binary) - (-len(binary) % 4)  # where the binary chunk's data starts
    path = tmp_path / "m.glb"
    path.write_bytes(data)
    refused(
        normalize(path),
        "m.glb",
        f"m.glb: byte {start + 72}: accessor 0: sparse index 9 (entry 0) is beyond its 4 elements",
    )


def test_glb_errors_name_the_byte(tmp_path):
    doc = tetra((0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 30))
    del doc["buffers"][0]["uri"]
    binary = POSITIONS + struct.pack("<12H", 0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 30)
    data = glb(doc, binary)
    start = len(data) - len(binary)
    path = tmp_path / "m.glb"
    path.write_bytes(data)
    refused(normalize(path), "m.glb", f"m.glb: byte {start + 48 + 11 * 2}: mesh 0 primitive 0: index 30 (element 11")
    doc["accessors"][0]["count"] = 5
    path.write_bytes(glb(doc, binary))
    refused(normalize(path), "m.glb", f"m.glb: byte {start}: accessor 0 runs past its bufferView 0")


def test_sparse_accessor_inside_its_range_is_read(tmp_path):
    doc = tetra()
    moved = struct.pack("<3f", 0, 0, 2)
    doc["buffers"].append({"uri": uri(struct.pack("<H", 3) + bytes(2) + moved), "byteLength": 16})
    doc["bufferViews"] += [{"buffer": 1, "byteLength": 2}, {"buffer": 1, "byteOffset": 4, "byteLength": 12}]
    doc["accessors"][0]["sparse"] = {
        "count": 1,
        "indices": {"bufferView": 2, "componentType": 5123},
        "values": {"bufferView": 3},
    }
    mesh = read(write(tmp_path, doc))
    np.testing.assert_allclose(mesh.positions.max(axis=0), [1, 1, 2])


# -- genuine files still convert, as trimesh reads them -------------------------------------------------


@pytest.mark.parametrize(
    "src",
    [FIXTURES / "formats" / "gltf" / "external" / "cube.gltf", FIXTURES / "formats" / "gltf" / "embedded_texture.glb"],
)
def test_genuine_files_convert_as_trimesh_reads_them(tmp_path, src):
    trimesh = pytest.importorskip("trimesh")
    outcome = run_bounded(["meshtool", "normalize", str(src), "-o", str(tmp_path / "out")], seconds=60, memory_mb=1500)
    assert outcome.code == 0, outcome.err
    scene = trimesh.load(src, force="scene")
    mesh = read(src)
    assert mesh.face_sizes.size == sum(len(g.faces) for g in scene.dump()) == 12
    np.testing.assert_allclose(mesh.positions.min(axis=0), scene.bounds[0], atol=1e-6)
    np.testing.assert_allclose(mesh.positions.max(axis=0), scene.bounds[1], atol=1e-6)


def test_generated_tetrahedron_converts_as_trimesh_reads_it(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    doc = tetra()
    doc["nodes"] = [{"mesh": 0, "translation": [0, 0, 0]}, {"mesh": 0, "translation": [2, 0, 0]}]
    doc["scenes"] = [{"nodes": [0, 1]}]
    path = write(tmp_path, doc)
    assert normalize(path).code == 0
    scene = trimesh.load(path, force="scene")
    mesh = read(path)
    assert mesh.face_sizes.size == sum(len(g.faces) for g in scene.dump()) == 8
    np.testing.assert_allclose(mesh.positions.max(axis=0), scene.bounds[1], atol=1e-6)
