"""COLLADA ``<geometry>``: sources, accessors, ``<p>``/``<vcount>`` and primitives, read and checked.

- :func:`read_geometry`: ``<source>`` (``count``, ``stride``, ``offset`` checked against the data),
  ``<triangles>``, ``<polylist>``, ``<polygons>``, ``<tristrips>`` and ``<trifans>`` (triangulated as
  pycollada does: fans, strips in its order); every index is checked against its source, and a damaged
  primitive is an error naming the element and its line.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from meshtool.read.collada_xml import child, children, describe, fail, local
from meshtool.read.source_mesh import FloatArray, IntArray

_TRIANGULAR = ("triangles", "polylist", "polygons", "tristrips", "trifans")


def floats(element: Any, path: str) -> FloatArray:
    """The numbers in ``element``'s text (float64), every token checked."""
    tokens = (element.text or "").split()
    try:
        return np.array(tokens, dtype=np.float64)
    except ValueError:
        bad = next(t for t in tokens if not _is_float(t))
        raise fail(f"{describe(element)} holds {bad[:20]!r}, which is not a number", path, element) from None


def _is_float(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def _ints(element: Any, path: str) -> IntArray:
    """The whole numbers in ``element``'s text (int64), every token checked."""
    text = element.text or ""
    tokens = len(text.split())
    try:
        with warnings.catch_warnings():  # numpy < 2.3 warns and stops at a token that is not an integer
            warnings.simplefilter("ignore")
            values = np.fromstring(text, dtype=np.int64, sep=" ") if tokens else np.zeros(0, dtype=np.int64)
    except ValueError:  # numpy >= 2.3
        values = np.zeros(0, dtype=np.int64)
    if values.size != tokens:
        bad = next((t for t in text.split() if not _is_int(t)), "?")
        raise fail(f"{describe(element)} holds {bad[:20]!r}, which is not a whole number", path, element)
    return values


def _is_int(token: str) -> bool:
    try:
        value = int(token)
    except ValueError:
        return False
    return abs(value) < 1 << 62


def _count(element: Any, name: str, path: str, default: int | None = None) -> int | None:
    """Attribute ``name`` of ``element`` as a whole number (``default`` when absent)."""
    text = element.get(name)
    if text is None:
        return default
    try:
        return int(text)
    except ValueError:
        raise fail(f"{describe(element)} {name}={text[:20]!r} is not a whole number", path, element) from None


@dataclass(slots=True)
class Prim:
    """One triangulated primitive of a geometry, unplaced (pycollada's float32 data).

    Attributes:
        material: The material symbol the primitive names (bound by ``<instance_material>``), or ``None``.
        positions: (n, 3) float32, the whole position source.
        vertex_index: (m, 3) indices into ``positions``.
        normals: (k, 3) float32 or ``None``; ``normal_index`` (m, 3) indexes it.
        uvs: (t, 2) float32 or ``None``; ``uv_index`` (m, 3) indexes it.
        line: Line of the element.
    """

    material: str | None
    positions: Any
    vertex_index: IntArray
    normals: Any
    normal_index: IntArray | None
    uvs: Any
    uv_index: IntArray | None
    line: int

    @property
    def triangles(self) -> int:
        """Triangles the primitive adds each time it is placed."""
        return int(self.vertex_index.shape[0])

    @property
    def vertices(self) -> int:
        """Vertices the reader makes each time it is placed (corners split when normals or uvs are read)."""
        split = self.normals is not None or self.uvs is not None
        return 3 * self.triangles if split else int(self.positions.shape[0])


@dataclass(slots=True)
class Geometry:
    """A ``<geometry>`` with a ``<mesh>``: its triangulated primitives (empty ones left out) and line sets."""

    id: str
    name: str
    prims: list[Prim]
    lines: int
    line: int
    triangles: int = 0
    vertices: int = 0


@dataclass(slots=True)
class _Source:
    values: Any  # (count, stride) float32
    element: Any


def read_geometry(element: Any, path: str) -> Geometry | None:
    """Read a ``<geometry>``; ``None`` when it has no ``<mesh>`` (splines, B-reps, convex meshes).

    Raises:
        FormatError: A damaged source or primitive, naming the element and its line.
    """
    mesh = child(element, "mesh")
    if mesh is None:
        return None
    gid = element.get("id") or ""
    out = Geometry(gid, element.get("name") or gid or "geometry", [], 0, element.sourceline or 0)
    sources = {s.get("id"): s for s in children(mesh, "source") if s.get("id")}
    vertices: dict[str, list[tuple[str, str]]] = {}
    for v in children(mesh, "vertices"):
        inputs = [(i.get("semantic") or "", i.get("source") or "") for i in children(v, "input")]
        if not any(s == "POSITION" for s, _ in inputs):
            raise fail(f"{describe(v)} has no POSITION input", path, v)
        vertices[v.get("id") or ""] = inputs
    cache: dict[str, _Source] = {}

    def source(ref: str, user: Any, width: int) -> _Source:
        key = ref[1:] if ref.startswith("#") else ""
        if key not in sources:
            raise fail(f"{describe(user)} names source {ref[:60]!r}, which is not in its <mesh>", path, user)
        if key not in cache:
            cache[key] = _read_source(sources[key], path)
        found = cache[key]
        if found.values.shape[1] < width:
            raise fail(
                f"{describe(found.element)} has {found.values.shape[1]} value(s) per entry; {width} are needed",
                path,
                found.element,
            )
        return found

    for prim_element in mesh:
        kind = local(prim_element)
        if kind in ("lines", "linestrips"):
            out.lines += 1
        elif kind in _TRIANGULAR:
            prim = _read_prim(prim_element, kind, vertices, source, path)
            if prim is not None and prim.triangles:
                out.prims.append(prim)
    out.triangles = sum(p.triangles for p in out.prims)
    out.vertices = sum(p.vertices for p in out.prims)
    return out


def _read_source(element: Any, path: str) -> _Source:
    array = child(element, "float_array")
    if array is None:
        raise fail(f"{describe(element)} has no <float_array>", path, element)
    values = floats(array, path)
    declared = _count(array, "count", path)
    if declared is not None and declared != values.size:
        raise fail(f'{describe(array)} count="{declared}" but it holds {values.size} number(s)', path, array)
    accessor = element.find("./{*}technique_common/{*}accessor")
    if accessor is None:
        raise fail(f"{describe(element)} has no <accessor>", path, element)
    params = sum(1 for _ in children(accessor, "param"))
    stride = _count(accessor, "stride", path, default=max(params, 1))
    offset = _count(accessor, "offset", path, default=0)
    entries = _count(accessor, "count", path)
    assert stride is not None and offset is not None  # defaults given
    if stride < 1:
        raise fail(f'<accessor> stride="{stride}" is not a positive whole number', path, accessor)
    if offset < 0:
        raise fail(f'<accessor> offset="{offset}" is negative', path, accessor)
    if entries is None:
        entries = max(values.size - offset, 0) // stride
    if entries < 0 or offset + entries * stride > values.size:
        raise fail(
            f'<accessor> count="{entries}" x stride="{stride}" from offset {offset} needs '
            f"{offset + entries * stride} number(s) but {describe(array)} holds {values.size}",
            path,
            accessor,
        )
    with np.errstate(over="ignore"):  # beyond float32: inf, refused where it is used as a position
        data = values[offset : offset + entries * stride].astype(np.float32).reshape(entries, stride)
    return _Source(data, element)


def _read_prim(
    element: Any,
    kind: str,
    vertices: Mapping[str, list[tuple[str, str]]],
    source: Callable[[str, Any, int], _Source],
    path: str,
) -> Prim | None:
    inputs: list[tuple[int, str, str, Any]] = []  # offset, semantic, source reference, <input>
    for i in children(element, "input"):
        offset = _count(i, "offset", path)
        if offset is None or offset < 0:
            raise fail(f"{describe(element)}: an <input> has no offset or a negative one", path, i)
        semantic, ref = i.get("semantic") or "", i.get("source") or ""
        key = ref[1:] if ref.startswith("#") else ""
        if semantic == "VERTEX" and key in vertices:
            for inner, inner_ref in vertices[key]:
                inputs.append((offset, "VERTEX" if inner == "POSITION" else inner, inner_ref, i))
        else:
            inputs.append((offset, semantic, ref, i))
    first = {s: (o, r, i) for o, s, r, i in reversed(inputs)}  # the first input of each semantic
    if "VERTEX" not in first:
        raise fail(f"{describe(element)} has no VERTEX input", path, element)
    stride = max(o for o, _, _, _ in inputs) + 1
    corners, raw, ps = _triangulate(element, kind, stride, path)  # (T*3,) rows of raw (n, stride)
    if not raw.size:
        return None

    def read(semantic: str, width: int) -> tuple[Any, IntArray | None]:
        if semantic not in first:
            return None, None
        offset, ref, user = first[semantic]
        found = source(ref, user, width)
        column = raw[:, offset]
        if column.size:
            low, high = int(column.min()), int(column.max())
            if low < 0 or high >= found.values.shape[0]:
                bad = low if low < 0 else high
                what = (
                    "is negative"
                    if bad < 0
                    else f"is past the end of {describe(found.element)} ({found.values.shape[0]} entries)"
                )
                row = int(np.flatnonzero(column == bad)[0])
                p = ps[int(np.searchsorted(np.cumsum([n for _, n in ps]), row, side="right"))][0]
                raise fail(f"{describe(element)}: index {bad} of input {semantic} {what}", path, p)
        return found.values[:, :width], column[corners].reshape(-1, 3)

    positions, vertex_index = read("VERTEX", 3)
    normals, normal_index = read("NORMAL", 3)
    uvs, uv_index = read("TEXCOORD", 2)
    assert vertex_index is not None
    used = positions[vertex_index.reshape(-1)]
    if not np.isfinite(used).all():
        bad = int(vertex_index.reshape(-1)[~np.isfinite(used).all(axis=1)][0])
        named = source(first["VERTEX"][1], first["VERTEX"][2], 3).element
        raise fail(
            f"{describe(element)} uses position {bad} of {describe(named)}, which is not finite "
            f"({positions[bad].tolist()})",
            path,
            element,
        )
    return Prim(
        element.get("material"), positions, vertex_index, normals, normal_index, uvs, uv_index, element.sourceline or 0
    )


def _triangulate(element: Any, kind: str, stride: int, path: str) -> tuple[IntArray, IntArray, list[tuple[Any, int]]]:
    """Triangle corners ``(T*3,)`` as rows of the raw indices ``(n, stride)``; the ``<p>`` and rows each holds.

    Triangles as pycollada makes them: ``<polylist>``/``<polygons>`` fanned from each polygon's first
    vertex (polygons of fewer than 3 vertices add none), strips as (0 1 2) (2 3 4)... then (2 1 3)
    (4 3 5)..., fans from their first vertex.
    """
    ps = list(children(element, "p"))
    if kind == "triangles":
        ps = ps[:1]
    if not ps:
        return np.zeros(0, dtype=np.int64), np.zeros((0, stride), dtype=np.int64), []
    rows: list[IntArray] = []
    sizes: list[int] = []
    for p in ps:
        values = _ints(p, path)
        unit = 3 * stride if kind == "triangles" else stride
        if values.size % unit:
            raise fail(
                f"{describe(element)}: <p> holds {values.size} index(es), not a multiple of {unit} "
                f"({stride} input offset(s){' x 3 corners' if unit != stride else ''})",
                path,
                p,
            )
        rows.append(values.reshape(-1, stride))
        sizes.append(rows[-1].shape[0])
    raw = rows[0] if len(rows) == 1 else np.concatenate(rows)
    held = list(zip(ps, sizes, strict=True))
    declared = _count(element, "count", path)
    if kind == "triangles":
        if declared is not None and declared != raw.shape[0] // 3:
            raise fail(
                f'{describe(element)} count="{declared}" but <p> holds {raw.shape[0] // 3} triangle(s)', path, element
            )
        return np.arange(raw.shape[0], dtype=np.int64), raw, held
    if kind == "polylist":
        vcount_element = child(element, "vcount")
        if vcount_element is None:
            raise fail(f"{describe(element)} has no <vcount>", path, element)
        vcounts = _ints(vcount_element, path)
        if vcounts.size and int(vcounts.min()) < 0:
            raise fail(f"<vcount> holds a negative count {int(vcounts.min())}", path, vcount_element)
        total = int(vcounts.sum())
        if total != raw.shape[0]:
            raise fail(
                f"<vcount> adds up to {total} vertices but <p> holds {raw.shape[0]} ({raw.size} indices / "
                f"{stride} input offset(s))",
                path,
                vcount_element,
            )
        if declared is not None and declared != vcounts.size:
            raise fail(
                f'{describe(element)} count="{declared}" but <vcount> lists {vcounts.size} polygon(s)', path, element
            )
        return _fan(vcounts), raw, held
    sizes_array = np.asarray(sizes, dtype=np.int64)
    holes = sum(1 for _ in children(element, "ph")) if kind == "polygons" else 0
    if declared is not None and declared != len(ps) + holes:
        raise fail(f'{describe(element)} count="{declared}" but it has {len(ps) + holes} <p>', path, element)
    if kind == "polygons":
        return _fan(sizes_array), raw, held
    starts = np.concatenate([[0], np.cumsum(sizes_array)[:-1]]).astype(np.int64)
    out: list[IntArray] = []
    for start, n in zip(starts.tolist(), sizes, strict=True):
        k = np.arange(start, start + n, dtype=np.int64)
        if kind == "tristrips":
            out.append(np.stack([k[0:-2:2], k[1:-1:2], k[2::2]], axis=1).reshape(-1))
            out.append(np.stack([k[2:-1:2], k[1:-2:2], k[3::2]], axis=1).reshape(-1))
        elif n >= 3:  # trifans
            out.append(np.stack([np.full(n - 2, start), k[1:-1], k[2:]], axis=1).reshape(-1))
    return (np.concatenate(out) if out else np.zeros(0, dtype=np.int64)), raw, held


def _fan(vcounts: IntArray) -> IntArray:
    """Corner rows of the fan triangulation of consecutive polygons of ``vcounts`` vertices."""
    ends = np.cumsum(vcounts)
    starts = ends - vcounts
    tris = np.maximum(vcounts - 2, 0)
    total = int(tris.sum())
    first = np.repeat(starts, tris)
    j = np.arange(total, dtype=np.int64) - np.repeat(np.cumsum(tris) - tris, tris)
    return np.stack([first, first + j + 1, first + j + 2], axis=1).reshape(-1).astype(np.int64)


__all__ = ["Geometry", "Prim", "floats", "read_geometry"]
