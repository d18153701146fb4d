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
- **Hostile files**: the JSON is checked before any binary data is read (:mod:`meshtool.read.gltf_checks`:
  indices in range, node tree, strides, accessors inside their views, topology); what every node that
  instances a mesh will produce is charged to the file's :class:`~meshtool.read.budget.ExpansionBudget`
  and the primitive instances are counted (at most :data:`~meshtool.read.budget.MAX_INSTANCES`)
  before anything is decoded, and each primitive is decoded once however many nodes instance it.

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
import numpy.typing as npt

from meshtool.errors import FormatError, MeshtoolError
from meshtool.files.resolve import Resolver
from meshtool.findings import Finding, info, warning
from meshtool.formats import IMAGE_SUFFIXES
from meshtool.read.budget import INSTANCES_ENV, ExpansionBudget
from meshtool.read.gltf_checks import (
    MAX_ZERO_FILLED,
    Document,
    Layout,
    Primitive,
    View,
    max_primitives,
    whole,
)
from meshtool.read.gltf_container import GLB_MAGIC, data_uri, read_container
from meshtool.read.obj.mtl import Material, TextureMap
from meshtool.read.source_mesh import (
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

#: A URI with a scheme (``file://``), an absolute path, or a Windows drive path: outside any asset's root.
_ABSOLUTE = re.compile(r"^(?:[A-Za-z][A-Za-z0-9+.-]*://|/|\\|[A-Za-z]:[\\/])")

FRAME = SourceFrame(1.0, "glTF 2.0 (metres by the specification)", "y", "glTF 2.0 (+Y up by the specification)")
COMPRESSION = {"KHR_draco_mesh_compression": "Draco", "EXT_meshopt_compression": "meshopt"}
_NORMALISE = {5120: 127.0, 5121: 255.0, 5122: 32767.0, 5123: 65535.0}


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
            asset folder or too short, an index, accessor or node tree the specification forbids
            (:mod:`meshtool.read.gltf_checks`), more geometry than the expansion budget allows (code
            ``expansion-limit``), or compression meshtool cannot decode.
    """
    doc, glb_bin, bin_offset = read_container(data, path)
    findings: list[Finding] = []
    checked = Document(doc, path, findings, bin_offset if glb_bin is not None else None)
    reader = _Reader(checked, glb_bin, path, src, resolver, ExpansionBudget.for_file(path), findings)
    try:
        return reader.read("glb" if data[:4] == GLB_MAGIC else "gltf")
    except MeshtoolError:
        raise
    except (TypeError, ValueError, KeyError, IndexError, AttributeError, OverflowError) as exc:
        # a value of the wrong JSON type or range somewhere (a string where a count belongs, ...)
        what = str(exc).splitlines()[0][:100] if str(exc) else type(exc).__name__
        raise FormatError(f"malformed glTF: {what}", path=path, hint="the file is damaged; export it again") from None


#: A primitive decoded once for all the nodes that instance its mesh: positions, faces, uvs, normals, colours.
_Decoded = tuple[FloatArray, IntArray, FloatArray | None, FloatArray | None, FloatArray | None]


@dataclass(slots=True)
class _Reader:
    doc: Document
    glb_bin: bytes | None
    path: str
    src: Path
    resolver: Resolver
    budget: ExpansionBudget
    findings: list[Finding]
    buffers: dict[int, bytes] = field(default_factory=dict)
    images: dict[int, str | None] = field(default_factory=dict)
    decoded: dict[tuple[int, int], _Decoded] = field(default_factory=dict)
    triangles: int = 0
    compressed: list[str] = field(default_factory=list)
    skipped_modes: dict[int, int] = field(default_factory=dict)
    sources: list[dict[str, str]] = field(default_factory=list)

    def read(self, fmt: str) -> SourceMesh:
        required = self.doc.doc.get("extensionsRequired") or []
        for ext, what in COMPRESSION.items():
            if isinstance(required, list) and ext in required:
                raise FormatError(
                    f"uses {what} compression ({ext}), which meshtool cannot decode",
                    path=self.path,
                    hint="export it uncompressed (e.g. gltf-transform copy with no compression, or Blender "
                    "without Draco)",
                    code="gltf-compressed",
                )
        materials, transforms = self._materials()
        uv_sets = {m: uv for m, (_, uv) in transforms.items()}
        nodes = self.doc.items("nodes")
        # every instance is counted and charged from the JSON alone, before any buffer is read or decoded
        placed: list[tuple[int, FloatArray, int]] = []
        instances = zero_filled = 0
        most = max_primitives()
        for index, world in self.doc.walk(lambda node, i: _local(node, self.path, i)):
            if nodes[index].get("mesh") is None:
                continue
            mesh = self.doc.mesh(nodes[index]["mesh"], f"node {index}", uv_sets)
            what = f"node {index} instancing mesh {mesh.index} ({len(mesh.primitives)} primitive(s))"
            self.budget.charge(mesh.triangles, mesh.vertices, what)
            instances += len(mesh.primitives)
            zero_filled += mesh.zero_filled
            if instances > most:
                self._refuse(f"{most:,} mesh primitive instances (at least {instances:,} with {what})", INSTANCES_ENV)
            if zero_filled > MAX_ZERO_FILLED:
                self._refuse(
                    f"{MAX_ZERO_FILLED:,} zero-filled accessor elements (accessors without a bufferView: at least "
                    f"{zero_filled:,} with {what})",
                    None,
                )
            placed.append((index, world, mesh.index))
        pieces: list[Piece] = []
        for index, world, mesh_index in placed:
            pieces.extend(self._instance(index, world, mesh_index, transforms))
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
            "generator": str((self.doc.doc.get("asset") or {}).get("generator", ""))[:100],
            "nodes": len(nodes),
            "meshes": len(self.doc.items("meshes")),
            "extensions_used": sorted(str(e) for e in self.doc.doc.get("extensionsUsed") or []),
        }
        result = assemble(pieces, self.path, fmt, "triangle", materials, FRAME, self.findings, record)
        result.sources = self.sources
        return result

    def _refuse(self, what: str, env: str | None) -> None:
        hint = f"check the file; for a genuine scene this large set {env}" if env else "export it with its buffers"
        raise FormatError(f"places more than {what}; not read", path=self.path, hint=hint, code="expansion-limit")

    # -- binary data -----------------------------------------------------------------------------------

    def _buffer(self, index: int) -> bytes:
        if index in self.buffers:
            return self.buffers[index]
        buffer = self.doc.items("buffers")[index]
        uri = buffer.get("uri")
        if uri is None:
            if index != 0 or self.glb_bin is None:
                raise FormatError(f"buffer {index} has no uri and there is no GLB binary chunk", path=self.path)
            data = self.glb_bin
        elif str(uri).startswith("data:"):
            data = data_uri(str(uri), self.path, f"buffer {index}")
        else:
            data = self._external(str(uri), "buffer", f"buffer {index}")
        length = whole(buffer.get("byteLength", len(data)), f"buffer {index} byteLength", self.path)
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

    def _bytes(self, view: View) -> bytes:
        """The buffer of a checked bufferView, which holds the view's bytes (checked here)."""
        if "EXT_meshopt_compression" in (self.doc.items("bufferViews")[view.index].get("extensions") or {}):
            self.compressed.append("meshopt")
        data = self._buffer(view.buffer)
        if view.offset + view.length > len(data):
            raise self.doc.error(
                f"bufferView {view.index} (bytes {view.offset}..{view.offset + view.length}) runs past buffer "
                f"{view.buffer} ({len(data)} bytes)",
                self.doc.file_offset(view.buffer, view.offset),
            )
        return data

    def _raw(self, lay: Layout) -> npt.NDArray[Any]:
        """A checked accessor's elements in their own component type, shape (count, width), sparse applied."""
        raw: npt.NDArray[Any] = np.zeros((lay.count, lay.width), lay.dtype)
        if lay.view is not None and lay.count:
            data, start = self._bytes(lay.view), lay.view.offset + lay.offset
            raw = np.ndarray((lay.count, lay.width), lay.dtype, data, start, (lay.stride, lay.dtype.itemsize))
        sparse = lay.sparse
        if sparse is not None and sparse.count:
            raw = np.array(raw)
            start = sparse.indices.offset + sparse.indices_offset
            at = np.frombuffer(self._bytes(sparse.indices), sparse.indices_dtype, sparse.count, start)
            if int(at.max()) >= lay.count:
                k = int(np.argmax(at >= lay.count))
                raise self.doc.error(
                    f"accessor {lay.index}: sparse index {int(at[k])} (entry {k}) is beyond its {lay.count} elements "
                    "(glTF 2.0 §3.6.2.3)",
                    self.doc.file_offset(sparse.indices.buffer, start + k * sparse.indices_dtype.itemsize),
                )
            start = sparse.values.offset + sparse.values_offset
            values = np.frombuffer(self._bytes(sparse.values), lay.dtype, sparse.count * lay.width, start)
            raw[at.astype(np.int64)] = values.reshape(sparse.count, lay.width)
        return raw

    def values(self, lay: Layout) -> FloatArray:
        """A checked accessor as float64 (normalised integers mapped to 0..1 / -1..1), shape (count, width)."""
        with np.errstate(invalid="ignore"):  # a signalling NaN; non-finite values are replaced downstream
            values: FloatArray = self._raw(lay).astype(np.float64)
        if lay.normalized and lay.ctype in _NORMALISE:
            values = np.maximum(values / _NORMALISE[lay.ctype], -1.0)
        return values

    # -- meshes ----------------------------------------------------------------------------------------

    def _instance(
        self, index: int, world: FloatArray, mesh: int, transforms: dict[int, tuple[FloatArray | None, int]]
    ) -> list[Piece]:
        """The pieces node ``index`` places: mesh ``mesh`` (checked and charged) transformed by ``world``."""
        node = self.doc.items("nodes")[index]
        name = str(node.get("name") or "") or str(self.doc.items("meshes")[mesh].get("name") or "") or f"node{index}"
        prims, skipped = self.doc.meshes[mesh].primitives, self.doc.meshes[mesh].skipped
        for mode, count in skipped.items():
            self.skipped_modes[mode] = self.skipped_modes.get(mode, 0) + count
        flip = mirrors(world)
        pieces = []
        for prim in prims:
            if prim.compressed is not None:
                self.compressed.append(COMPRESSION[prim.compressed])
            key = (prim.mesh, prim.number)
            if key not in self.decoded:
                self.decoded[key] = self._decode(prim, transforms.get(prim.material, (None, 0))[0])
            positions, faces, uvs, normals, colors = self.decoded[key]
            if flip:
                faces = faces[:, ::-1].copy()
            locations = np.arange(self.triangles + 1, self.triangles + faces.shape[0] + 1, dtype=np.int64)
            self.triangles += faces.shape[0]
            placed = None if normals is None else transform_normals(world, normals)
            pieces.append(
                Piece(name, prim.material, transform_points(world, positions), faces, locations, uvs, placed, colors)
            )
        return pieces

    def _decode(self, prim: Primitive, matrix: FloatArray | None) -> _Decoded:
        """A primitive's vertex data (in the mesh's frame) and triangles; indices checked against POSITION."""
        positions = self.values(prim.position)
        n = positions.shape[0]
        if prim.indices is not None:
            indices = self._raw(prim.indices).reshape(-1).astype(np.int64)
            if indices.size and int(indices.max()) >= n:
                k = int(np.argmax(indices >= n))
                lay = prim.indices
                offset = None
                if lay.view is not None and lay.sparse is None:
                    offset = self.doc.file_offset(lay.view.buffer, lay.view.offset + lay.offset + k * lay.stride)
                raise self.doc.error(
                    f"mesh {prim.mesh} primitive {prim.number}: index {int(indices[k])} (element {k} of accessor "
                    f"{lay.index}) is beyond the {n} vertices of POSITION accessor {prim.position.index} "
                    "(glTF 2.0 §3.7.2.1)",
                    offset,
                )
        else:
            indices = np.arange(n, dtype=np.int64)
        faces = _triangles(indices, prim.mode)
        uvs = None
        if prim.uvs is not None:
            uvs = self.values(prim.uvs)
            if matrix is not None:
                with np.errstate(invalid="ignore", over="ignore"):  # non-finite coordinates are replaced downstream
                    uvs = uvs @ matrix[:2, :2].T + matrix[:2, 2]
            uvs = np.stack([uvs[:, 0], 1.0 - uvs[:, 1]], axis=1)  # glTF v points down, OBJ v up
        normals = None if prim.normals is None else self.values(prim.normals)
        colors = None if prim.colors is None else self.values(prim.colors)[:, :3]
        return positions, faces, uvs, normals, colors

    # -- materials -------------------------------------------------------------------------------------

    def _materials(self) -> tuple[list[Material], dict[int, tuple[FloatArray | None, int]]]:
        out: list[Material] = []
        transforms: dict[int, tuple[FloatArray | None, int]] = {}
        for i, mat in enumerate(self.doc.items("materials")):
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
        texture = self.doc.item("textures", index, "a material")
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
        image = self.doc.item("images", source, f"texture {index}")
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
                    view = self.doc.view(self.doc.index("bufferViews", image.get("bufferView"), f"image {source}"))
                    blob = self._bytes(view)[view.offset : view.offset + view.length]
                    mime = str(image.get("mimeType", ""))
            except FormatError as exc:
                self.findings.append(
                    warning("texture-unreadable", f"image {source}: {exc.message}: dropped", self.path)
                )
                self.images[source] = None
                return None
            ref = self.resolver.embed(self.src, f"{label}{IMAGE_SUFFIXES.get(mime, '')}", blob)
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


def read(data: bytes, path: str, src: Path, resolver: Resolver) -> SourceMesh:
    """The formats registry's reader (:data:`meshtool.formats.MESH_FORMATS`): :func:`read_gltf`."""
    return read_gltf(data, path, src, resolver)
