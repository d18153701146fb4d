"""Write fixtures/formats/: one small file per mesh format and per quirk of issue 20 (deterministic).

Every file is written byte by byte here (struct, JSON, XML text), not by a library, so each quirk is
exactly what the fixture name says. The geometry is axis-aligned boxes whose corners the tests know.

Usage: python scripts/make_format_fixtures.py
"""

from __future__ import annotations

import io
import json
import shutil
import struct
from pathlib import Path

import numpy as np
from PIL import Image

ROOT = Path(__file__).resolve().parent.parent / "fixtures" / "formats"

#: Unit cube corners and outward, counter-clockwise triangles.
CUBE = np.array(
    [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], dtype=np.float64
)
CUBE_FACES = np.array(
    [
        [0, 2, 1], [0, 3, 2],  # z = 0
        [4, 5, 6], [4, 6, 7],  # z = 1
        [0, 1, 5], [0, 5, 4],  # y = 0
        [3, 7, 6], [3, 6, 2],  # y = 1
        [0, 4, 7], [0, 7, 3],  # x = 0
        [1, 2, 6], [1, 6, 5],  # x = 1
    ],
    dtype=np.int64,
)  # fmt: skip


def box(size: tuple[float, float, float], origin: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> np.ndarray:
    """Corners of a box with its minimum corner at ``origin``."""
    out: np.ndarray = CUBE * np.asarray(size) + np.asarray(origin)
    return out


def face_normals(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    out: np.ndarray = n / np.linalg.norm(n, axis=1, keepdims=True)
    return out


def png_bytes(rgb: tuple[int, int, int], size: int = 4) -> bytes:
    y, x = np.mgrid[0:size, 0:size]
    checker = ((x + y) % 2)[..., None].astype(np.uint8)
    pixels = np.where(checker == 1, np.array(rgb, np.uint8), np.array([255, 255, 255], np.uint8)).astype(np.uint8)
    buf = io.BytesIO()
    Image.fromarray(pixels, "RGB").save(buf, format="PNG")
    return buf.getvalue()


def write(path: Path, data: bytes | str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(data.encode("utf-8") if isinstance(data, str) else data)


# -- STL ---------------------------------------------------------------------------------------------------


def stl_binary(v: np.ndarray, f: np.ndarray, header: bytes) -> bytes:
    normals = face_normals(v, f)
    out = [header.ljust(80, b" ")[:80], struct.pack("<I", f.shape[0])]
    for n, tri in zip(normals, f, strict=True):
        out.append(struct.pack("<12fH", *n, *v[tri].reshape(-1), 0))
    return b"".join(out)


def stl_ascii_solid(name: str, v: np.ndarray, f: np.ndarray, flip_normals: tuple[int, ...] = ()) -> str:
    normals = face_normals(v, f)
    lines = [f"solid {name}"]
    for k, tri in enumerate(f):
        n = -normals[k] if k in flip_normals else normals[k]
        lines.append(f"  facet normal {n[0]:g} {n[1]:g} {n[2]:g}")
        lines.append("    outer loop")
        lines.extend(f"      vertex {p[0]:g} {p[1]:g} {p[2]:g}" for p in v[tri])
        lines.append("    endloop")
        lines.append("  endfacet")
    lines.append(f"endsolid {name}")
    return "\n".join(lines) + "\n"


def make_stl() -> None:
    d = ROOT / "stl"
    # 40 x 30 x 20 mm part; the header starts with "solid" as SolidWorks writes it
    write(d / "solid_header_binary.stl", stl_binary(box((40, 30, 20)), CUBE_FACES, b"solid bracket exported by CAD"))
    base = stl_ascii_solid("base", box((100, 100, 10)), CUBE_FACES)
    post = stl_ascii_solid("post", box((10, 10, 50), (45, 45, 10)), CUBE_FACES)
    write(d / "two_solids_ascii.stl", base + post)
    write(d / "flipped_normals.stl", stl_ascii_solid("flipped", box((20, 20, 20)), CUBE_FACES, flip_normals=(2, 7)))


# -- PLY ---------------------------------------------------------------------------------------------------


def make_ply() -> None:
    d = ROOT / "ply"
    v = box((0.2, 0.1, 0.05))
    colors = (CUBE * 255).astype(np.uint8)  # each corner coloured by its position
    uv = CUBE[:, :2]
    header = (
        "ply\nformat binary_big_endian 1.0\ncomment big-endian, vertex colours and uvs\nelement vertex 8\n"
        "property float x\nproperty float y\nproperty float z\nproperty uchar red\nproperty uchar green\n"
        "property uchar blue\nproperty float s\nproperty float t\nelement face 12\n"
        "property list uchar int vertex_indices\nend_header\n"
    ).encode("ascii")
    body = b"".join(struct.pack(">3f3B2f", *p, *c, *t) for p, c, t in zip(v, colors, uv, strict=True))
    body += b"".join(struct.pack(">B3i", 3, *tri) for tri in CUBE_FACES)
    write(d / "colored_big_endian.ply", header + body)
    lines = [
        "ply",
        "format ascii 1.0",
        "comment TextureFile checker.png",
        "element vertex 8",
        "property float x",
        "property float y",
        "property float z",
        "property float u",
        "property float v",
        "element face 6",
        "property list uchar int vertex_indices",
        "end_header",
    ]
    lines += [f"{p[0]:g} {p[1]:g} {p[2]:g} {t[0]:g} {t[1]:g}" for p, t in zip(box((0.3, 0.3, 0.3)), uv, strict=True)]
    quads = [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [3, 7, 6, 2], [0, 4, 7, 3], [1, 2, 6, 5]]
    lines += [f"4 {q[0]} {q[1]} {q[2]} {q[3]}" for q in quads]
    write(d / "textured_quads_ascii.ply", "\n".join(lines) + "\n")
    write(d / "checker.png", png_bytes((40, 90, 200)))


# -- glTF --------------------------------------------------------------------------------------------------


class GltfBuilder:
    """Accumulates one binary buffer with accessors (4-byte aligned views)."""

    def __init__(self) -> None:
        self.blob = bytearray()
        self.views: list[dict[str, object]] = []
        self.accessors: list[dict[str, object]] = []

    def view(self, data: bytes, target: int | None = None) -> int:
        while len(self.blob) % 4:
            self.blob += b"\0"
        entry: dict[str, object] = {"buffer": 0, "byteOffset": len(self.blob), "byteLength": len(data)}
        if target:
            entry["target"] = target
        self.blob += data
        self.views.append(entry)
        return len(self.views) - 1

    def accessor(self, values: np.ndarray, kind: str) -> int:
        if kind == "SCALAR":
            data = values.astype("<u2").tobytes()
            acc = {"componentType": 5123, "count": int(values.size), "type": "SCALAR"}
            acc["bufferView"] = self.view(data, 34963)
        else:
            data = values.astype("<f4").tobytes()
            acc = {"componentType": 5126, "count": int(values.shape[0]), "type": kind}
            acc["bufferView"] = self.view(data, 34962)
            if kind == "VEC3":
                acc["min"] = values.min(axis=0).astype(np.float32).astype(float).tolist()
                acc["max"] = values.max(axis=0).astype(np.float32).astype(float).tolist()
        self.accessors.append(acc)
        return len(self.accessors) - 1

    def box_primitive(self, v: np.ndarray, material: int | None) -> dict[str, object]:
        """A box split per face (24 vertices) with normals and uvs (glTF: v down)."""
        corners = CUBE_FACES.reshape(-1, 6)  # two triangles per side
        pos, nrm, uv, idx = [], [], [], []
        for side, quad in enumerate(corners):
            ids = list(dict.fromkeys(quad.tolist()))  # 4 corners in first-use order
            n = face_normals(v, CUBE_FACES[2 * side : 2 * side + 1])[0]
            base = len(pos)
            for i in ids:
                pos.append(v[i])
                nrm.append(n)
                axes = [a for a in range(3) if abs(n[a]) < 0.5]
                uv.append([CUBE[i][axes[0]], 1.0 - CUBE[i][axes[1]]])
            idx.extend(base + ids.index(c) for c in quad.tolist())
        prim: dict[str, object] = {
            "attributes": {
                "POSITION": self.accessor(np.asarray(pos), "VEC3"),
                "NORMAL": self.accessor(np.asarray(nrm), "VEC3"),
                "TEXCOORD_0": self.accessor(np.asarray(uv), "VEC2"),
            },
            "indices": self.accessor(np.asarray(idx), "SCALAR"),
        }
        if material is not None:
            prim["material"] = material
        return prim


def make_gltf() -> None:
    d = ROOT / "gltf"
    # GLB with an embedded PNG, node transforms (translated parent, rotated child) and KHR_texture_transform
    b = GltfBuilder()
    prim = b.box_primitive(box((0.4, 0.2, 0.1)), 0)
    image_view = b.view(png_bytes((200, 40, 40)))
    doc = {
        "asset": {"version": "2.0", "generator": "make_format_fixtures.py"},
        "extensionsUsed": ["KHR_texture_transform"],
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [
            {"name": "base", "translation": [1.0, 0.5, 0.0], "children": [1]},
            # 90 degrees about +Y: (x, y, z) -> (z, y, -x)
            {"name": "crate", "mesh": 0, "rotation": [0.0, 0.7071067811865476, 0.0, 0.7071067811865476]},
        ],
        "meshes": [{"name": "crate_mesh", "primitives": [prim]}],
        "materials": [
            {
                "name": "red_checker",
                "pbrMetallicRoughness": {
                    "baseColorFactor": [1.0, 1.0, 1.0, 1.0],
                    "baseColorTexture": {
                        "index": 0,
                        "extensions": {"KHR_texture_transform": {"offset": [0.5, 0.0], "scale": [2.0, 2.0]}},
                    },
                    "metallicFactor": 0.0,
                    "roughnessFactor": 0.5,
                },
            }
        ],
        "textures": [{"source": 0}],
        "images": [{"name": "checker", "bufferView": image_view, "mimeType": "image/png"}],
        "accessors": b.accessors,
        "bufferViews": b.views,
        "buffers": [{"byteLength": len(b.blob)}],
    }
    write(d / "embedded_texture.glb", glb(doc, bytes(b.blob)))

    # .gltf with an external buffer and an external image inside its folder
    b = GltfBuilder()
    prim = b.box_primitive(box((0.5, 0.5, 0.5)), 0)
    doc = {
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": [0]}],
        "nodes": [{"name": "cube", "mesh": 0}],
        "meshes": [{"primitives": [prim]}],
        "materials": [{"name": "wood", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
        "textures": [{"source": 0}],
        "images": [{"uri": "textures/wood%20grain.png"}],
        "accessors": b.accessors,
        "bufferViews": b.views,
        "buffers": [{"uri": "cube.bin", "byteLength": len(b.blob)}],
    }
    write(d / "external" / "cube.gltf", json.dumps(doc, indent=1) + "\n")
    write(d / "external" / "cube.bin", bytes(b.blob))
    write(d / "external" / "textures" / "wood grain.png", png_bytes((150, 100, 50)))

    # a buffer outside the glTF's folder: containment must refuse it
    doc["buffers"] = [{"uri": "../outside.bin", "byteLength": len(b.blob)}]
    doc["images"] = []
    doc["textures"] = []
    doc["materials"] = []
    doc["meshes"] = [{"primitives": [{k: v for k, v in prim.items() if k != "material"}]}]
    write(d / "escape" / "model" / "escape.gltf", json.dumps(doc, indent=1) + "\n")
    write(d / "escape" / "outside.bin", bytes(b.blob))

    # Draco compression required: refused with a clear error
    draco = {
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_draco_mesh_compression"],
        "extensionsRequired": ["KHR_draco_mesh_compression"],
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [
            {
                "primitives": [
                    {
                        "attributes": {"POSITION": 0},
                        "extensions": {"KHR_draco_mesh_compression": {"bufferView": 0, "attributes": {"POSITION": 0}}},
                    }
                ]
            }
        ],
        "accessors": [{"componentType": 5126, "count": 8, "type": "VEC3"}],
        "bufferViews": [{"buffer": 0, "byteLength": 4}],
        "buffers": [{"byteLength": 4, "uri": "data:application/octet-stream;base64,AAAAAA=="}],
    }
    write(d / "draco_required.gltf", json.dumps(draco, indent=1) + "\n")


def glb(doc: dict[str, object], blob: bytes) -> bytes:
    text = json.dumps(doc, separators=(",", ":")).encode("utf-8")
    text += b" " * (-len(text) % 4)
    blob += b"\0" * (-len(blob) % 4)
    body = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(blob), 0x004E4942) + blob
    return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body


# -- COLLADA -----------------------------------------------------------------------------------------------


def make_collada() -> None:
    d = ROOT / "dae" / "cm_zup"
    v = box((20, 10, 5))  # centimetres
    normals = face_normals(v, CUBE_FACES)
    uv = CUBE[:, :2]

    # triangles: vertex / normal / texcoord offsets; first 6 triangles red, last 6 textured
    def tris(rows: range) -> str:
        return " ".join(f"{CUBE_FACES[k][c]} {k} {CUBE_FACES[k][c]}" for k in rows for c in range(3))

    floats = lambda a: " ".join(f"{x:g}" for x in np.asarray(a).reshape(-1))  # noqa: E731
    xml = f"""<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset>
    <contributor><authoring_tool>make_format_fixtures.py</authoring_tool></contributor>
    <unit name="centimeter" meter="0.01"/>
    <up_axis>Z_UP</up_axis>
  </asset>
  <library_images>
    <image id="paint-img" name="paint"><init_from>textures/paint.png</init_from></image>
  </library_images>
  <library_effects>
    <effect id="red-fx"><profile_COMMON><technique sid="common"><phong>
      <diffuse><color>0.8 0.1 0.1 1</color></diffuse>
      <shininess><float>20</float></shininess>
    </phong></technique></profile_COMMON></effect>
    <effect id="paint-fx"><profile_COMMON>
      <newparam sid="paint-surface"><surface type="2D"><init_from>paint-img</init_from></surface></newparam>
      <newparam sid="paint-sampler"><sampler2D><source>paint-surface</source></sampler2D></newparam>
      <technique sid="common"><lambert>
        <diffuse><texture texture="paint-sampler" texcoord="UVMap"/></diffuse>
      </lambert></technique></profile_COMMON></effect>
  </library_effects>
  <library_materials>
    <material id="red-mat" name="red"><instance_effect url="#red-fx"/></material>
    <material id="paint-mat" name="paint"><instance_effect url="#paint-fx"/></material>
  </library_materials>
  <library_geometries>
    <geometry id="block-mesh" name="block">
      <mesh>
        <source id="block-pos"><float_array id="block-pos-array" count="{v.size}">{floats(v)}</float_array>
          <technique_common><accessor source="#block-pos-array" count="{len(v)}" stride="3">
            <param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/>
          </accessor></technique_common></source>
        <source id="block-nrm"><float_array id="block-nrm-array" count="{normals.size}">{floats(normals)}</float_array>
          <technique_common><accessor source="#block-nrm-array" count="{len(normals)}" stride="3">
            <param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/>
          </accessor></technique_common></source>
        <source id="block-uv"><float_array id="block-uv-array" count="{uv.size}">{floats(uv)}</float_array>
          <technique_common><accessor source="#block-uv-array" count="{len(uv)}" stride="2">
            <param name="S" type="float"/><param name="T" type="float"/>
          </accessor></technique_common></source>
        <vertices id="block-vtx"><input semantic="POSITION" source="#block-pos"/></vertices>
        <triangles material="red-sym" count="6">
          <input semantic="VERTEX" source="#block-vtx" offset="0"/>
          <input semantic="NORMAL" source="#block-nrm" offset="1"/>
          <input semantic="TEXCOORD" source="#block-uv" offset="2" set="0"/>
          <p>{tris(range(0, 6))}</p>
        </triangles>
        <triangles material="paint-sym" count="6">
          <input semantic="VERTEX" source="#block-vtx" offset="0"/>
          <input semantic="NORMAL" source="#block-nrm" offset="1"/>
          <input semantic="TEXCOORD" source="#block-uv" offset="2" set="0"/>
          <p>{tris(range(6, 12))}</p>
        </triangles>
      </mesh>
    </geometry>
  </library_geometries>
  <library_visual_scenes>
    <visual_scene id="scene">
      <node id="link" name="link">
        <matrix>1 0 0 0 0 1 0 0 0 0 1 10 0 0 0 1</matrix>
        <instance_geometry url="#block-mesh">
          <bind_material><technique_common>
            <instance_material symbol="red-sym" target="#red-mat"/>
            <instance_material symbol="paint-sym" target="#paint-mat">
              <bind_vertex_input semantic="UVMap" input_semantic="TEXCOORD" input_set="0"/>
            </instance_material>
          </technique_common></bind_material>
        </instance_geometry>
      </node>
    </visual_scene>
  </library_visual_scenes>
  <scene><instance_visual_scene url="#scene"/></scene>
</COLLADA>
"""
    write(d / "link_cm_zup.dae", xml)
    write(d / "textures" / "paint.png", png_bytes((30, 160, 60)))


# -- one folder with all five formats ----------------------------------------------------------------------


def make_mixed() -> None:
    d = ROOT / "mixed"
    v = box((0.1, 0.2, 0.3))
    obj = ["# a box in metres, Z-up", "mtllib box.mtl"] + [f"v {p[0]:g} {p[1]:g} {p[2]:g}" for p in v]
    obj += ["usemtl grey"] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in CUBE_FACES]
    write(d / "box.obj", "\n".join(obj) + "\n")
    write(d / "box.mtl", "newmtl grey\nKd 0.5 0.5 0.5\n")
    write(d / "bracket.stl", (ROOT / "stl" / "solid_header_binary.stl").read_bytes())
    write(d / "scan.ply", (ROOT / "ply" / "colored_big_endian.ply").read_bytes())
    write(d / "crate.glb", (ROOT / "gltf" / "embedded_texture.glb").read_bytes())
    shutil.copytree(ROOT / "dae" / "cm_zup", d / "link", dirs_exist_ok=True)


def make_validate() -> None:
    """One asset per format-specific ``meshtool validate`` rule (S012, S013), triggering only that rule."""
    d = ROOT / "validate"
    text = stl_ascii_solid("flipped", box((0.2, 0.2, 0.2)), CUBE_FACES, flip_normals=(2, 7))
    write(d / "S012_facet_normals" / "flipped.stl", text)
    doc = json.loads((ROOT / "gltf" / "external" / "cube.gltf").read_text())
    doc["buffers"][0]["uri"] = "model.bin"  # not there
    doc["images"], doc["textures"], doc["materials"] = [], [], []
    doc["meshes"] = [
        {"primitives": [{k: v for k, v in p.items() if k != "material"} for p in doc["meshes"][0]["primitives"]]}
    ]
    write(d / "S013_buffer_missing" / "model.gltf", json.dumps(doc, indent=1) + "\n")


def main() -> None:
    if ROOT.exists():
        shutil.rmtree(ROOT)
    make_stl()
    make_ply()
    make_gltf()
    make_collada()
    make_mixed()
    make_validate()
    for path in sorted(ROOT.rglob("*")):
        if path.is_file():
            print(path.relative_to(ROOT.parent.parent))


if __name__ == "__main__":
    main()
