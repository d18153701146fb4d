"""The glTF writer (``meshtool/export/gltf_write.py``) checked against the glTF 2.0 specification and its readers.

In-process (so a mutation of the writer is seen): every test builds with :class:`GltfBuilder` directly and
checks what it wrote against sources outside the writer:

- the glTF 2.0 specification (Khronos, version 2.0.1), cited by section title: the GLB container ("GLB File
  Format Specification": header, chunks and their padding), "Accessors" (types, component types, data
  alignment), "Meshes" (the primitive restart values indices must not hold), "Coordinate System and Units",
  and the properties reference for ``bufferView.target``, ``sampler`` (filter and wrap codes),
  ``node.matrix`` (column-major), ``material`` (defaults), ``mesh.primitive.mode`` and data URIs ("URIs");
- the Khronos glTF validator (``tools/gltf-validator``, installed by ``scripts/install_test_tools.sh``; the
  validator tests skip, saying why, without it or without node);
- pygltflib and trimesh reading the bytes back (the arrays decoded from the buffer, the vertices placed by
  the node transforms).
"""

from __future__ import annotations

import base64
import io
import json
import shutil
import struct
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pygltflib  # type: ignore[import-untyped]
import pytest
import trimesh
from PIL import Image

import meshtool
from meshtool.export.gltf_write import (
    ARRAY_BUFFER,
    Z_UP_TO_Y_UP,
    Z_UP_TO_Y_UP_ROTATION,
    GltfBuilder,
    column_major,
)

ROOT = Path(__file__).resolve().parent.parent
VALIDATOR = ROOT / "tools" / "gltf-validator" / "node_modules" / "gltf-validator"
# glTF 2.0, "Accessor Data Types" and the properties reference, bufferView.target
FLOAT, UNSIGNED_SHORT, UNSIGNED_INT = 5126, 5123, 5125
ELEMENT_ARRAY_BUFFER = 34963
# glTF 2.0, properties reference, sampler: LINEAR, LINEAR_MIPMAP_LINEAR, REPEAT, CLAMP_TO_EDGE
LINEAR, LINEAR_MIPMAP_LINEAR, REPEAT, CLAMP_TO_EDGE = 9729, 9987, 10497, 33071
# glTF 2.0, "GLB File Format Specification": magic "glTF", chunk types "JSON" and "BIN\0" as little-endian uint32
MAGIC, JSON_CHUNK, BIN_CHUNK = 0x46546C67, 0x4E4F534A, 0x004E4942


def _png(colour: tuple[int, int, int], size: int = 4) -> bytes:
    buffer = io.BytesIO()
    Image.new("RGB", (size, size), colour).save(buffer, format="PNG")
    return buffer.getvalue()


def _chunks(glb: bytes) -> tuple[dict[str, Any], bytes]:
    """The JSON document and BIN chunk of a GLB, read by the layout of glTF 2.0 "GLB File Format Specification"."""
    magic, version, length = struct.unpack_from("<III", glb, 0)
    assert (magic, version, length) == (MAGIC, 2, len(glb))
    json_length, json_type = struct.unpack_from("<II", glb, 12)
    assert json_type == JSON_CHUNK and json_length % 4 == 0
    text = glb[20 : 20 + json_length]
    stripped = text.rstrip(b" ")
    assert len(text) - len(stripped) < 4  # padded with spaces (0x20), no more than alignment needs
    document: dict[str, Any] = json.loads(text)
    at = 20 + json_length
    bin_length, bin_type = struct.unpack_from("<II", glb, at)
    assert bin_type == BIN_CHUNK and bin_length % 4 == 0
    assert at + 8 + bin_length == len(glb)  # the BIN chunk is the last thing in the file
    return document, glb[at + 8 :]


def _view_bytes(document: dict[str, Any], blob: bytes, view: int) -> bytes:
    entry = document["bufferViews"][view]
    start = entry.get("byteOffset", 0)
    return blob[start : start + entry["byteLength"]]


def _accessor_array(document: dict[str, Any], blob: bytes, index: int) -> np.ndarray:
    """An accessor's values decoded from the buffer by its componentType, type and count ("Accessors")."""
    accessor = document["accessors"][index]
    dtype = {FLOAT: "<f4", UNSIGNED_SHORT: "<u2", UNSIGNED_INT: "<u4"}[accessor["componentType"]]
    width = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}[accessor["type"]]
    raw = _view_bytes(document, blob, accessor["bufferView"])
    values = np.frombuffer(raw, dtype=dtype, count=accessor["count"] * width)
    return values if width == 1 else values.reshape(accessor["count"], width)


def _validate(tmp_path: Path, name: str, data: bytes) -> list[tuple[str, str]]:
    """The Khronos validator's messages (code, pointer) for ``data``; skips without node or the validator."""
    node = shutil.which("node")
    if node is None:
        pytest.skip("node is not installed (the Khronos glTF validator runs on Node.js)")
    if not VALIDATOR.is_dir():
        pytest.skip("gltf-validator is not installed: run scripts/install_test_tools.sh")
    path = tmp_path / name
    path.write_bytes(data)
    run = subprocess.run(
        [node, str(ROOT / "scripts" / "gltf_validate.cjs"), str(path)], capture_output=True, text=True, check=False
    )
    assert run.returncode == 0, run.stderr
    issues = json.loads(run.stdout)["issues"]
    shown = [(m["code"], m["pointer"]) for m in issues["messages"]]
    counts = (issues["numErrors"], issues["numWarnings"], issues["numInfos"], issues["numHints"])
    assert counts == (0, 0, 0, 0) or shown, counts
    return shown


# A unit quad in the z = 0.5 plane (Z-up), two triangles wound counter-clockwise seen from +Z.
QUAD = np.array([[0, 0, 0.5], [1, 0, 0.5], [1, 1, 0.5], [0, 1, 0.5]], dtype=np.float64)
QUAD_TRIANGLES = np.array([[0, 1, 2], [0, 2, 3]])
QUAD_UV = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], dtype=np.float64)


def _quad_primitive(
    builder: GltfBuilder, material: int, name: str = "quad", offset: float = 0.0, tangents: bool = True
) -> int:
    attributes = {
        "POSITION": builder.accessor(QUAD + np.array([offset, 0.0, 0.0]), bounds=True),
        "NORMAL": builder.accessor(np.tile([0.0, 0.0, 1.0], (4, 1))),
        "TEXCOORD_0": builder.accessor(QUAD_UV),
    }
    if tangents:
        attributes["TANGENT"] = builder.accessor(np.tile([1.0, 0.0, 0.0, 1.0], (4, 1)))
    return builder.mesh(name, attributes, builder.indices(QUAD_TRIANGLES, 4), material)


def _full(generator: str | None = None) -> GltfBuilder:
    """Everything the writer has: two textured, normal-mapped meshes, two scenes and one animation."""
    builder = GltfBuilder() if generator is None else GltfBuilder(generator)
    colour, normal_map = _png((200, 100, 50)), _png((128, 128, 255))
    opaque = builder.material(
        "opaque", [1.0, 0.5, 0.25, 1.0], builder.texture(colour), False, False, builder.texture(normal_map, False), 0.5
    )
    glass = builder.material("glass", [0.2, 0.4, 0.6, 0.5], builder.texture(colour, False), True, True)
    first = builder.node({"name": "first", "mesh": _quad_primitive(builder, opaque)})
    second = builder.node({"name": "second", "mesh": _quad_primitive(builder, glass, "other", 2.0, False)})
    root = builder.node({"name": "root", "matrix": column_major(Z_UP_TO_Y_UP), "children": [first, second]})
    builder.scene("world", [root])
    builder.extra_scene("alone", [builder.node({"name": "alone", "rotation": Z_UP_TO_Y_UP_ROTATION, "mesh": 0})])
    times = builder.accessor([0.0, 0.5, 1.0], bounds=True, target=None)
    moves = builder.accessor([[0, 0, 0], [0, 1, 0], [0, 2, 0]], target=None)
    turns = builder.accessor([[0, 0, 0, 1], [0, 0, np.sqrt(0.5), np.sqrt(0.5)], [0, 0, 1, 0]], target=None)
    builder.animation("motion", [(first, "translation", times, moves), (second, "rotation", times, turns)])
    return builder


def test_the_glb_container_follows_the_glb_layout() -> None:
    glb = _full().glb()
    document, blob = _chunks(glb)
    (buffer,) = document["buffers"]
    assert "uri" not in buffer  # GLB "Binary buffer": the GLB-stored buffer has no uri
    assert buffer["byteLength"] == len(blob)
    assert document["asset"] == {"version": "2.0", "generator": f"meshtool {meshtool.__version__}"}
    assert pygltflib.GLTF2.load_from_bytes(glb).binary_blob() == blob


def test_everything_the_writer_makes_passes_the_khronos_validator(tmp_path: Path) -> None:
    builder = _full("test 1.0")
    assert _validate(tmp_path, "full.glb", builder.glb()) == []
    assert _validate(tmp_path, "full.gltf", builder.gltf()) == []


def test_the_same_calls_give_the_same_bytes_and_the_generator_passes_through() -> None:
    assert _full().glb() == _full().glb()
    assert _full().gltf() == _full().gltf()
    document, _ = _chunks(_full("simrun 9.9").glb())
    assert document["asset"]["generator"] == "simrun 9.9"


def test_the_gltf_form_is_one_json_file_with_the_same_buffer_as_a_data_uri() -> None:
    builder = _full()
    text = builder.gltf()
    assert text.endswith(b"\n")
    document = json.loads(text)
    (buffer,) = document["buffers"]
    prefix = "data:application/octet-stream;base64,"  # "URIs": a data URI of the buffer's bytes
    assert buffer["uri"].startswith(prefix)
    data = base64.b64decode(buffer["uri"][len(prefix) :], validate=True)
    assert len(data) == buffer["byteLength"] and len(data) % 4 == 0
    glb_document, blob = _chunks(_full().glb())
    assert data == blob
    glb_document.pop("buffers")
    document.pop("buffers")
    assert document == glb_document  # the same objects in either form
    loaded = pygltflib.GLTF2.from_json(text.decode("utf-8"))
    assert [m.name for m in loaded.meshes] == ["quad", "other"]


def test_trimesh_places_the_vertices_y_up() -> None:
    scene: Any = trimesh.load(io.BytesIO(_full().glb()), file_type="glb", force="scene")
    placed = {}
    for name in scene.graph.nodes_geometry:
        transform, geometry = scene.graph[name]
        mesh = scene.geometry[geometry]
        placed[name] = (trimesh.transform_points(mesh.vertices, transform), np.asarray(mesh.faces))
    # Z-up (x, y, z) is Y-up (x, z, -y): glTF 2.0, "Coordinate System and Units"
    expected = np.column_stack([QUAD[:, 0], QUAD[:, 2], -QUAD[:, 1]])
    np.testing.assert_allclose(placed["first"][0], expected, atol=1e-6)
    np.testing.assert_allclose(placed["second"][0], expected + np.array([2.0, 0.0, 0.0]), atol=1e-6)
    np.testing.assert_array_equal(placed["first"][1], QUAD_TRIANGLES)


def test_the_frame_constants_turn_z_up_into_y_up() -> None:
    np.testing.assert_allclose(Z_UP_TO_Y_UP[:3, :3] @ [0, 0, 1], [0, 1, 0])
    np.testing.assert_allclose(Z_UP_TO_Y_UP[:3, :3] @ [0, 1, 0], [0, 0, -1])
    x, y, z, w = Z_UP_TO_Y_UP_ROTATION
    turn = trimesh.transformations.quaternion_matrix([w, x, y, z])  # type: ignore[no-untyped-call]
    np.testing.assert_allclose(turn, Z_UP_TO_Y_UP, atol=1e-12)


def test_a_node_matrix_is_column_major() -> None:
    # properties reference, node.matrix: "a floating-point 4x4 transformation matrix stored in column-major order"
    moved = np.eye(4)
    moved[:3, 3] = [1.0, 2.0, 3.0]
    moved[0, 1] = 7.0  # row 0, column 1: the fifth number in column-major order
    values = column_major(moved)
    assert values[12:15] == [1.0, 2.0, 3.0] and values[4] == 7.0 and values[1] == 0.0
    assert len(values) == 16 and all(type(v) is float for v in values)
    builder = GltfBuilder()
    material = builder.material("m", [1, 1, 1, 1], None, False, False)
    node = builder.node({"matrix": values, "mesh": _quad_primitive(builder, material)})
    builder.scene("s", [node])
    scene: Any = trimesh.load(io.BytesIO(builder.glb()), file_type="glb", force="scene")
    np.testing.assert_allclose(scene.bounds, [[1, 2, 3.5], [9, 3, 3.5]])  # x + 7 y + 1, y + 2, z + 3


@pytest.mark.parametrize(("shape", "kind"), [((5,), "SCALAR"), ((5, 2), "VEC2"), ((5, 3), "VEC3"), ((5, 4), "VEC4")])
def test_float_accessors_hold_the_values_and_their_bounds(shape: tuple[int, ...], kind: str) -> None:
    values = np.arange(np.prod(shape), dtype=np.float64).reshape(shape) * 0.1 - 0.7
    builder = GltfBuilder()
    plain = builder.accessor(values)
    bounded = builder.accessor(values, bounds=True)
    loose = builder.accessor(values, target=None)
    document, blob = _chunks(builder.glb())
    for index in (plain, bounded, loose):
        accessor = document["accessors"][index]
        assert (accessor["componentType"], accessor["type"], accessor["count"]) == (FLOAT, kind, 5)
        np.testing.assert_array_equal(_accessor_array(document, blob, index), values.astype(np.float32))
    assert "min" not in document["accessors"][plain] and "max" not in document["accessors"][plain]
    flat = values.astype(np.float32).reshape(5, -1)
    assert document["accessors"][bounded]["min"] == flat.min(axis=0).tolist()
    assert document["accessors"][bounded]["max"] == flat.max(axis=0).tolist()
    views = document["bufferViews"]
    assert views[document["accessors"][plain]["bufferView"]]["target"] == ARRAY_BUFFER == 34962
    assert "target" not in views[document["accessors"][loose]["bufferView"]]


@pytest.mark.parametrize(("vertices", "component"), [(65535, UNSIGNED_SHORT), (65536, UNSIGNED_INT)])
def test_indices_use_the_smallest_type_that_avoids_the_restart_value(vertices: int, component: int) -> None:
    # "Meshes", Overview: indices MUST NOT hold the largest value of their type (65535 for unsigned shorts)
    triangles = np.array([[0, 1, vertices - 1], [vertices - 1, 1, 2]])
    builder = GltfBuilder()
    index = builder.indices(triangles, vertices)
    document, blob = _chunks(builder.glb())
    accessor = document["accessors"][index]
    assert (accessor["componentType"], accessor["type"], accessor["count"]) == (component, "SCALAR", 6)
    assert document["bufferViews"][accessor["bufferView"]]["target"] == ELEMENT_ARRAY_BUFFER
    np.testing.assert_array_equal(_accessor_array(document, blob, index), triangles.ravel())


def test_a_large_mesh_reads_back_through_trimesh(tmp_path: Path) -> None:
    grid = 257  # 66049 vertices: the indices need uint32
    u, v = np.meshgrid(np.arange(grid, dtype=np.float64), np.arange(grid, dtype=np.float64), indexing="xy")
    positions = np.column_stack([u.ravel(), v.ravel(), np.zeros(grid * grid)]) / (grid - 1)
    corner = np.arange(grid - 1)[None, :] + grid * np.arange(grid - 1)[:, None]
    a, b, c, d = corner.ravel(), corner.ravel() + 1, corner.ravel() + grid + 1, corner.ravel() + grid
    triangles = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    builder = GltfBuilder()
    material = builder.material("grid", [1, 1, 1, 1], None, False, False)
    attributes = {"POSITION": builder.accessor(positions, bounds=True)}
    mesh = builder.mesh("grid", attributes, builder.indices(triangles, len(positions)), material)
    builder.scene("s", [builder.node({"name": "grid", "mesh": mesh})])
    glb = builder.glb()
    loaded: Any = trimesh.load(io.BytesIO(glb), file_type="glb", force="mesh", process=False)
    np.testing.assert_allclose(loaded.vertices, positions, atol=1e-7)
    np.testing.assert_array_equal(loaded.faces, triangles)
    assert _validate(tmp_path, "grid.glb", glb) == []


def test_buffer_views_are_aligned_without_gaps_or_overlaps() -> None:
    builder = GltfBuilder()
    odd_png = next(png for png in (_png((1, 2, 3), size) for size in range(1, 9)) if len(png) % 4)
    builder.indices([[0, 1, 2]], 3)  # 6 bytes
    builder.image(odd_png)
    builder.accessor([[0.0, 1.0, 2.0]])
    builder.indices([[0, 1, 2]], 3)
    document, blob = _chunks(builder.glb())
    end = 0
    for view in document["bufferViews"]:
        # "Data Alignment": an accessor's offset into the buffer is a multiple of its component size (4 is enough)
        assert view["byteOffset"] % 4 == 0 and 0 <= view["byteOffset"] - end < 4
        end = view["byteOffset"] + view["byteLength"]
    assert len(blob) == end + (-end % 4)  # the buffer itself ends padded to 4
    assert blob[end:] == b"\0" * (len(blob) - end)  # GLB "Chunks": the BIN chunk is padded with trailing zeros
    assert _view_bytes(document, blob, document["images"][0]["bufferView"]) == odd_png


def test_images_are_stored_once_and_samplers_are_shared_by_wrap_mode() -> None:
    red, blue = _png((255, 0, 0)), _png((0, 0, 255))
    builder = GltfBuilder()
    textures = [builder.texture(red), builder.texture(red), builder.texture(blue, False), builder.texture(red, False)]
    assert textures == [0, 1, 2, 3]
    document, blob = _chunks(builder.glb())
    assert len(document["images"]) == 2
    sources = [document["textures"][t]["source"] for t in textures]
    assert sources == [0, 0, 1, 0]
    for image, png in ((0, red), (1, blue)):
        assert document["images"][image]["mimeType"] == "image/png"
        assert _view_bytes(document, blob, document["images"][image]["bufferView"]) == png
        assert "target" not in document["bufferViews"][document["images"][image]["bufferView"]]
    samplers = [document["samplers"][document["textures"][t]["sampler"]] for t in textures]
    repeat = {"magFilter": LINEAR, "minFilter": LINEAR_MIPMAP_LINEAR, "wrapS": REPEAT, "wrapT": REPEAT}
    clamp = {"magFilter": LINEAR, "minFilter": LINEAR_MIPMAP_LINEAR, "wrapS": CLAMP_TO_EDGE, "wrapT": CLAMP_TO_EDGE}
    assert samplers == [repeat, repeat, clamp, clamp]
    assert len(document["samplers"]) == 2
    assert builder.image(red) == 0 and builder.image(blue) == 1


def test_materials_write_what_differs_from_the_specification_defaults() -> None:
    builder = GltfBuilder()
    plain = builder.material("plain", [0.1, 0.2, 0.3, 1.0], None, False, False)
    texture = builder.texture(_png((9, 9, 9)))
    dressed = builder.material("dressed", [1, 1, 1, 0.5], texture, True, True, texture, 0.25)
    unit = builder.material("unit", [1, 1, 1, 1], None, False, False, texture, 1.0)
    default = builder.material("default", [1, 1, 1, 1], None, False, False, texture)
    document, _ = _chunks(builder.glb())
    materials = document["materials"]
    # properties reference, material: alphaMode defaults to OPAQUE, doubleSided to false, normalTexture.scale to 1
    assert materials[plain] == {
        "name": "plain",
        "pbrMetallicRoughness": {
            "baseColorFactor": [0.1, 0.2, 0.3, 1.0],
            "metallicFactor": 0.0,
            "roughnessFactor": 1.0,
        },
    }
    assert materials[dressed]["pbrMetallicRoughness"]["baseColorTexture"] == {"index": texture}
    assert materials[dressed]["normalTexture"] == {"index": texture, "scale": 0.25}
    assert (materials[dressed]["alphaMode"], materials[dressed]["doubleSided"]) == ("BLEND", True)
    assert materials[unit]["normalTexture"] == materials[default]["normalTexture"] == {"index": texture}
    assert "alphaMode" not in materials[unit] and "doubleSided" not in materials[unit]


def test_meshes_nodes_and_scenes() -> None:
    builder = GltfBuilder()
    material = builder.material("m", [1, 1, 1, 1], None, False, False)
    mesh = _quad_primitive(builder, material)
    assert builder.node({"name": "a", "mesh": mesh}) == 0
    assert builder.node({"name": "b", "translation": [1.0, 2.0, 3.0]}) == 1
    builder.scene("main", [0])
    builder.extra_scene("more", [1])
    builder.extra_scene("both", [0, 1])
    document, _ = _chunks(builder.glb())
    (primitive,) = document["meshes"][mesh]["primitives"]
    assert primitive["mode"] == 4  # mesh.primitive.mode 4: TRIANGLES
    assert primitive["indices"] == 4 and primitive["material"] == material
    assert sorted(primitive["attributes"]) == ["NORMAL", "POSITION", "TANGENT", "TEXCOORD_0"]
    assert document["meshes"][mesh]["name"] == "quad"
    assert document["scene"] == 0
    assert document["scenes"] == [
        {"name": "main", "nodes": [0]},
        {"name": "more", "nodes": [1]},
        {"name": "both", "nodes": [0, 1]},
    ]
    assert document["nodes"][1] == {"name": "b", "translation": [1.0, 2.0, 3.0]}


def test_animations_pair_each_channel_with_its_linear_sampler(tmp_path: Path) -> None:
    builder = _full()
    builder.animation("nothing", [])
    glb = builder.glb()
    document, blob = _chunks(glb)
    (animation,) = document["animations"]  # an animation without channels is not written
    assert animation["name"] == "motion"
    assert animation["channels"] == [
        {"sampler": 0, "target": {"node": 0, "path": "translation"}},
        {"sampler": 1, "target": {"node": 1, "path": "rotation"}},
    ]
    inputs = {sampler["input"] for sampler in animation["samplers"]}
    assert len(inputs) == 1 and [s["interpolation"] for s in animation["samplers"]] == ["LINEAR", "LINEAR"]
    np.testing.assert_allclose(_accessor_array(document, blob, inputs.pop()), [0.0, 0.5, 1.0])
    outputs = [_accessor_array(document, blob, s["output"]) for s in animation["samplers"]]
    np.testing.assert_allclose(outputs[0][:, 1], [0, 1, 2])
    np.testing.assert_allclose(outputs[1][2], [0, 0, 1, 0])
    loaded = pygltflib.GLTF2.load_from_bytes(glb)
    assert loaded.animations[0].channels[1].target.path == "rotation"
    assert _validate(tmp_path, "animated.glb", glb) == []


def test_an_animation_input_without_bounds_or_with_a_target_is_what_the_validator_refuses(tmp_path: Path) -> None:
    """The validator is strict about what the callers must ask for (animation.sampler.input, bufferView.target)."""
    builder = GltfBuilder()
    node = builder.node({"name": "n"})
    builder.scene("s", [node])
    times = builder.accessor([0.0, 1.0])  # no bounds, and an ARRAY_BUFFER target
    builder.animation("a", [(node, "translation", times, builder.accessor([[0, 0, 0], [1, 0, 0]], target=None))])
    shown = set(_validate(tmp_path, "bad.glb", builder.glb()))
    # so the clean reports above do check the bounds and targets the writer gives what its callers ask for
    assert {
        ("BUFFER_VIEW_TARGET_OVERRIDE", "/animations/0/samplers/0/input"),
        ("ANIMATION_SAMPLER_INPUT_ACCESSOR_WITHOUT_BOUNDS", "/animations/0/samplers/0/input"),
    } <= shown
