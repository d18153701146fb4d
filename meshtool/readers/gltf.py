"""glTF 2.0 reader (``.gltf`` with its buffers and images, and binary ``.glb``).

Follows the glTF 2.0 specification (https://registry.khronos.org/glTF/specs/2.0/glTF-2.0.html):

- **Geometry**: the default scene's node tree is walked; each node's matrix (or translation, rotation,
  scale) is baked into its meshes' positions and normals, winding reversed under a mirroring transform.
  Triangle lists, strips and fans are read; points and lines are skipped with a finding. Accessors may be
  interleaved (``byteStride``), normalised integers or sparse.
- **Materials**: ``baseColorFactor`` -> ``Kd`` (and ``d`` unless ``alphaMode`` is ``OPAQUE``),
  ``metallicFactor``/``roughnessFactor`` -> ``Pm``/``Pr``, ``emissiveFactor`` -> ``Ke``; base colour,
  normal and emissive textures -> ``map_Kd``/``norm``/``map_Ke``. ``KHR_texture_transform`` on the base
  colour texture is baked into the texture coordinates (offset, rotation, scale). Texture coordinates are
  flipped to the OBJ convention (``v`` up). ``COLOR_0`` becomes vertex colours.
- **Files**: external buffers and images are found and read by the asset's resolver only (the same
  containment rules as an OBJ's MTL and textures); a buffer it cannot read is an error naming the buffer.
  Embedded images (GLB buffer views and ``data:`` URIs) are registered with the resolver and converted
  like any texture.
- **Compression**: ``KHR_draco_mesh_compression`` and ``EXT_meshopt_compression`` cannot be decoded: a
  file that requires them is refused with one error line (code ``gltf-compressed``); a primitive that has
  an uncompressed fallback uses it.
- **Frame**: glTF is metres and +Y up by definition.

Locations of findings count triangles in file order.
"""

from __future__ import annotations

import hashlib
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import unquote

import numpy as np

from meshtool.errors import FormatError, MeshtoolError
from meshtool.findings import Finding, info, warning
from meshtool.obj.mtl import Material, TextureMap
from meshtool.readers.gltf_container import GLB_MAGIC, data_uri, read_container
from meshtool.readers.model import (
    FloatArray,
    IntArray,
    Piece,
    SourceFrame,
    SourceMesh,
    assemble,
    mirrors,
    transform_normals,
    transform_points,
)
from meshtool.resolve import Resolver

#: A URI with a scheme (``file://``), an absolute path, or a Windows drive path: outside any asset's root.
_ABSOLUTE = re.compile(r"^(?:[A-Za-z][A-Za-z0-9+.-]*://|/|\\|[A-Za-z]:[\\/])")

FRAME = SourceFrame(1.0, "glTF 2.0 (metres by the specification)", "y", "glTF 2.0 (+Y up by the specification)")
COMPRESSION = {"KHR_draco_mesh_compression": "Draco", "EXT_meshopt_compression": "meshopt"}
_COMPONENT = {5120: "i1", 5121: "u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_NORMALISE = {5120: 127.0, 5121: 255.0, 5122: 32767.0, 5123: 65535.0}
_MAX_DEPTH = 256
#: Most elements of an accessor without a bufferView (all zeros): such an accessor costs no bytes in the file.
_MAX_UNBACKED = 1 << 24
_MIME_SUFFIX = {"image/png": ".png", "image/jpeg": ".jpg", "image/webp": ".webp", "image/ktx2": ".ktx2"}


def read_gltf(data: bytes, path: str, src: Path, resolver: Resolver) -> SourceMesh:
    """Read a ``.gltf`` or ``.glb`` file.

    Args:
        data: The file's bytes.
        path: Name for findings and errors.
        src: The file (its folder is the base of relative URIs).
        resolver: The asset's resolver: reads external buffers and images, holds embedded images.

    Returns:
        The mesh with one part per node that has a mesh, and its materials.

    Raises:
        FormatError: Not glTF 2.0, damaged JSON or binary chunks, a buffer that is missing, outside the
            asset folder or too short, an accessor out of range, or compression meshtool cannot decode.
    """
    doc, glb_bin = read_container(data, path)
    reader = _Reader(doc, glb_bin, path, src, resolver)
    try:
        return reader.read("glb" if data[:4] == GLB_MAGIC else "gltf")
    except MeshtoolError:
        raise
    except (TypeError, ValueError, KeyError, IndexError, AttributeError, OverflowError) as exc:
        # a value of the wrong JSON type or range somewhere (a string where a count belongs, ...)
        what = str(exc).splitlines()[0][:100] if str(exc) else type(exc).__name__
        raise FormatError(f"malformed glTF: {what}", path=path, hint="the file is damaged; export it again") from None


@dataclass(slots=True)
class _Reader:
    doc: dict[str, Any]
    glb_bin: bytes | None
    path: str
    src: Path
    resolver: Resolver
    findings: list[Finding] = field(default_factory=list)
    buffers: dict[int, bytes] = field(default_factory=dict)
    images: dict[int, str | None] = field(default_factory=dict)
    triangles: int = 0
    compressed: list[str] = field(default_factory=list)
    skipped_modes: dict[int, int] = field(default_factory=dict)
    sources: list[dict[str, str]] = field(default_factory=list)

    def read(self, fmt: str) -> SourceMesh:
        required = set(self.doc.get("extensionsRequired") or [])
        for ext, what in COMPRESSION.items():
            if ext in required:
                raise FormatError(
                    f"uses {what} compression ({ext}), which meshtool cannot decode",
                    path=self.path,
                    hint="export it uncompressed (e.g. gltf-transform copy with no compression, or Blender "
                    "without Draco)",
                    code="gltf-compressed",
                )
        materials, transforms = self._materials()
        pieces: list[Piece] = []
        nodes = self._list("nodes")
        scenes = self._list("scenes")
        scene_index = self.doc.get("scene", 0)
        if scenes:
            scene = scenes[scene_index] if isinstance(scene_index, int) and 0 <= scene_index < len(scenes) else {}
            roots = list(scene.get("nodes") or [])
        else:  # no scene: every root node
            children = {c for n in nodes for c in (n.get("children") or [])}
            roots = [i for i in range(len(nodes)) if i not in children]
        stack: list[tuple[int, FloatArray, int]] = [(int(r), np.eye(4), 0) for r in reversed(roots)]
        visited: set[int] = set()
        while stack:
            index, parent, depth = stack.pop()
            if not (0 <= index < len(nodes)) or index in visited or depth > _MAX_DEPTH:
                raise FormatError(
                    f"node {index} is missing, repeated or nested too deep in the scene tree",
                    path=self.path,
                    hint="the file is damaged",
                )
            visited.add(index)
            node = nodes[index]
            world = parent @ _local(node, self.path, index)
            if "mesh" in node:
                name = str(node.get("name") or "") or self._mesh_name(node["mesh"]) or f"node{index}"
                pieces.extend(self._mesh(int(node["mesh"]), world, name, materials, transforms))
            for child in reversed(node.get("children") or []):
                stack.append((int(child), world, depth + 1))
        for mode, count in sorted(self.skipped_modes.items()):
            kind = "point" if mode == 0 else "line"
            self.findings.append(
                info(f"{kind}s-skipped", f"{count} {kind} primitive(s) skipped: not surface geometry", self.path)
            )
        if self.compressed:
            self.findings.append(
                warning(
                    "gltf-compressed-fallback",
                    f"{len(self.compressed)} primitive(s) are {'/'.join(sorted(set(self.compressed)))} compressed: "
                    "their uncompressed fallback data was read",
                    self.path,
                )
            )
        record = {
            "generator": str((self.doc.get("asset") or {}).get("generator", ""))[:100],
            "nodes": len(nodes),
            "meshes": len(self._list("meshes")),
            "extensions_used": sorted(str(e) for e in self.doc.get("extensionsUsed") or []),
        }
        mesh = assemble(pieces, self.path, fmt, "triangle", materials, FRAME, self.findings, record)
        mesh.sources = self.sources
        return mesh

    # -- documents -------------------------------------------------------------------------------------

    def _list(self, key: str) -> list[dict[str, Any]]:
        value = self.doc.get(key) or []
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            raise FormatError(f"glTF '{key}' is not a list of objects", path=self.path, hint="the file is damaged")
        return value

    def _item(self, key: str, index: Any) -> dict[str, Any]:
        items = self._list(key)
        if not isinstance(index, int) or not 0 <= index < len(items):
            raise FormatError(
                f"glTF refers to {key}[{index}], which does not exist", path=self.path, hint="the file is damaged"
            )
        return items[index]

    def _mesh_name(self, index: Any) -> str:
        return str(self._item("meshes", index).get("name") or "")

    # -- binary data -----------------------------------------------------------------------------------

    def _buffer(self, index: int) -> bytes:
        if index in self.buffers:
            return self.buffers[index]
        buffer = self._item("buffers", index)
        uri = buffer.get("uri")
        if uri is None:
            if index != 0 or self.glb_bin is None:
                raise FormatError(f"buffer {index} has no uri and there is no GLB binary chunk", path=self.path)
            data = self.glb_bin
        elif str(uri).startswith("data:"):
            data = data_uri(str(uri), self.path, f"buffer {index}")
        else:
            data = self._external(str(uri), "buffer", f"buffer {index}")
        length = int(buffer.get("byteLength", len(data)))
        if len(data) < length:
            raise FormatError(
                f"buffer {index} has {len(data)} bytes, the file says byteLength {length}",
                path=self.path,
                hint="the .bin file does not belong to this glTF or was cut short",
                code="gltf-buffer-missing",
            )
        self.buffers[index] = data
        return data

    def _external(self, uri: str, kind: str, what: str) -> bytes:
        res = self.resolver.resolve(unquote(uri), self.src.parent, kind, self.path, 0)
        if res.found is None:
            outside = any(f.code == "reference-outside-root" for f in res.findings)
            reason = "is outside the asset folder" if outside else "was not found"
            hint = "add its folder with --search-path" if outside else "put the file beside the glTF"
            if _ABSOLUTE.match(uri):  # never read where it points: only looked for by name inside the roots
                name = unquote(uri).replace("\\", "/").rstrip("/").rsplit("/", 1)[-1]
                reason = f"is an absolute URI outside the asset's root ({name!r} is not inside it either)"
                hint = "make the uri relative to the glTF and put the file there, or add its folder with --search-path"
            raise FormatError(
                f"{what} {uri!r} {reason}; the geometry cannot be read without it",
                path=self.path,
                hint=hint,
                code="gltf-buffer-missing",
            )
        data = self.resolver.read_resolution(res, "other")
        shown = self.resolver.display(res.found, resolved=True) if res.found is not None else uri
        self.sources.append({"role": kind, "path": shown, "sha256": hashlib.sha256(data).hexdigest()})
        return data

    def _view(self, index: int) -> tuple[bytes, int, int, int | None]:
        view = self._item("bufferViews", index)
        if "extensions" in view and "EXT_meshopt_compression" in view["extensions"]:
            self.compressed.append("meshopt")
        data = self._buffer(int(view.get("buffer", -1)))
        offset, length = int(view.get("byteOffset", 0)), int(view.get("byteLength", 0))
        if offset < 0 or length < 0 or offset + length > len(data):
            raise FormatError(
                f"bufferView {index} (bytes {offset}..{offset + length}) runs past its buffer ({len(data)} bytes)",
                path=self.path,
                hint="the file is damaged",
            )
        stride = view.get("byteStride")
        return data, offset, length, int(stride) if stride else None

    def accessor(self, index: Any) -> FloatArray:
        """Accessor ``index`` as float64 (normalised integers mapped to 0..1 / -1..1), shape (count, width)."""
        acc = self._item("accessors", index)
        ctype, atype = acc.get("componentType"), acc.get("type")
        if ctype not in _COMPONENT or atype not in _WIDTH:
            raise FormatError(f"accessor {index} has an unknown type {atype}/{ctype}", path=self.path)
        width, count = _WIDTH[atype], int(acc.get("count", 0))
        dtype = np.dtype(_COMPONENT[ctype])
        if count < 0:
            raise FormatError(f"accessor {index} has a negative count", path=self.path)
        if "bufferView" in acc:
            data, view_start, length, stride = self._view(int(acc["bufferView"]))
            extra = int(acc.get("byteOffset", 0))
            start = view_start + extra
            item = dtype.itemsize * width
            stride = stride or item
            need = (count - 1) * stride + item if count else 0
            if extra < 0 or extra + need > length:
                raise FormatError(
                    f"accessor {index} ({count} x {atype}) runs past its bufferView",
                    path=self.path,
                    hint="the file is damaged",
                )
            raw = (
                np.ndarray((count, width), dtype, data, start, (stride, dtype.itemsize))
                if count
                else np.zeros((0, width), dtype)
            )
            values = raw.astype(np.float64)
        else:
            if count > _MAX_UNBACKED:
                raise FormatError(f"accessor {index} has {count} elements and no data", path=self.path)
            values = np.zeros((count, width))
        if acc.get("normalized") and ctype in _NORMALISE:
            values = np.maximum(values / _NORMALISE[ctype], -1.0)
        sparse = acc.get("sparse")
        if sparse:
            values = values.copy()
            n = int(sparse.get("count", 0))
            idx_info, val_info = sparse.get("indices") or {}, sparse.get("values") or {}
            idx = self._sparse(idx_info, n, _COMPONENT.get(int(idx_info.get("componentType", 5125)), "<u4"), 1).reshape(
                -1
            )
            vals = self._sparse(val_info, n, _COMPONENT[ctype], width)
            if acc.get("normalized") and ctype in _NORMALISE:
                vals = np.maximum(vals / _NORMALISE[ctype], -1.0)
            if idx.size and (idx.min() < 0 or idx.max() >= count):
                raise FormatError(f"accessor {index}: sparse index out of range", path=self.path)
            values[idx.astype(np.int64)] = vals
        return values

    def _sparse(self, info_: dict[str, Any], count: int, dtype_text: str, width: int) -> FloatArray:
        data, start, _, _ = self._view(int(info_.get("bufferView", -1)))
        start += int(info_.get("byteOffset", 0))
        dtype = np.dtype(dtype_text)
        if start + count * width * dtype.itemsize > len(data):
            raise FormatError("sparse accessor runs past its buffer", path=self.path)
        out: FloatArray = np.frombuffer(data, dtype, count * width, start).astype(np.float64).reshape(count, width)
        return out

    # -- meshes ----------------------------------------------------------------------------------------

    def _mesh(
        self,
        index: int,
        world: FloatArray,
        name: str,
        materials: list[Material],
        transforms: dict[int, tuple[FloatArray | None, int]],
    ) -> list[Piece]:
        mesh = self._item("meshes", index)
        flip = mirrors(world)
        pieces = []
        for prim in mesh.get("primitives") or []:
            if not isinstance(prim, dict):
                continue
            mode = int(prim.get("mode", 4))
            if mode in (0, 1, 2, 3):
                self.skipped_modes[mode] = self.skipped_modes.get(mode, 0) + 1
                continue
            extensions = prim.get("extensions") or {}
            for ext, what in COMPRESSION.items():
                if ext in extensions:
                    self.compressed.append(what)
            attributes = prim.get("attributes") or {}
            if "POSITION" not in attributes:
                continue
            positions = self.accessor(attributes["POSITION"])[:, :3]
            n = positions.shape[0]
            if "indices" in prim:
                indices = self.accessor(prim["indices"]).reshape(-1).astype(np.int64)
                if indices.size and (indices.min() < 0 or indices.max() >= n):
                    raise FormatError(
                        f"mesh {index} ({name!r}): an index is beyond its {n} vertices",
                        path=self.path,
                        hint="the file is damaged",
                    )
            else:
                indices = np.arange(n, dtype=np.int64)
            faces = _triangles(indices, mode)
            if flip:
                faces = faces[:, ::-1].copy()
            material = int(prim.get("material", -1))
            if material >= len(materials):
                material = -1
            uvs = None
            matrix, uv_index = transforms.get(material, (None, 0))
            key = f"TEXCOORD_{uv_index}"
            if key in attributes:
                uvs = self.accessor(attributes[key])[:, :2]
                if matrix is not None:
                    uvs = uvs @ matrix[:2, :2].T + matrix[:2, 2]
                uvs = np.stack([uvs[:, 0], 1.0 - uvs[:, 1]], axis=1)  # glTF v points down, OBJ v up
            normals = None
            if "NORMAL" in attributes:
                normals = transform_normals(world, self.accessor(attributes["NORMAL"])[:, :3])
            colors = None
            if "COLOR_0" in attributes:
                colors = self.accessor(attributes["COLOR_0"])[:, :3]
            locations = np.arange(self.triangles + 1, self.triangles + faces.shape[0] + 1, dtype=np.int64)
            self.triangles += faces.shape[0]
            pieces.append(
                Piece(name, material, transform_points(world, positions), faces, locations, uvs, normals, colors)
            )
        return pieces

    # -- materials -------------------------------------------------------------------------------------

    def _materials(self) -> tuple[list[Material], dict[int, tuple[FloatArray | None, int]]]:
        out: list[Material] = []
        transforms: dict[int, tuple[FloatArray | None, int]] = {}
        for i, mat in enumerate(self._list("materials")):
            name = str(mat.get("name") or f"material{i}")
            pbr = mat.get("pbrMetallicRoughness") or {}
            sg = (mat.get("extensions") or {}).get("KHR_materials_pbrSpecularGlossiness") or {}
            factor = pbr.get("baseColorFactor") or sg.get("diffuseFactor") or [1.0, 1.0, 1.0, 1.0]
            rgba = [_unit(v) for v in list(factor)[:4]] + [1.0] * (4 - len(list(factor)[:4]))
            material = Material(name, 0, colors={"Kd": (rgba[0], rgba[1], rgba[2])}, illum=2)
            if str(mat.get("alphaMode", "OPAQUE")) != "OPAQUE" and rgba[3] < 1.0:
                material.scalars["d"] = rgba[3]
            if "metallicFactor" in pbr or pbr:
                material.scalars["Pm"] = _unit(pbr.get("metallicFactor", 1.0))
                material.scalars["Pr"] = _unit(pbr.get("roughnessFactor", 1.0))
            emissive = mat.get("emissiveFactor")
            if isinstance(emissive, list) and len(emissive) == 3 and any(_unit(v) > 0 for v in emissive):
                material.colors["Ke"] = (_unit(emissive[0]), _unit(emissive[1]), _unit(emissive[2]))
            base = pbr.get("baseColorTexture") or sg.get("diffuseTexture")
            matrix: FloatArray | None = None
            uv_set = 0
            for key, ref in (
                ("map_Kd", base),
                ("norm", mat.get("normalTexture")),
                ("map_Ke", mat.get("emissiveTexture")),
            ):
                if not isinstance(ref, dict):
                    continue
                image = self._texture_image(ref.get("index"))
                if image is None:
                    continue
                material.maps[key] = TextureMap(image, {}, 0)
                if key == "map_Kd":
                    matrix, uv_set = self._texture_transform(ref, name)
            transforms[i] = (matrix, uv_set)
            out.append(material)
        return out, transforms

    def _texture_transform(self, ref: dict[str, Any], material: str) -> tuple[FloatArray | None, int]:
        """The 3x3 ``KHR_texture_transform`` matrix (glTF uv space) and the TEXCOORD set the texture uses."""
        uv_set = int(ref.get("texCoord", 0))
        ext = (ref.get("extensions") or {}).get("KHR_texture_transform")
        if not isinstance(ext, dict):
            return None, uv_set
        ox, oy = [*list(ext.get("offset") or []), 0.0, 0.0][:2]
        sx, sy = [*list(ext.get("scale") or []), 1.0, 1.0][:2]
        r = float(ext.get("rotation", 0.0))
        if not all(math.isfinite(float(v)) for v in (ox, oy, sx, sy, r)):
            self.findings.append(
                warning(
                    "gltf-texture-transform", f"material {material!r}: non-finite texture transform ignored", self.path
                )
            )
            return None, uv_set
        uv_set = int(ext.get("texCoord", uv_set))
        c, s = math.cos(r), math.sin(r)
        translation = np.array([[1, 0, ox], [0, 1, oy], [0, 0, 1]], dtype=np.float64)
        rotation = np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]], dtype=np.float64)
        scale = np.array([[sx, 0, 0], [0, sy, 0], [0, 0, 1]], dtype=np.float64)
        self.findings.append(
            info(
                "gltf-texture-transform",
                f"material {material!r}: KHR_texture_transform baked into the texture coordinates",
                self.path,
            )
        )
        result: FloatArray = translation @ rotation @ scale
        return result, uv_set

    def _texture_image(self, index: Any) -> str | None:
        """The resolver reference of texture ``index``'s image (``None`` with a finding when it has none)."""
        texture = self._item("textures", index)
        source = texture.get("source")
        for ext in ("EXT_texture_webp", "KHR_texture_basisu", "MSFT_texture_dds"):
            alt = (texture.get("extensions") or {}).get(ext)
            if source is None and isinstance(alt, dict):
                source = alt.get("source")
        if source is None:
            self.findings.append(warning("texture-missing", f"texture {index} has no image: dropped", self.path))
            return None
        if source in self.images:
            return self.images[source]
        image = self._item("images", source)
        label = str(image.get("name") or f"image{source}")
        ref: str | None
        uri = image.get("uri")
        if uri is not None and not str(uri).startswith("data:"):
            ref = unquote(str(uri))
        else:
            try:
                if uri is not None:
                    blob = data_uri(str(uri), self.path, f"image {source}")
                    mime = str(uri)[5:].split(";", 1)[0].split(",", 1)[0]
                else:
                    data, start, length, _ = self._view(int(image.get("bufferView", -1)))
                    blob = data[start : start + length]
                    mime = str(image.get("mimeType", ""))
            except FormatError as exc:
                self.findings.append(
                    warning("texture-unreadable", f"image {source}: {exc.message}: dropped", self.path)
                )
                self.images[source] = None
                return None
            ref = self.resolver.embed(self.src, f"{label}{_MIME_SUFFIX.get(mime, '')}", blob)
        self.images[source] = ref
        return ref


def _local(node: dict[str, Any], path: str, index: int) -> FloatArray:
    """A node's local 4x4 transform: ``matrix`` (column-major) or T @ R @ S."""
    try:
        if "matrix" in node:
            values = [float(v) for v in node["matrix"]]
            if len(values) != 16:
                raise ValueError("matrix needs 16 numbers")
            matrix = np.asarray(values, dtype=np.float64).reshape(4, 4).T
        else:
            t = [float(v) for v in node.get("translation", [0.0, 0.0, 0.0])]
            x, y, z, w = (float(v) for v in node.get("rotation", [0.0, 0.0, 0.0, 1.0]))
            s = [float(v) for v in node.get("scale", [1.0, 1.0, 1.0])]
            norm = math.sqrt(x * x + y * y + z * z + w * w) or 1.0
            x, y, z, w = x / norm, y / norm, z / norm, w / norm
            rotation = np.array(
                [
                    [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                    [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                    [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
                ]
            )
            matrix = np.eye(4)
            matrix[:3, :3] = rotation * np.asarray(s, dtype=np.float64)
            matrix[:3, 3] = t
    except (TypeError, ValueError) as exc:
        raise FormatError(
            f"node {index} has a malformed transform ({exc})", path=path, hint="the file is damaged"
        ) from None
    if not np.isfinite(matrix).all():
        raise FormatError(f"node {index} has a non-finite transform", path=path, hint="the file is damaged")
    return matrix


def _triangles(indices: IntArray, mode: int) -> IntArray:
    """(m, 3) triangles from a list (4), strip (5) or fan (6) of indices."""
    if mode == 5:
        n = indices.size - 2
        if n <= 0:
            return np.zeros((0, 3), dtype=np.int64)
        k = np.arange(n)
        even = k % 2 == 0
        a = indices[k]
        b = np.where(even, indices[k + 1], indices[k + 2])
        c = np.where(even, indices[k + 2], indices[k + 1])
        return np.stack([a, b, c], axis=1)
    if mode == 6:
        n = indices.size - 2
        if n <= 0:
            return np.zeros((0, 3), dtype=np.int64)
        k = np.arange(1, n + 1)
        return np.stack([np.full(n, indices[0]), indices[k], indices[k + 1]], axis=1)
    m = indices.size // 3
    return indices[: m * 3].reshape(m, 3)


def _unit(value: Any) -> float:
    """A 0..1 factor (non-numbers and non-finite values become 1, others are clamped)."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        return 1.0
    return min(max(v, 0.0), 1.0) if math.isfinite(v) else 1.0
