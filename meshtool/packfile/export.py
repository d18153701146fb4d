"""From ``.mbin`` to other forms: OBJ/MTL/PNG (unpack), glTF binary (GLB), MuJoCo's legacy MSH, a summary."""

from __future__ import annotations

import io
import struct
from typing import Any

import numpy as np
import numpy.typing as npt

from meshtool import __version__
from meshtool.errors import PackFormatError
from meshtool.export.gltf_write import GENERATOR, Z_UP_TO_Y_UP, GltfBuilder, column_major
from meshtool.formats import MTL_SUFFIX, suffix
from meshtool.packfile.read import PackedMesh
from meshtool.packfile.view import DEFAULT_COLOUR, asset_view, unique_names
from meshtool.read.obj.mtl import Material, TextureMap, format_mtl


def _floats(values: npt.NDArray[np.float32]) -> list[str]:
    """Shortest text that reads back to the same float32 for every value."""
    return [np.format_float_positional(v, unique=True, trim="-") if v != 0 else "0" for v in values.reshape(-1)]


def unpack_files(packed: PackedMesh, name: str) -> dict[str, bytes]:
    """The mesh as ``NAME.obj`` (+ ``NAME.mtl`` and PNGs), one index per corner (``f a/a/a``).

    Reading the OBJ back (metres, Z-up) and packing it again gives the same positions, normals, uvs and
    indices as the source file, bit for bit, in lossless mode.
    """
    files: dict[str, bytes] = {}
    textures = list(packed.pack_meta.textures)
    for k, data in enumerate(packed.textures):
        files[textures[k]] = bytes(data)
    materials = [_material(m) for m in packed.materials]
    mtl_file = f"{name}{MTL_SUFFIX}" if materials else None
    lines = [f"# meshtool {__version__} normalized OBJ: units=m up=z"]
    if mtl_file:
        lines.append(f"mtllib {mtl_file}")
    p = _floats(np.asarray(packed.positions, dtype=np.float32))
    if packed.colors is not None:
        c = [repr(v / 255) if v not in (0, 255) else str(v // 255) for v in packed.colors[:, :3].reshape(-1).tolist()]
        lines += [f"v {p[i]} {p[i + 1]} {p[i + 2]} {c[i]} {c[i + 1]} {c[i + 2]}" for i in range(0, len(p), 3)]
    else:
        lines += [f"v {p[i]} {p[i + 1]} {p[i + 2]}" for i in range(0, len(p), 3)]
    if packed.uvs is not None:
        t = _floats(np.asarray(packed.uvs, dtype=np.float32))
        lines += [f"vt {t[i]} {t[i + 1]}" for i in range(0, len(t), 2)]
    if packed.normals is not None:
        n = _floats(np.asarray(packed.normals, dtype=np.float32))
        lines += [f"vn {n[i]} {n[i + 1]} {n[i + 2]}" for i in range(0, len(n), 3)]
    idx = np.asarray(packed.indices, dtype=np.int64) + 1
    if packed.uvs is not None and packed.normals is not None:
        corner = "{0}/{0}/{0}"
    elif packed.uvs is not None:
        corner = "{0}/{0}"
    elif packed.normals is not None:
        corner = "{0}//{0}"
    else:
        corner = "{0}"
    parts = list(packed.pack_meta.parts)
    show_parts = len({int(r[3]) for r in packed.submeshes}) > 1 or any(
        parts[int(r[3])] != "default" for r in packed.submeshes
    )
    current_material = current_part = -1
    for first, count, material, part in np.asarray(packed.submeshes, dtype=np.int64).tolist():
        if mtl_file and material != current_material:
            lines.append(f"usemtl {materials[material].name}")
            current_material, current_part = material, -1
        if show_parts and part != current_part:
            lines.append(f"g {parts[part]}")
            current_part = part
        for a, b, c in idx[first : first + count].tolist():
            lines.append(f"f {corner.format(a)} {corner.format(b)} {corner.format(c)}")
    obj_file = f"{name}{suffix('obj')}"
    files[obj_file] = ("\n".join(lines) + "\n").encode("utf-8")
    if mtl_file:
        files[mtl_file] = format_mtl(materials, f"meshtool {__version__} materials for {obj_file}").encode("utf-8")
    return files


def _material(m: dict[str, Any]) -> Material:
    colors = {k: (float(v[0]), float(v[1]), float(v[2])) for k, v in m.get("colors", {}).items()}
    maps = {
        k: TextureMap(str(v["file"]), {o: tuple(str(a) for a in args) for o, args in v.get("options", {}).items()}, 0)
        for k, v in m.get("maps", {}).items()
    }
    scalars = {k: float(v) for k, v in m.get("scalars", {}).items()}
    return Material(str(m["name"]), 0, colors, scalars, m.get("illum"), maps)


def to_msh(packed: PackedMesh) -> bytes:
    """MuJoCo's legacy binary mesh (``.msh``).

    Layout: int32 counts (vertices, normals, texcoords, faces), then float32 positions, normals, texcoords
    and int32 faces, all little-endian. Materials and textures are not part of the format.
    """
    v = np.ascontiguousarray(packed.positions, dtype="<f4")
    n = np.ascontiguousarray(packed.normals, dtype="<f4") if packed.normals is not None else np.zeros((0, 3), "<f4")
    t = np.ascontiguousarray(packed.uvs, dtype="<f4") if packed.uvs is not None else np.zeros((0, 2), "<f4")
    f = np.ascontiguousarray(packed.indices, dtype="<i4")
    head = struct.pack("<4i", v.shape[0], n.shape[0], t.shape[0], f.shape[0])
    return head + v.tobytes() + n.tobytes() + t.tobytes() + f.tobytes()


def to_glb(packed: PackedMesh) -> bytes:
    """A glTF binary scene with one primitive per part, materials and textures (:mod:`meshtool.export.gltf_write`).

    Vertex data stays in metres, Z-up, exactly as packed; each part's node carries :data:`Z_UP_TO_Y_UP` as its
    ``matrix``, so viewers that follow glTF's +Y-up show the asset standing upright. Texture coordinates are
    written in glTF's convention (``v`` down from the image top: ``1 - v`` of the pack's).

    Materials (one per material of the pack, :func:`meshtool.packfile.view.asset_view`): base colour and
    ``d`` as ``baseColorFactor`` (blended when ``d < 1``), the colour map as ``baseColorTexture`` (sRGB, as
    glTF defines it), the tangent-space normal map as ``normalTexture`` (linear) with its ``-bm`` strength as
    ``scale``, its primitives with ``NORMAL`` and ``TANGENT``. Other maps have no glTF slot
    (:func:`meshtool.repair.normalmaps.export_findings` lists them). Images carry no colour-space chunks.
    """
    from meshtool.repair.normalmaps import vertex_normals, vertex_tangents

    view = asset_view(packed)
    gltf = GltfBuilder(GENERATOR)
    images: dict[int, int] = {}  # view texture -> glTF texture
    materials: dict[int, int] = {}  # view material -> glTF material
    names = unique_names(m.name for m in view.materials)

    def texture(index: int | None) -> int | None:
        if index is not None and index not in images:
            images[index] = gltf.texture(_glb_image(view.textures[index].data, index))
        return images[index] if index is not None else None

    def material(index: int) -> int:
        if index not in materials:
            spec = view.materials[index] if index >= 0 else None
            if spec is None:
                materials[index] = gltf.material("material_0", [*DEFAULT_COLOUR, 1.0], None, False, False)
            else:
                base = [*spec.diffuse, spec.alpha]
                colour, normal = texture(spec.colour_map), texture(spec.normal_map)
                blend = spec.alpha < 1.0
                materials[index] = gltf.material(names[index], base, colour, blend, False, normal, spec.normal_scale)
        return materials[index]

    nodes = []
    for part in view.parts:
        glb_material = material(part.material)
        normal_mapped = part.material >= 0 and view.materials[part.material].normal_map is not None
        attributes = {"POSITION": gltf.accessor(part.positions, bounds=True)}
        normals = part.normals
        if normal_mapped and normals is None:  # a normal map needs NORMAL and TANGENT
            normals = vertex_normals(part.positions, part.faces)
        if normals is not None:
            attributes["NORMAL"] = gltf.accessor(normals)
        if part.uvs is not None:
            attributes["TEXCOORD_0"] = gltf.accessor(np.column_stack([part.uvs[:, 0], 1.0 - part.uvs[:, 1]]))
            if normal_mapped and normals is not None:
                attributes["TANGENT"] = gltf.accessor(vertex_tangents(part.positions, part.faces, normals, part.uvs))
        name = f"submesh_{part.index}"
        mesh = gltf.mesh(name, attributes, gltf.indices(part.faces, len(part.positions)), glb_material)
        nodes.append(gltf.node({"name": name, "mesh": mesh, "matrix": column_major(Z_UP_TO_Y_UP)}))
    gltf.scene("asset", nodes)
    return gltf.glb()


def _glb_image(data: bytes, index: int) -> bytes:
    """Packed texture ``index`` as an RGBA PNG without colour-space chunks (glTF fixes each slot's)."""
    from PIL import Image, UnidentifiedImageError

    try:
        image = Image.open(io.BytesIO(data)).convert("RGBA")
    except (OSError, ValueError, SyntaxError, EOFError, Image.DecompressionBombError) as exc:
        why = "unknown image format" if isinstance(exc, UnidentifiedImageError) else str(exc)
        raise PackFormatError(
            f"a texture cannot be decoded as an image (texture {index}, {type(exc).__name__}: {why})",
            hint="re-pack the asset from a valid image",
        ) from None
    image.info.clear()  # no iCCP/gAMA/cHRM/sRGB chunks: glTF fixes each slot's colour space itself
    buffer = io.BytesIO()
    image.save(buffer, format="PNG")
    return buffer.getvalue()


def describe(packed: PackedMesh) -> dict[str, Any]:
    """Counts, sections (with checksum status), sizes and the metadata of a loaded file."""
    return {
        "version": f"{packed.version[0]}.{packed.version[1]}",
        "quantized": packed.quantized,
        "vertices": int(packed.positions.shape[0]),
        "triangles": int(packed.indices.shape[0]),
        "index_type": str(packed.indices.dtype),
        "submeshes": int(packed.submeshes.shape[0]),
        "materials": [m.get("name") for m in packed.materials],
        "textures": list(packed.pack_meta.textures),
        "hulls": len(packed.hulls),
        # what each section's "crc" holds (docs/mbin-spec.md section 2)
        "checksum_algorithm": "crc32" if packed.version[1] == 0 else "xxh3-64-low32",
        "sections": [
            {
                "kind": s.kind.strip(),
                "index": s.index,
                "dtype": s.dtype,
                "shape": list(s.shape),
                "offset": s.offset,
                "bytes": s.length,
                "encoding": ("plain", "u16-box", "oct-snorm16", "deflate")[s.encoding]
                if s.encoding < 4
                else s.encoding,
                "crc": f"{s.crc:08x}",
                "checksum": {True: "ok", False: "BAD", None: "not checked"}[s.crc_ok],
            }
            for s in packed.sections
        ],
        "meta": packed.meta,
    }
