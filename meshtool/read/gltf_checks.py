"""Checks of a glTF 2.0 document's structure, made on the JSON before any binary data is read or allocated.

Split out of :mod:`meshtool.read.gltf`, which decodes what these checks let through. Section numbers are
those of the glTF 2.0 specification (https://registry.khronos.org/glTF/specs/2.0/glTF-2.0.html):

- every index (scene, node, mesh, accessor, bufferView, buffer, material) is a whole number in range;
- the node hierarchy is a set of disjoint strict trees (§3.5.2): no cycle, no node with two parents; it is
  walked without recursion and refused deeper than :data:`MAX_DEPTH`; every combined transform is finite;
- a bufferView lies inside its buffer's ``byteLength`` (§5.11); an accessor's ``componentType`` and ``type``
  are glTF 2.0 values (§3.6.2.2), its ``byteStride`` is at least its element size and it fits its
  bufferView: ``byteOffset + stride * (count - 1) + element size <= byteLength`` (§3.6.2.4); a sparse
  accessor's ``count`` is at most the accessor's and its indices and values fit their bufferViews (§3.6.2.3);
- a primitive's topology is 0..6, its POSITION is VEC3, its indices SCALAR unsigned, a triangle list has a
  multiple of 3 vertex indices (§3.7.2.1). An optional attribute (NORMAL, TEXCOORD_n, COLOR_0) of the wrong
  type or of a count other than POSITION's (all attributes of a primitive have the same count, §3.7.2.1)
  is dropped for that primitive with a ``gltf-attribute-dropped`` warning.

What every primitive of a mesh produces (triangles, vertices) follows from the accessor counts alone, so
:meth:`Document.mesh` lets the reader charge each node that instances a mesh to the file's
:class:`~meshtool.read.budget.ExpansionBudget` before decoding anything.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from meshtool.errors import FormatError
from meshtool.findings import Finding, warning
from meshtool.read.budget import INSTANCES_ENV, MAX_INSTANCES, limit_from_env
from meshtool.read.source_mesh import FloatArray

COMPONENT = {5120: "i1", 5121: "u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_INDEX_TYPES = (5121, 5123, 5125)
_COMPRESSION = ("KHR_draco_mesh_compression", "EXT_meshopt_compression")
#: Accessor types an optional attribute may have (§3.7.2.1), and what it is called in a finding.
_OPTIONAL = {"NORMAL": (("VEC3",), "normals"), "TEXCOORD": (("VEC2",), "texture coordinates"),
             "COLOR": (("VEC3", "VEC4"), "vertex colours")}  # fmt: skip
#: Deepest node nesting read (a deeper tree is refused; real rigs are a few dozen levels deep).
MAX_DEPTH = 256
#: Elements all primitive instances together may read from accessors without a bufferView: those are zeros
#: that take no bytes in the file (§3.6.2.3), so any count costs nothing to write. Geometry made of them is
#: degenerate; real uses (a few sparse entries on a zero base) are small.
MAX_ZERO_FILLED = 1 << 16
_DAMAGED = "the file is damaged; export it again"


def whole(value: Any, what: str, path: str) -> int:
    """``value`` as a non-negative whole number (``12.0`` is 12; JSON booleans and fractions are refused).

    Raises:
        FormatError: It is not one, naming ``what``.
    """
    if isinstance(value, float) and value.is_integer():
        value = int(value)
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise FormatError(f"{what} is {value!r}, not a whole number >= 0", path=path, hint=_DAMAGED)
    return value


@dataclass(frozen=True, slots=True)
class View:
    """A checked bufferView: ``buffer`` index, ``offset`` and ``length`` in it, ``stride`` (``None``: packed)."""

    index: int
    buffer: int
    offset: int
    length: int
    stride: int | None


@dataclass(frozen=True, slots=True)
class Sparse:
    """A checked ``accessor.sparse``: ``count`` replaced elements, their indices and values."""

    count: int
    indices: View
    indices_offset: int
    indices_dtype: np.dtype[Any]
    values: View
    values_offset: int


@dataclass(frozen=True, slots=True)
class Layout:
    """A checked accessor: what to read, from where; ``stride`` is the effective byte stride."""

    index: int
    atype: str
    ctype: int
    width: int
    count: int
    dtype: np.dtype[Any]
    normalized: bool
    view: View | None
    offset: int
    stride: int
    sparse: Sparse | None


@dataclass(frozen=True, slots=True)
class Primitive:
    """A checked triangle primitive: its accessors (optional ones ``None`` when absent or dropped)."""

    mesh: int
    number: int
    mode: int
    material: int
    position: Layout
    indices: Layout | None
    uvs: Layout | None
    normals: Layout | None
    colors: Layout | None
    triangles: int
    compressed: str | None


@dataclass(slots=True)
class Mesh:
    """A checked mesh: its triangle primitives, the modes of the others, and what one instance produces.

    Attributes:
        zero_filled: Elements its primitives read from accessors without a bufferView (zeros, no bytes).
    """

    index: int
    primitives: list[Primitive] = field(default_factory=list)
    skipped: dict[int, int] = field(default_factory=dict)
    triangles: int = 0
    vertices: int = 0
    zero_filled: int = 0


@dataclass(slots=True)
class Document:
    """The glTF JSON, checked piece by piece as the reader asks for pieces (each checked once)."""

    doc: dict[str, Any]
    path: str
    findings: list[Finding]
    #: Where a GLB's binary chunk starts in the file (``None`` for ``.gltf``): errors about its bytes name them.
    bin_offset: int | None = None
    lists: dict[str, list[dict[str, Any]]] = field(default_factory=dict)
    views: dict[int, View] = field(default_factory=dict)
    layouts: dict[int, Layout] = field(default_factory=dict)
    meshes: dict[int, Mesh] = field(default_factory=dict)

    def error(self, message: str, offset: int | None = None) -> FormatError:
        """A damaged-file error naming this file (and the byte, inside a GLB's binary chunk)."""
        return FormatError(message, path=self.path, offset=offset, hint=_DAMAGED)

    def file_offset(self, buffer: int, offset: int) -> int | None:
        """Where byte ``offset`` of ``buffer`` is in the file: only a GLB's own buffer (0, no uri) is in it."""
        if self.bin_offset is None or buffer != 0 or self.items("buffers")[0].get("uri") is not None:
            return None
        return self.bin_offset + offset

    def items(self, key: str) -> list[dict[str, Any]]:
        """The top-level array ``key`` (empty when absent)."""
        if key not in self.lists:
            value = self.doc.get(key) or []
            if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
                raise FormatError(f"glTF '{key}' is not a list of objects", path=self.path, hint=_DAMAGED)
            self.lists[key] = value
        return self.lists[key]

    def index(self, key: str, value: Any, where: str) -> int:
        """``value`` as an index into ``key``; ``where`` says who refers to it (``mesh 2 primitive 0 NORMAL``)."""
        items = self.items(key)
        if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < len(items):
            raise self.error(f"{where} refers to {key}[{value!r}], which does not exist ({len(items)} in the file)")
        return value

    def item(self, key: str, value: Any, where: str) -> dict[str, Any]:
        """The object ``key[value]``."""
        return self.items(key)[self.index(key, value, where)]

    # -- binary layout ---------------------------------------------------------------------------------

    def view(self, index: int) -> View:
        """The bufferView ``index``, inside its buffer's declared ``byteLength`` (§5.11)."""
        if index not in self.views:
            view = self.items("bufferViews")[index]
            where = f"bufferView {index}"
            buffer_index = self.index("buffers", view.get("buffer"), where)
            offset = whole(view.get("byteOffset", 0), f"{where} byteOffset", self.path)
            length = whole(view.get("byteLength", 0), f"{where} byteLength", self.path)
            stride = view.get("byteStride")
            if stride is not None:  # 0: glTF 1.0 exporters wrote it for "packed"
                stride = whole(stride, f"{where} byteStride", self.path) or None
            declared = self.items("buffers")[buffer_index].get("byteLength")
            if declared is not None and offset + length > whole(
                declared, f"buffer {buffer_index} byteLength", self.path
            ):
                raise self.error(
                    f"{where} (bytes {offset}..{offset + length}) runs past buffer {buffer_index} "
                    f"(byteLength {declared})",
                    self.file_offset(buffer_index, offset),
                )
            self.views[index] = View(index, buffer_index, offset, length, stride)
        return self.views[index]

    def accessor(self, value: Any, where: str) -> Layout:
        """The accessor ``value`` refers to, checked (§3.6.2.2 to §3.6.2.4)."""
        index = self.index("accessors", value, where)
        if index in self.layouts:
            return self.layouts[index]
        acc = self.items("accessors")[index]
        name = f"accessor {index}"
        ctype, atype = acc.get("componentType"), acc.get("type")
        if not _integer(ctype) or ctype not in COMPONENT or not isinstance(atype, str) or atype not in WIDTH:
            raise self.error(
                f"{name} has componentType {ctype!r} and type {atype!r}: glTF 2.0 has componentType "
                "5120, 5121, 5122, 5123, 5125 or 5126 and type SCALAR, VEC2, VEC3, VEC4, MAT2, MAT3 or MAT4"
            )
        dtype, width = np.dtype(COMPONENT[ctype]), WIDTH[atype]
        count = whole(acc.get("count", 0), f"{name} count", self.path)
        item = dtype.itemsize * width
        offset = whole(acc.get("byteOffset", 0), f"{name} byteOffset", self.path)
        view, stride = None, item
        if acc.get("bufferView") is not None:
            view = self.view(self.index("bufferViews", acc["bufferView"], name))
            if view.stride is not None:
                if view.stride < item:
                    raise self.error(
                        f"{name} reads {item}-byte {atype} elements from bufferView {view.index} with byteStride "
                        f"{view.stride}: elements would overlap (glTF 2.0 §3.6.2.4: a stride is at least the "
                        "element size)",
                        self.file_offset(view.buffer, view.offset + offset),
                    )
                stride = view.stride
            need = offset + stride * (count - 1) + item if count else offset
            if need > view.length:
                raise self.error(
                    f"{name} runs past its bufferView {view.index}: byteOffset {offset} + stride {stride} x "
                    f"({count} - 1) + {item}-byte element = {need} bytes, the view has {view.length} "
                    "(glTF 2.0 §3.6.2.4)",
                    self.file_offset(view.buffer, view.offset + offset),
                )
        sparse = self._sparse(acc.get("sparse"), name, count, item) if acc.get("sparse") else None
        normalized = bool(acc.get("normalized")) and ctype != 5126
        layout = Layout(index, atype, ctype, width, count, dtype, normalized, view, offset, stride, sparse)
        self.layouts[index] = layout
        return layout

    def _sparse(self, sparse: Any, name: str, count: int, item: int) -> Sparse:
        if not isinstance(sparse, dict):
            raise self.error(f"{name} sparse is not an object")
        where = f"{name} sparse"
        n = whole(sparse.get("count"), f"{where} count", self.path)
        if n > count:
            raise self.error(f"{where} count {n} is more than the accessor's {count} elements (glTF 2.0 §3.6.2.3)")
        parts = []
        for key, size in (("indices", 0), ("values", item)):
            part = sparse.get(key)
            if not isinstance(part, dict):
                raise self.error(f"{where} has no {key} object")
            view = self.view(self.index("bufferViews", part.get("bufferView"), f"{where} {key}"))
            offset = whole(part.get("byteOffset", 0), f"{where} {key} byteOffset", self.path)
            if key == "indices":
                ctype = part.get("componentType")
                if not _integer(ctype) or ctype not in _INDEX_TYPES:
                    raise self.error(f"{where} indices componentType {ctype!r} is not 5121, 5123 or 5125")
                size = np.dtype(COMPONENT[ctype]).itemsize
            if offset + n * size > view.length:
                raise self.error(
                    f"{where} {key} runs past bufferView {view.index}: {offset} + {n} x {size} bytes, the view has "
                    f"{view.length}",
                    self.file_offset(view.buffer, view.offset + offset),
                )
            parts.append((view, offset, size))
        dtype = np.dtype({1: "u1", 2: "<u2", 4: "<u4"}[parts[0][2]])
        return Sparse(n, parts[0][0], parts[0][1], dtype, parts[1][0], parts[1][1])

    # -- meshes ----------------------------------------------------------------------------------------

    def mesh(self, value: Any, where: str, uv_set: dict[int, int]) -> Mesh:
        """The mesh ``value`` refers to, checked, with what one instance of it produces.

        Args:
            value: The index (from a node).
            where: Who refers to it.
            uv_set: The TEXCOORD set each material's base colour texture uses (0 when absent).
        """
        index = self.index("meshes", value, where)
        if index not in self.meshes:
            self.meshes[index] = self._mesh(index, uv_set)
        return self.meshes[index]

    def _mesh(self, index: int, uv_set: dict[int, int]) -> Mesh:
        mesh = Mesh(index)
        primitives = self.items("meshes")[index].get("primitives") or []
        if not isinstance(primitives, list):
            raise self.error(f"mesh {index} primitives is not a list")
        for number, prim in enumerate(primitives):
            if not isinstance(prim, dict):
                continue
            name = f"mesh {index} primitive {number}"
            mode = prim.get("mode", 4)
            if not _integer(mode) or mode not in range(7):
                raise self.error(f"{name} has mode {mode!r}, not a glTF topology (0 to 6, §3.7.2.1)")
            attributes = prim.get("attributes") or {}
            if not isinstance(attributes, dict):
                raise self.error(f"{name} attributes is not an object")
            if mode < 4:
                mesh.skipped[mode] = mesh.skipped.get(mode, 0) + 1
                continue
            if "POSITION" not in attributes:
                continue
            extensions = prim.get("extensions") or {}
            compressed = next((str(k) for k in extensions if k in _COMPRESSION), None)
            position = self.accessor(attributes["POSITION"], f"{name} POSITION")
            if position.atype != "VEC3":
                raise self.error(f"accessor {position.index} (POSITION of {name}) is {position.atype}, not VEC3")
            if compressed is not None and position.view is None and position.sparse is None:
                raise FormatError(
                    f"{name} is {compressed} compressed and has no uncompressed data, which meshtool cannot decode",
                    path=self.path,
                    hint="export it uncompressed (e.g. gltf-transform copy with no compression, or Blender "
                    "without Draco)",
                    code="gltf-compressed",
                )
            indices = None
            corners = position.count
            if prim.get("indices") is not None:
                indices = self.accessor(prim["indices"], f"{name} indices")
                if indices.atype != "SCALAR" or indices.ctype not in _INDEX_TYPES:
                    raise self.error(
                        f"accessor {indices.index} (indices of {name}) is {indices.atype} of componentType "
                        f"{indices.ctype}: indices are SCALAR unsigned byte, short or int (glTF 2.0 §3.7.2.1)"
                    )
                corners = indices.count
            if mode == 4 and corners % 3:
                source = f"accessor {indices.index if indices else position.index}"
                raise self.error(
                    f"{name} is a triangle list of {corners} vertex indices ({source}), not a multiple of 3 "
                    "(glTF 2.0 §3.7.2.1)"
                )
            material = -1
            if prim.get("material") is not None:
                material = self.index("materials", prim["material"], name)
            uv = f"TEXCOORD_{uv_set.get(material, 0)}"
            normals, uvs, colors = (
                self._optional(attributes, key, name, position) for key in ("NORMAL", uv, "COLOR_0")
            )
            made = corners // 3 if mode == 4 else max(corners - 2, 0)
            mesh.primitives.append(
                Primitive(index, number, mode, material, position, indices, uvs, normals, colors, made, compressed)
            )
            mesh.triangles += made
            mesh.vertices += position.count
            used = (position, indices, normals, uvs, colors)
            mesh.zero_filled += sum(u.count for u in used if u is not None and u.view is None)
        return mesh

    def _optional(self, attributes: dict[str, Any], key: str, name: str, position: Layout) -> Layout | None:
        """Attribute ``key`` of a primitive, or ``None`` (absent, or dropped with a warning)."""
        if key not in attributes:
            return None
        layout = self.accessor(attributes[key], f"{name} {key}")
        types, what = _OPTIONAL[key.split("_")[0]]
        problem = None
        if layout.atype not in types:
            problem = f"is {layout.atype}, not {' or '.join(types)}"
        elif layout.count != position.count:
            problem = f"has {layout.count} elements, POSITION (accessor {position.index}) has {position.count}"
        if problem is None:
            return layout
        self.findings.append(
            warning(
                "gltf-attribute-dropped",
                f"{name}: {key} (accessor {layout.index}) {problem}: its {what} are dropped "
                "(glTF 2.0 §3.7.2.1: every attribute of a primitive has POSITION's count and a set type)",
                self.path,
            )
        )
        return None

    # -- node tree -------------------------------------------------------------------------------------

    def roots(self) -> list[tuple[int, str]]:
        """The root nodes of the default scene (every node that is no child, without scenes), and who names them."""
        scenes = self.items("scenes")
        nodes = self.items("nodes")
        if not scenes:
            children = {k for n in nodes for k in _list(n.get("children")) if isinstance(k, int)}
            return [(i, "the node list") for i in range(len(nodes)) if i not in children]
        scene_index = self.index("scenes", self.doc.get("scene", 0), "the default scene")
        listed = scenes[scene_index].get("nodes") or []
        if not isinstance(listed, list):
            raise self.error(f"scene {scene_index} nodes is not a list")
        return [(r, f"scene {scene_index}") for r in listed]

    def walk(self, local: Any) -> Iterator[tuple[int, FloatArray]]:
        """Every node of the default scene with its world transform, parents first (iterative, §3.5.2).

        Args:
            local: ``local(node, index)`` -> the node's 4x4 local transform.
        """
        nodes = self.items("nodes")
        stack: list[tuple[Any, FloatArray, int, str]] = [(r, np.eye(4), 0, who) for r, who in reversed(self.roots())]
        seen: set[int] = set()
        while stack:
            index, parent, depth, who = stack.pop()
            if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < len(nodes):
                raise self.error(f"node {index!r} is missing: {who} refers to it, the file has {len(nodes)} nodes")
            if index in seen:
                raise self.error(
                    f"node {index} is reached twice (again from {who}): the node hierarchy has a cycle or a node "
                    "with two parents (glTF 2.0 §3.5.2)"
                )
            if depth > MAX_DEPTH:
                raise FormatError(
                    f"node {index} is nested more than {MAX_DEPTH} levels deep in the scene tree",
                    path=self.path,
                    hint="flatten the node hierarchy",
                )
            seen.add(index)
            with np.errstate(over="ignore", invalid="ignore"):  # an overflow is refused just below
                world = parent @ local(nodes[index], index)
            if not np.isfinite(world).all():
                raise self.error(f"node {index} has a transform that is not finite once combined with its parents'")
            yield index, world
            children = nodes[index].get("children") or []
            if not isinstance(children, list):
                raise self.error(f"node {index} children is not a list")
            stack.extend((child, world, depth + 1, f"node {index}") for child in reversed(children))


def _integer(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _list(value: Any) -> list[Any]:
    return value if isinstance(value, list) else []


def max_primitives() -> int:
    """The most mesh primitive instances (a primitive times the nodes that instance its mesh) a file may have.

    Each is decoded, transformed and assembled separately, so a few kilobytes of JSON could otherwise ask for
    millions; the limit is the one of every format's instances (:data:`meshtool.read.budget.MAX_INSTANCES`,
    ``MESHTOOL_MAX_INSTANCES``).
    """
    return limit_from_env(INSTANCES_ENV, MAX_INSTANCES)
