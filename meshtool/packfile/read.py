"""``.mbin`` reader: memory-mapped, validated, zero-copy (see docs/mbin-spec.md).

Every offset, length and count is checked against the file size before it is used, with Python integers
(no overflow), so a truncated, corrupted or hostile file raises :class:`PackFormatError` naming the section
and byte offset; nothing is allocated beyond the file's own size.
"""

from __future__ import annotations

import contextlib
import itertools
import json
import mmap
import os
import pickle
import shlex
import struct
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from meshtool.errors import PackFormatError, ResolveError
from meshtool.files.safeopen import open_regular, printable
from meshtool.packfile import format as fmt
from meshtool.packfile import verify as check
from meshtool.packfile.encode import dequantize_box, oct_decode
from meshtool.packfile.meta import PackMeta


@dataclass(slots=True)
class Section:
    """One entry of the section table, as read.

    Attributes:
        kind: Four-character tag, e.g. ``"POS "``.
        dtype: Element type name (``bytes``, ``u8``, ``u16``, ``u32``, ``i16``, ``f32``).
        shape: Array shape (rows, columns) or (bytes,) for blobs.
        offset: Byte offset in the file.
        length: Byte length.
        crc: Stored checksum (CRC-32 in 1.0 files, low 32 bits of XXH3-64 in 1.1).
        encoding: Encoding code (0 plain, 1 u16 box, 2 octahedral).
        index: Index among sections of the same kind (textures).
        crc_ok: Result of the checksum check, ``None`` when not verified.
    """

    kind: str
    dtype: str
    shape: tuple[int, ...]
    offset: int
    length: int
    crc: int
    encoding: int
    index: int
    crc_ok: bool | None = None


@dataclass(slots=True)
class PackedMesh:
    """A loaded ``.mbin``. Arrays are read-only views into the memory map unless stated.

    Attributes:
        positions: (V, 3) float32 metres (decoded copy in quantised files; see ``raw``).
        indices: (M, 3) u16 or u32 triangle vertex indices.
        normals: (V, 3) float32 or ``None`` (decoded copy in quantised files).
        uvs: (V, 2) float32 or ``None`` (decoded copy in quantised files).
        colors: (V, 4) u8 RGBA or ``None``.
        submeshes: (S, 4) u32 rows (first triangle, triangle count, material, part).
        materials: Material dicts (name, colors, scalars, illum, maps with texture index).
        textures: PNG bytes per texture (memoryviews into the map), in ``meta["textures"]`` order.
        hulls: (vertices (n, 3) float32, faces (k, 3) u32) per collision hull.
        meta: The metadata object.
        version: (major, minor).
        quantized: Whether positions/normals/uvs are quantised.
        sections: The section table.
        raw: The stored arrays by section kind, as views.
    """

    positions: npt.NDArray[np.float32]
    indices: npt.NDArray[np.unsignedinteger[Any]]
    normals: npt.NDArray[np.float32] | None
    uvs: npt.NDArray[np.float32] | None
    colors: npt.NDArray[np.uint8] | None
    submeshes: npt.NDArray[np.uint32]
    materials: list[dict[str, Any]]
    textures: list[memoryview]
    hulls: list[tuple[npt.NDArray[np.float32], npt.NDArray[np.uint32]]]
    meta: dict[str, Any]
    version: tuple[int, int]
    quantized: bool
    sections: list[Section]
    raw: dict[str, npt.NDArray[Any]] = field(default_factory=dict)
    _map: mmap.mmap | None = None

    @property
    def pack_meta(self) -> PackMeta:
        """:attr:`meta` as the typed record (:class:`meshtool.packfile.meta.PackMeta`)."""
        return PackMeta(self.meta)

    def close(self) -> None:
        """Release the memory map (arrays must not be used afterwards)."""
        if self._map is not None:
            self.raw.clear()
            with contextlib.suppress(BufferError):  # views still exported: the map closes when they go
                self._map.close()
            self._map = None

    def __enter__(self) -> PackedMesh:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def load(path: str | Path, verify: bool = True) -> PackedMesh:
    """Memory-map and validate an ``.mbin`` file.

    Args:
        path: The file.
        verify: Also check every section's checksum (CRC-32 in 1.0 files, XXH3 in 1.1) and the content:
            indices, submeshes and hulls in range, every float finite (reads the whole file once); without
            it only the header, the table, the bounds and the JSON sections are checked.

    Returns:
        The mesh, arrays viewing the map.

    Raises:
        PackFormatError: Anything wrong with the file, with the section and byte offset.
        ResolveError: The file cannot be opened.
    """
    fd = open_regular(Path(path))
    try:
        return load_descriptor(fd, path, verify)
    finally:
        os.close(fd)


def load_descriptor(fd: int, path: str | Path, verify: bool = True) -> PackedMesh:
    """:func:`load` of the ``.mbin`` open as ``fd``, a regular file the caller opened (and closes).

    For a caller that opened the file itself (to refuse a FIFO or device with its own message): the file is
    opened once, and what is read is what that descriptor names (no second lookup by name).

    Args:
        fd: A descriptor open for reading on a regular file, at offset 0.
        path: The file's name, for messages.
        verify: See :func:`load`.

    Raises:
        PackFormatError: See :func:`load`.
        ResolveError: It cannot be read.
    """
    name = str(path)
    mapped = _read_pack(fd, path)
    if mapped is None:
        raise PackFormatError("empty file, not an .mbin", path=name, offset=0)
    if isinstance(mapped, bytes):  # a small file, read whole: the arrays view these bytes
        return parse(mapped, name, verify)
    try:
        return parse(mapped, name, verify, keep=mapped)
    except PackFormatError:
        with contextlib.suppress(BufferError):  # views made before the error still point into the map
            mapped.close()
        raise


#: Files up to this size (bytes) are read into memory instead of mapped: for a small asset a map's set-up,
#: page faults and unmapping cost more than one read (suzanne's 20 KB: about 20 us of a 65 us load).
SMALL_FILE_BYTES = 256 * 1024


def _read_pack(fd: int, path: str | Path) -> mmap.mmap | bytes | None:
    """The bytes of the file open as ``fd`` (at most :data:`SMALL_FILE_BYTES`), else a read-only map of it.

    ``None`` when it is empty. :func:`load` opens it as :func:`meshtool.files.resolve.map_readonly` does (a regular
    file, symlinks followed, never blocking), once; the caller closes ``fd``.

    Raises:
        ResolveError: It cannot be read.
    """
    try:
        size = os.fstat(fd).st_size
        if size == 0:
            return None
        if size > SMALL_FILE_BYTES:
            return mmap.mmap(fd, 0, access=mmap.ACCESS_READ)
        chunks = []
        while True:  # to the end, as a map would see it (the file may grow or shrink meanwhile)
            chunk = os.read(fd, max(size, 65536))
            if not chunk:
                break
            chunks.append(chunk)
        if not chunks:
            return None
        return chunks[0] if len(chunks) == 1 else b"".join(chunks)
    except OSError as exc:
        raise ResolveError(f"cannot be read: {exc.strerror}", path=printable(path)) from None


def parse(buffer: Any, name: str = "<mbin>", verify: bool = True, keep: mmap.mmap | None = None) -> PackedMesh:
    """Validate and view an ``.mbin`` held in memory (bytes, memoryview or mmap).

    Args:
        buffer: The whole file.
        name: For error messages.
        verify: See :func:`load`.
        keep: A memory map to keep open for the views' lifetime.

    Returns:
        The mesh.

    Raises:
        PackFormatError: See :func:`load`.
    """
    view = memoryview(buffer)
    size = len(view)
    if size < fmt.HEADER_SIZE:
        raise PackFormatError(f"truncated: {size} bytes, the header alone is 64", path=name, offset=size)
    magic, major, minor, flags, count, table_offset, stated, table_crc = _HEADER.unpack_from(view, 0)
    if magic != fmt.MAGIC:
        hint = (
            "damaged by a text-mode transfer (line endings changed)" if bytes(view[:1]) == b"\x89" else "not an .mbin"
        )
        if _mesh_file(name):  # `meshtool info X.obj`, `[assets] head = "X.obj"` where a pack is needed
            quoted = shlex.quote(name)
            raise PackFormatError(
                "a mesh file, not an .mbin",
                path=name,
                hint=f"pack it first: obj2bin {quoted}; for a MuJoCo model: obj2bin {quoted} --mjcf OUT/",
            )
        raise PackFormatError(f"bad magic number: {hint}", path=name, offset=0)
    if major != fmt.MAJOR:
        raise PackFormatError(
            f"unsupported format version {major}.{minor}: this reader reads {fmt.MAJOR}.x",
            path=name,
            offset=8,
            hint="upgrade meshtool or re-pack the asset",
            code="pack-version",
        )
    if stated != size:
        raise PackFormatError(
            f"truncated or padded: header says {stated} bytes, the file has {size}", path=name, offset=24
        )
    table_end = table_offset + count * fmt.ENTRY_SIZE
    if table_offset != fmt.HEADER_SIZE or count == 0 or table_end > size:
        raise PackFormatError(
            f"section table ({count} entries at {table_offset}) does not fit the file", path=name, offset=16
        )
    head = bytes(view[:table_end])
    if fmt.checksum(head[:32] + head[table_offset:], minor) != table_crc:  # every file's own table, always
        raise PackFormatError("header or section table checksum mismatch", path=name, offset=32)
    layout_key = (_without_checksums(head, count), size)
    layout = _LAYOUTS.get(layout_key)
    if layout is None:  # not seen before in this process: every check of the header and the table
        if any(head[36:64]):
            raise PackFormatError("reserved header bytes are not zero", path=name, offset=36)
        if flags & ~fmt.FLAG_QUANTIZED:
            raise PackFormatError(f"unknown header flags {flags:#x}", path=name, offset=12)
        entries = _ENTRY.iter_unpack(head[table_offset:])
        checked = [_entry(e, k, name, size, table_end, table_offset) for k, e in enumerate(entries)]
        _check_layout(checked, name)
        layout = _remember(_LAYOUTS, layout_key, tuple(_fields(s)[:5] + _fields(s)[6:] for s in checked))
    crcs = _crcs(head, count)
    sections = [
        Section(kind, dtype, shape, offset, length, crc, encoding, index)
        for (kind, dtype, shape, offset, length, encoding, index), crc in zip(layout, crcs, strict=True)
    ]
    if verify:
        for s in sections:
            s.crc_ok = fmt.checksum(view[s.offset : s.offset + s.length], minor) == s.crc
            if not s.crc_ok:
                raise PackFormatError(f"section {s.kind!r} checksum mismatch", path=name, offset=s.offset)
    quantized = bool(flags & fmt.FLAG_QUANTIZED)
    return _build(view, sections, name, verify, quantized, (major, minor), keep, layout_key)


#: Byte offset of a section's stored checksum within its table entry (``crc`` in docs/mbin-spec.md section 3).
_CRC_AT = 40


def _without_checksums(head: bytes, count: int) -> bytes:
    """``head`` (the header and ``count`` table entries) with the header's and every entry's checksum zeroed.

    The key of the layout caches: files of one layout whose contents differ (a distinct file per entity)
    differ in their checksums alone, and no check of the layout reads a checksum (each file's table checksum
    and, when verifying, each section's are computed from its own bytes).
    """
    key = bytearray(head)
    key[32:36] = bytes(4)
    for at in range(fmt.HEADER_SIZE + _CRC_AT, fmt.HEADER_SIZE + count * fmt.ENTRY_SIZE, fmt.ENTRY_SIZE):
        key[at : at + 4] = bytes(4)
    return bytes(key)


def _crcs(head: bytes, count: int) -> tuple[int, ...]:
    """The stored section checksums of ``count`` table entries, in table order."""
    unpack = _CRCS.get(count)
    if unpack is None:
        unpack = struct.Struct(f"<{'I60x' * (count - 1)}I")
        if count <= 64:
            _CRCS[count] = unpack
    result: tuple[int, ...] = unpack.unpack_from(head, fmt.HEADER_SIZE + _CRC_AT)
    return result


#: Struct reading the section checksums of a table of N entries (one unpack per file), by N.
_CRCS: dict[int, struct.Struct] = {}


#: Checks made once per content (issue 28: a small asset's load was ~100 Python-level checks and two
#: JSON decodes with a call per number, 0.2-0.4 ms). Each cache is keyed by the exact bytes the checks
#: read (never by a checksum: a checksum is not a proof of sameness), so a file that differs anywhere they
#: look is checked in full. Layout: (header + table bytes with their checksums zeroed, file size; see
#: :func:`_without_checksums`) -> the sections' fields but their checksums. JSON:
#: (the META and MATL stored bytes, what their checks depend on) -> the values (pickled) and the part names.
#: Content: the small arrays check_submeshes and check_hulls read -> passed.
_LAYOUTS: dict[tuple[bytes, int], tuple[tuple[Any, ...], ...]] = {}
_JSON_CHECKED: dict[tuple[Any, ...], tuple[Any, ...]] = {}
#: The layout key -> how :func:`_build` views that layout's sections, once its checks of
#: the layout alone (section types, row counts, the quantised flag) passed.
_PLANS: dict[tuple[bytes, int], _Plan] = {}
_CONTENT_CHECKED: dict[tuple[Any, ...], bool] = {}
#: Entries kept per cache; the oldest goes first (a process loading many assets stays bounded).
CACHE_ENTRIES = 256
#: Largest section (bytes) whose content checks are remembered by its bytes.
CACHE_SECTION_BYTES = 64 * 1024


def _remember(cache: dict[Any, Any], key: Any, value: Any) -> Any:
    """Store ``value`` under ``key``, dropping the oldest entry beyond :data:`CACHE_ENTRIES`; return it."""
    if len(cache) >= CACHE_ENTRIES:
        del cache[next(iter(cache))]
    cache[key] = value
    return value


def _fields(s: Section) -> tuple[Any, ...]:
    return (s.kind, s.dtype, s.shape, s.offset, s.length, s.crc, s.encoding, s.index)


def forget_checks() -> None:
    """Empty the caches of checks made once per content (for benchmarks that time a first load)."""
    _LAYOUTS.clear()
    _PLANS.clear()
    _JSON_CHECKED.clear()
    _CONTENT_CHECKED.clear()


#: Header fields before ``reserved`` and one table entry, as the layouts of docs/mbin-spec.md sections 2 and 3.
_HEADER = struct.Struct("<8sHHIIIQI")
_ENTRY = struct.Struct("<4sBBH2QQQII16s")
assert _HEADER.size == 36 and _ENTRY.size == fmt.ENTRY_SIZE
_DTYPE_NAMES = {code: name for name, code in fmt.CODES.items()}


def _mesh_file(name: str) -> bool:
    """Whether ``name`` is a mesh file meshtool reads (OBJ, STL, PLY, glTF/GLB, COLLADA), by its suffix."""
    from meshtool.read import MESH_SUFFIXES

    return Path(name).suffix.lower() in MESH_SUFFIXES


def _entry(e: tuple[Any, ...], k: int, name: str, size: int, table_end: int, table_offset: int) -> Section:
    kind_raw, code, ndim, index, rows, cols, offset, length, crc, encoding, reserved = e
    at = table_offset + k * fmt.ENTRY_SIZE
    kind_bytes = kind_raw.rstrip(b"\0").ljust(4)  # a numpy "S4" field's reading: trailing NULs dropped
    try:
        kind = kind_bytes.decode("ascii")
    except UnicodeDecodeError:
        raise PackFormatError(f"section {k} has a non-ASCII kind", path=name, offset=at) from None
    if code not in fmt.DTYPES or ndim not in (1, 2):
        raise PackFormatError(f"section {kind!r} has dtype code {code}, ndim {ndim}", path=name, offset=at + 4)
    itemsize = fmt.DTYPES[code].itemsize
    elements = rows * (cols if ndim == 2 else 1)
    if encoding == fmt.ENC_DEFLATE:
        expected_ok = elements * itemsize <= fmt.MAX_INFLATE_RATIO * length + 1024
    else:
        expected_ok = elements * itemsize == length
    if (ndim == 1 and cols != 0) or not expected_ok:
        raise PackFormatError(
            f"section {kind!r}: shape ({rows}, {cols}) does not match {length} bytes", path=name, offset=at + 8
        )
    if offset % fmt.ALIGN or offset < table_end or offset + length > size:
        raise PackFormatError(
            f"section {kind!r}: {length} bytes at {offset} are outside the data area", path=name, offset=at + 24
        )
    if any(reserved):
        raise PackFormatError(f"section {kind!r}: reserved bytes are not zero", path=name, offset=at + 48)
    shape = (rows, cols) if ndim == 2 else (rows,)
    return Section(kind, _DTYPE_NAMES[code], shape, offset, length, crc, encoding, index)


def _check_layout(sections: list[Section], name: str) -> None:
    # A zero-length section holds no bytes, so it overlaps nothing (its offset is still checked in _entry).
    ordered = sorted((s for s in sections if s.length), key=lambda s: s.offset)
    for a, b in itertools.pairwise(ordered):
        if a.offset + a.length > b.offset:
            raise PackFormatError(f"sections {a.kind!r} and {b.kind!r} overlap", path=name, offset=b.offset)
    kinds = [s.kind.encode() for s in sections]
    for k, s in enumerate(sections):
        if s.index and kinds[k] in fmt.REQUIRED + fmt.OPTIONAL[:3]:
            at = fmt.HEADER_SIZE + k * fmt.ENTRY_SIZE + 6
            raise PackFormatError(f"section {s.kind!r} has index {s.index}, expected 0", path=name, offset=at)
    for kind in fmt.REQUIRED + fmt.OPTIONAL[:3]:
        n = kinds.count(kind)
        if n > 1 or (n == 0 and kind in fmt.REQUIRED):
            raise PackFormatError(f"section {kind.decode()!r} appears {n} times", path=name, offset=fmt.HEADER_SIZE)
    tex = sorted(s.index for s in sections if s.kind.encode() == fmt.KIND_TEXTURE)
    if tex != list(range(len(tex))):
        raise PackFormatError(
            f"texture sections are numbered {tex}, expected 0..{len(tex) - 1}", path=name, offset=fmt.HEADER_SIZE
        )


_EXPECT: dict[bytes, tuple[tuple[str, int, int], ...]] = {
    # kind: allowed (dtype, columns, encoding)
    fmt.KIND_POSITIONS: (("f32", 3, fmt.ENC_PLAIN), ("u16", 3, fmt.ENC_UNORM16_BOX)),
    fmt.KIND_NORMALS: (("f32", 3, fmt.ENC_PLAIN), ("i16", 2, fmt.ENC_OCT_SNORM16)),
    fmt.KIND_UVS: (("f32", 2, fmt.ENC_PLAIN), ("u16", 2, fmt.ENC_UNORM16_BOX)),
    fmt.KIND_COLORS: (("u8", 4, fmt.ENC_PLAIN),),
    fmt.KIND_INDICES: (
        ("u16", 3, fmt.ENC_PLAIN),
        ("u32", 3, fmt.ENC_PLAIN),
        ("u16", 3, fmt.ENC_DEFLATE),
        ("u32", 3, fmt.ENC_DEFLATE),
    ),
    fmt.KIND_SUBMESHES: (("u32", 4, fmt.ENC_PLAIN),),
    fmt.KIND_HULL_TABLE: (("u32", 4, fmt.ENC_PLAIN),),
    fmt.KIND_HULL_VERTICES: (("f32", 3, fmt.ENC_PLAIN),),
    fmt.KIND_HULL_FACES: (("u32", 3, fmt.ENC_PLAIN),),
    fmt.KIND_META: (("bytes", 0, fmt.ENC_PLAIN), ("bytes", 0, fmt.ENC_DEFLATE)),
    fmt.KIND_MATERIALS: (("bytes", 0, fmt.ENC_PLAIN), ("bytes", 0, fmt.ENC_DEFLATE)),
    fmt.KIND_TEXTURE: (("bytes", 0, fmt.ENC_PLAIN),),
}


def _build(
    view: memoryview,
    sections: list[Section],
    name: str,
    verify: bool,
    quantized: bool,
    version: tuple[int, int],
    keep: mmap.mmap | None,
    layout_key: tuple[bytes, int] | None = None,
) -> PackedMesh:
    plan = _PLANS.get(layout_key) if layout_key is not None else None
    if plan is None:
        by_kind, textures, raw = _view_sections(view, sections, name, quantized)
        if layout_key is not None:
            _remember(_PLANS, layout_key, _plan_of(sections, by_kind))
    else:  # a layout seen before: its checks passed, only the views (and any inflating) are made
        by_kind = plan.by_kind
        textures = [view[offset : offset + length].toreadonly() for offset, length in plan.textures]
        raw = {}
        for tag, dtype, count, shape, s in plan.arrays:
            if s.encoding == fmt.ENC_DEFLATE:
                raw[tag] = np.frombuffer(_inflate(view, s, name), dtype=dtype, count=count).reshape(shape)
            else:
                raw[tag] = np.frombuffer(view, dtype=dtype, count=count, offset=s.offset).reshape(shape)
    return _build_rest(view, sections, name, verify, quantized, version, keep, by_kind, textures, raw)


@dataclass(slots=True, frozen=True)
class _Plan:
    """How :func:`_build` views the sections of one layout (see :data:`_PLANS`).

    Attributes:
        by_kind: The sections :func:`_build` reads, by kind.
        textures: (offset, length) of each texture section, in texture order.
        arrays: (kind, dtype, element count, shape, section) of each array section, in table order.
    """

    by_kind: dict[bytes, Section]
    textures: tuple[tuple[int, int], ...]
    arrays: tuple[tuple[str, np.dtype[Any], int, tuple[int, ...], Section], ...]


def _plan_of(sections: list[Section], by_kind: dict[bytes, Section]) -> _Plan:
    """The :class:`_Plan` of sections whose layout :func:`_view_sections` accepted."""
    texture_sections = sorted((s for s in sections if s.kind == "TEX "), key=lambda s: s.index)
    # copies (the caller's are its own) without the checksum, which differs between files of one layout and is
    # read from the sections of the file at hand, never from the plan
    mine = {
        kind: Section(s.kind, s.dtype, s.shape, s.offset, s.length, 0, s.encoding, s.index)
        for kind, s in by_kind.items()
    }
    arrays = []
    for s in sections:  # table order, as _view_sections fills the arrays
        kind = s.kind.encode()
        if by_kind.get(kind) is s and s.dtype != "bytes":
            cols = s.shape[1] if len(s.shape) == 2 else 0
            arrays.append((s.kind, fmt.DTYPES[fmt.CODES[s.dtype]], s.shape[0] * cols, s.shape, mine[kind]))
    return _Plan(mine, tuple((s.offset, s.length) for s in texture_sections), tuple(arrays))


def _view_sections(
    view: memoryview, sections: list[Section], name: str, quantized: bool
) -> tuple[dict[bytes, Section], list[memoryview], dict[str, npt.NDArray[Any]]]:
    """Every section checked against its kind's types and viewed: (sections by kind, textures, arrays by kind)."""
    by_kind: dict[bytes, Section] = {}
    textures: list[memoryview] = [memoryview(b"")] * sum(s.kind == "TEX " for s in sections)
    raw: dict[str, npt.NDArray[Any]] = {}
    for s in sections:
        kind = s.kind.encode()
        if kind not in _EXPECT:
            continue  # a section kind from a newer minor version: skipped
        cols = s.shape[1] if len(s.shape) == 2 else 0
        if (s.dtype, cols, s.encoding) not in _EXPECT[kind]:
            raise PackFormatError(
                f"section {s.kind!r} has type {s.dtype} x {cols}, encoding {s.encoding}", path=name, offset=s.offset
            )
        if kind == fmt.KIND_TEXTURE:
            textures[s.index] = view[s.offset : s.offset + s.length].toreadonly()
            continue
        by_kind[kind] = s
        if s.dtype != "bytes":
            dtype = fmt.DTYPES[fmt.CODES[s.dtype]]
            source: Any = _inflate(view, s, name) if s.encoding == fmt.ENC_DEFLATE else view
            offset = 0 if s.encoding == fmt.ENC_DEFLATE else s.offset
            arr = np.frombuffer(source, dtype=dtype, count=s.shape[0] * cols, offset=offset)
            raw[s.kind] = arr.reshape(s.shape)
    n = raw["POS "].shape[0]
    for tag in ("NRM ", "UV  ", "COL "):
        if tag in raw and raw[tag].shape[0] != n:
            raise PackFormatError(
                f"section {tag!r} has {raw[tag].shape[0]} rows for {n} vertices",
                path=name,
                offset=by_kind[tag.encode()].offset,
            )
    encodings = {s.encoding for s in by_kind.values()}
    if quantized != bool(encodings & {fmt.ENC_UNORM16_BOX, fmt.ENC_OCT_SNORM16}):
        raise PackFormatError(
            "the header's quantised flag does not match the sections' encodings", path=name, offset=12
        )
    return by_kind, textures, raw


def _build_rest(
    view: memoryview,
    sections: list[Section],
    name: str,
    verify: bool,
    quantized: bool,
    version: tuple[int, int],
    keep: mmap.mmap | None,
    by_kind: dict[bytes, Section],
    textures: list[memoryview],
    raw: dict[str, npt.NDArray[Any]],
) -> PackedMesh:
    """What :func:`_build` reads beyond the layout: the JSON sections, the content checks, the mesh."""
    meta_at, matl_at = by_kind[fmt.KIND_META].offset, by_kind[fmt.KIND_MATERIALS].offset
    meta_section, matl_section = by_kind[fmt.KIND_META], by_kind[fmt.KIND_MATERIALS]
    meta_bytes = bytes(view[meta_at : meta_at + meta_section.length])
    matl_bytes = bytes(view[matl_at : matl_at + matl_section.length])
    n = raw["POS "].shape[0]
    boxed = {"positions": ("POS ", 3), "uvs": ("UV  ", 2)}
    quantised = {
        array: cols
        for array, (tag, cols) in boxed.items()
        if tag in raw and by_kind[tag.encode()].encoding == fmt.ENC_UNORM16_BOX
    }
    json_key: tuple[Any, ...] = (meta_bytes, meta_section.encoding, meta_section.shape, matl_bytes)
    json_key += (matl_section.encoding, matl_section.shape)
    json_key += (len(textures), *sorted(quantised.items()))
    known = _JSON_CHECKED.get(json_key)
    if known is not None:  # the same JSON checked before: its values again (a pickle we made: 3x json.loads)
        meta, materials = pickle.loads(known[0])
        parts = list(known[1])
    else:
        meta = _json(meta_bytes, meta_section, name, dict)
        materials = _json(matl_bytes, matl_section, name, list)
        _, parts = check.check_meta(meta, len(textures), quantised, name, meta_at)
        check.check_materials(materials, len(textures), name, matl_at)
        if len(meta_bytes) + len(matl_bytes) <= 4 * CACHE_SECTION_BYTES:  # the caches stay a few MB at most
            _remember(_JSON_CHECKED, json_key, (pickle.dumps((meta, materials), protocol=5), tuple(parts)))
    indices = raw["IDX "]
    submeshes = raw["SUBM"]
    quant = meta.get("quantization") or {}
    positions = _decode(raw["POS "], by_kind[fmt.KIND_POSITIONS].encoding, quant.get("positions"))
    normals = _decode(raw["NRM "], by_kind[fmt.KIND_NORMALS].encoding, None) if "NRM " in raw else None
    uvs = _decode(raw["UV  "], by_kind[fmt.KIND_UVS].encoding, quant.get("uvs")) if "UV  " in raw else None
    if verify:
        idx = by_kind[fmt.KIND_INDICES]
        check.check_indices(indices, n, "IDX ", name, idx.offset, idx.encoding == fmt.ENC_PLAIN)
        small = [by_kind[k] for k in (b"SUBM", fmt.KIND_HULL_TABLE, fmt.KIND_HULL_FACES)]
        content_key: tuple[Any, ...] | None = None
        if sum(s.length for s in small) <= CACHE_SECTION_BYTES:
            content_key = tuple(bytes(view[s.offset : s.offset + s.length]) for s in small)
            content_key += (*((s.dtype, s.shape, s.encoding) for s in small), indices.shape[0], len(materials))
            content_key += (len(parts),)
            content_key += (raw["HULV"].shape[0],)
        known_content = content_key is not None and content_key in _CONTENT_CHECKED
        if not known_content:
            check.check_submeshes(
                submeshes, indices.shape[0], len(materials), len(parts), name, by_kind[b"SUBM"].offset
            )
        for tag, values in (("POS ", positions), ("NRM ", normals), ("UV  ", uvs), ("HULV", raw["HULV"])):
            if values is None:
                continue
            s = by_kind[tag.encode()]
            if s.encoding == fmt.ENC_UNORM16_BOX and values.size:
                # decoding is monotonic in the code: all values are finite when codes 0 and 65535 decode finite
                extremes = np.array([[0] * values.shape[1], [65535] * values.shape[1]], dtype=np.uint16)
                array = "positions" if tag == "POS " else "uvs"
                if np.isfinite(_decode(extremes, s.encoding, quant.get(array))).all():
                    continue
            check.check_finite(values, tag, name, s.offset, 2 if s.dtype in ("u16", "i16") else 4)
        if not known_content:
            offsets = (by_kind[fmt.KIND_HULL_TABLE].offset, by_kind[fmt.KIND_HULL_FACES].offset)
            check.check_hulls(raw["HULT"], raw["HULV"].shape[0], raw["HULF"], offsets, name)
            if content_key is not None:
                _remember(_CONTENT_CHECKED, content_key, True)
        for s in sections:
            if s.kind == "TEX ":
                check.check_png(textures[s.index], s.index, name, s.offset)
        if len(meta.get("hull_parts") or []) not in (0, raw["HULT"].shape[0]):
            raise check.fail("section 'META': hull_parts does not name one part per hull", name, meta_at)
    hulls = _hulls(raw, by_kind, name)
    return PackedMesh(
        positions=positions,
        indices=indices,
        normals=normals,
        uvs=uvs,
        colors=raw.get("COL "),
        submeshes=submeshes,
        materials=materials,
        textures=textures,
        hulls=hulls,
        meta=meta,
        version=version,
        quantized=quantized,
        sections=sections,
        raw=raw,
        _map=keep,
    )


def _inflate(view: memoryview, s: Section, name: str, start: int | None = None) -> bytes:
    """Decompress a deflated section to exactly the size its shape states (never more).

    ``view`` is the file (the section at ``s.offset``), or the section alone when ``start`` is 0.
    """
    expected = s.shape[0] * (s.shape[1] if len(s.shape) == 2 else 1) * fmt.DTYPES[fmt.CODES[s.dtype]].itemsize
    inflater = zlib.decompressobj()
    at = s.offset if start is None else start
    try:
        data = inflater.decompress(view[at : at + s.length], expected)
        complete = inflater.eof and not inflater.unconsumed_tail
    except zlib.error as exc:
        raise PackFormatError(
            f"section {s.kind!r} is not a valid deflate stream ({exc})", path=name, offset=s.offset
        ) from None
    if len(data) != expected or not complete:
        raise PackFormatError(
            f"section {s.kind!r} inflates to a size other than its shape states ({expected} bytes)",
            path=name,
            offset=s.offset,
        )
    return data


#: JSON bytes mapped to the shape of their number literals: digits to ``0``, ``e``/``E`` to ``e``, both signs
#: to ``+``, every other byte to a space (a JSON number is ASCII: no byte of a multi-byte character is a digit).
_NUMBER_SHAPE = bytes(
    (ord("0") if chr(c).isdigit() else ord("e") if chr(c) in "eE" else ord("+") if chr(c) in "+-" else ord(" "))
    if c < 128
    else ord(" ")
    for c in range(256)
)
_DIGITS_200 = b"0" * 200


def _may_overflow(data: bytes) -> bool:
    """Whether some number literal of the JSON ``data`` could overflow a float (over 1.8e308) to infinity.

    Only a literal with an exponent of 3 or more digits or, with at most 2 (at most e99), an integer part
    of at least 210 digits can: the bytes are searched for ``e``/``E`` and an optional sign before 3 digits,
    and for 200 digits in a row (anywhere, strings included: a false match only takes the checked path).
    """
    shape = data.translate(_NUMBER_SHAPE)
    return b"e000" in shape or b"e+000" in shape or _DIGITS_200 in shape


def _json(stored: bytes, s: Section, name: str, kind: type) -> Any:
    """A JSON section's value from its ``stored`` bytes, every number checked finite."""
    data = _inflate(memoryview(stored), s, name, 0) if s.encoding == fmt.ENC_DEFLATE else stored
    try:
        text = data.decode("utf-8")
        # every float literal that could overflow to infinity (1e999) goes through the finiteness check; JSON
        # where none can is decoded by json's C float path (float(literal), what finite_float returns, without
        # a Python call per number)
        if not _may_overflow(data):
            value = json.loads(text, parse_constant=check.reject_constant)
        else:
            value = json.loads(text, parse_constant=check.reject_constant, parse_float=check.finite_float)
    except (UnicodeDecodeError, ValueError, RecursionError) as exc:
        raise PackFormatError(f"section {s.kind!r} is not UTF-8 JSON ({exc})", path=name, offset=s.offset) from None
    if not isinstance(value, kind):
        raise PackFormatError(f"section {s.kind!r} is not a JSON {kind.__name__}", path=name, offset=s.offset)
    return value


def _decode(arr: npt.NDArray[Any], encoding: int, params: dict[str, Any] | None) -> npt.NDArray[np.float32]:
    if encoding == fmt.ENC_PLAIN:
        result: npt.NDArray[np.float32] = arr
        return result
    if encoding == fmt.ENC_OCT_SNORM16:
        return oct_decode(arr)
    if params is None:
        raise KeyError("lo/hi")
    lo, hi = [float(x) for x in params["lo"]], [float(x) for x in params["hi"]]
    if len(lo) != arr.shape[1] or len(hi) != arr.shape[1]:
        raise ValueError("lo/hi length")
    return dequantize_box(arr, lo, hi)


def _hulls(
    raw: dict[str, npt.NDArray[Any]], by_kind: dict[bytes, Section], name: str
) -> list[tuple[npt.NDArray[np.float32], npt.NDArray[np.uint32]]]:
    table, verts, faces = raw["HULT"], raw["HULV"], raw["HULF"]
    hulls = []
    for row in table.astype(np.int64):
        v0, nv, f0, nf = (int(x) for x in row)
        if v0 + nv > verts.shape[0] or f0 + nf > faces.shape[0]:
            raise PackFormatError(
                "a hull points past the hull arrays", path=name, offset=by_kind[fmt.KIND_HULL_TABLE].offset
            )
        hulls.append((verts[v0 : v0 + nv], faces[f0 : f0 + nf]))
    return hulls
