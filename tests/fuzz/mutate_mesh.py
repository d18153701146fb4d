"""Mutators for binary and JSON mesh formats (STL, PLY, glTF/GLB), built on the generic machinery of :mod:`mutate`.

Mesh formats are mutated with what they are made of: binary STL's triangle count, float fields, attribute
words and size; PLY values re-encoded in the file's own format, header element counts, property types and
the format/byte-order line; GLB chunks (the JSON chunk as JSON, the BIN chunk as words) with lying length
fields; glTF JSON values (component types, indices, ``data:`` and escaping URIs) and its buffers.
"""

from __future__ import annotations

import math
import struct
from typing import Any

from hypothesis import strategies as st
from mutate import WORDS, mutated_buffer, mutated_bytes, mutated_document_json

# -- STL: the binary header's triangle count, float fields, attribute words ------------------------------------

STL_TOKENS = [
    b"solid ", b"solid\n", b"endsolid", b"endsolid\n", b"facet normal ", b"facet normal 0 0 0\n", b"outer loop\n",
    b"endloop\n", b"endfacet\n", b"vertex ", b"vertex 1 2 3\n", b"vertex nan inf -inf\n", b"vertex 1e39 0 0\n",
    b"facet\n", b"outer loop\nvertex 0 0 0\nvertex 0 0 0\nendloop\n", b"endsolid x\nsolid y\n", b"solid ascii",
]  # fmt: skip


def stl_is_binary(data: bytes) -> bool:
    """Whether ``data`` is a well-formed binary STL (84-byte header, 50 bytes per triangle as counted)."""
    return len(data) >= 84 and 84 + 50 * int.from_bytes(data[80:84], "little") == len(data)


@st.composite
def mutated_stl(draw: Any, seed: bytes) -> bytes:
    """A binary STL changed in its structure (count, floats, attributes, header, size), or ASCII STL as text."""
    if not stl_is_binary(seed) or draw(st.integers(0, 4)) == 0:
        return bytes(draw(mutated_bytes(seed, STL_TOKENS)))
    data = bytearray(seed)
    count = int.from_bytes(seed[80:84], "little")
    for _ in range(draw(st.integers(1, 4))):
        op = draw(st.sampled_from(["count", "count", "float", "float", "attribute", "header", "resize", "degenerate"]))
        triangles = max(0, (len(data) - 84) // 50)
        if op == "count":
            value = draw(st.sampled_from([0, 1, count - 1, count + 1, 2 * count, 2**24, 2**31 - 1, 2**31, 2**32 - 1]))
            data[80:84] = (value % 2**32).to_bytes(4, "little")
        elif op == "float" and triangles:
            at = 84 + 50 * draw(st.integers(0, triangles - 1)) + 4 * draw(st.integers(0, 11))
            data[at : at + 4] = draw(st.sampled_from(WORDS))
        elif op == "attribute" and triangles:
            at = 84 + 50 * draw(st.integers(0, triangles - 1)) + 48
            data[at : at + 2] = draw(st.sampled_from([b"\xff\xff", b"\x00\x80", b"\x1f\x7c", b"\x01\x00"]))
        elif op == "header":
            text = draw(st.sampled_from([b"solid x", b"solid x\nfacet normal 0 0 1\n", b"COLOR=\xff\x00\x00\xff", b""]))
            data[:80] = (text + b"\0" * 80)[:80]
        elif op == "resize":
            size = draw(st.sampled_from([0, 80, 83, 84, 85, 84 + 49, 84 + 50 * max(0, triangles - 1), len(data) - 1]))
            if draw(st.booleans()):
                del data[max(0, size) :]
            else:
                data += data[84 : 84 + 50] * draw(st.sampled_from([1, 1000])) + draw(st.binary(max_size=49))
        elif op == "degenerate" and triangles:  # a triangle's three corners made equal
            at = 84 + 50 * draw(st.integers(0, triangles - 1))
            data[at + 24 : at + 48] = data[at + 12 : at + 24] * 2
    return bytes(data)


# -- PLY: header counts, types, byte order; body values re-encoded in the file's own format --------------------

PLY_TYPES = [
    "char", "uchar", "short", "ushort", "int", "uint", "float", "double", "int8", "uint8", "int16", "uint16",
    "int32", "uint32", "float32", "float64", "int64", "long", "string", "",
]  # fmt: skip
PLY_FORMATS = ["ascii", "binary_little_endian", "binary_big_endian", "binary", "ASCII", ""]
PLY_LINES = [
    b"comment TextureFile ../../outside.png", b"comment TextureFile /dev/zero", b"comment TextureFile ",
    b"obj_info x", b"element face 1", b"element vertex 4294967296", b"element material 1", b"property float x",
    b"property list uchar float texcoord", b"property list uint int vertex_indices", b"property list uchar int x",
    b"property uchar red", b"property float nx", b"property list float float vertex_indices", b"property",
    b"element", b"end_header", b"format ascii 1.0", b"format binary_big_endian 1.0", b"ply",
]  # fmt: skip
PLY_TOKENS = [b"ply\n", b"end_header\n", b"element ", b"property ", b"format ", b"comment ", *PLY_LINES]
_PLY_STRUCT = {
    "char": "b", "int8": "b", "uchar": "B", "uint8": "B", "short": "h", "int16": "h", "ushort": "H", "uint16": "H",
    "int": "i", "int32": "i", "uint": "I", "uint32": "I", "float": "f", "float32": "f", "double": "d", "float64": "d",
}  # fmt: skip

PlyElement = tuple[str, int, list[list[str]]]


def split_ply(data: bytes) -> tuple[list[bytes], bytes] | None:
    """The header lines (through ``end_header``) and the body, or ``None`` without an ``end_header`` line."""
    end = data.find(b"end_header")
    newline = data.find(b"\n", end)
    if end < 0 or newline < 0:
        return None
    return data[:newline].split(b"\n"), data[newline + 1 :]


def join_ply(lines: list[bytes], body: bytes) -> bytes:
    """The inverse of :func:`split_ply`."""
    return b"\n".join(lines) + b"\n" + body


def ply_elements(lines: list[bytes]) -> tuple[str, list[PlyElement]] | None:
    """The format and the ``(name, count, properties)`` of each element, or ``None`` when unreadable."""
    fmt, elements = "", []
    for line in lines:
        words = line.decode("ascii", "replace").split()
        if words[:1] == ["format"] and len(words) >= 2:
            fmt = words[1]
        elif words[:1] == ["element"] and len(words) == 3 and words[2].isdigit():
            elements.append((words[1], int(words[2]), []))
        elif words[:1] == ["property"] and elements and len(words) >= 3:
            types = words[1:-1]
            shaped = len(types) == (3 if types[0] == "list" else 1)
            if shaped and all(t in _PLY_STRUCT for t in types if t != "list"):
                elements[-1][2].append(types)
                continue
            return None
        elif words[:1] in (["element"], ["property"]):
            return None
    return (fmt, elements) if fmt in PLY_FORMATS[:3] else None


def decode_ply(fmt: str, elements: list[PlyElement], body: bytes) -> list[list[list[Any]]] | None:
    """Each element's rows (a list of values per property; a list property is a list), or ``None``."""
    out: list[list[list[Any]]] = []
    if fmt == "ascii":
        words = body.split()
        at = 0
        try:
            for _name, count, props in elements:
                rows = []
                for _ in range(count):
                    row: list[Any] = []
                    for types in props:
                        scalar = types[-1]
                        if types[0] == "list":
                            n = int(words[at])
                            row.append([_ply_number(words[at + 1 + k], scalar) for k in range(n)])
                            at += 1 + n
                        else:
                            row.append(_ply_number(words[at], scalar))
                            at += 1
                    rows.append(row)
                out.append(rows)
        except (IndexError, ValueError):
            return None
        return out
    endian = "<" if fmt == "binary_little_endian" else ">"
    offset = 0
    try:
        for _name, count, props in elements:
            rows = []
            for _ in range(count):
                row = []
                for types in props:
                    if types[0] == "list":
                        (n,) = struct.unpack_from(endian + _PLY_STRUCT[types[1]], body, offset)
                        offset += struct.calcsize(_PLY_STRUCT[types[1]])
                        code = f"{endian}{n}{_PLY_STRUCT[types[2]]}"
                        row.append(list(struct.unpack_from(code, body, offset)))
                        offset += struct.calcsize(code)
                    else:
                        code = endian + _PLY_STRUCT[types[0]]
                        row.append(struct.unpack_from(code, body, offset)[0])
                        offset += struct.calcsize(code)
                rows.append(row)
            out.append(rows)
    except struct.error:
        return None
    return out


def _ply_number(word: bytes, kind: str) -> float | int:
    return float(word) if _PLY_STRUCT[kind] in "fd" else int(word)


def encode_ply(fmt: str, elements: list[PlyElement], rows: list[list[list[Any]]]) -> bytes:
    """The body of ``rows`` in ``fmt`` (integers wrapped to their type's width, as a writer would)."""
    if fmt == "ascii":
        lines = []
        for (_name, _count, props), element_rows in zip(elements, rows, strict=True):
            for row in element_rows:
                words = []
                for types, value in zip(props, row, strict=True):
                    if types[0] == "list":
                        words += [str(len(value)), *(_ply_text(v, types[2]) for v in value)]
                    else:
                        words.append(_ply_text(value, types[0]))
                lines.append(" ".join(words))
        return ("\n".join(lines) + "\n").encode("ascii")
    endian = "<" if fmt == "binary_little_endian" else ">"
    out = bytearray()
    for (_name, _count, props), element_rows in zip(elements, rows, strict=True):
        for row in element_rows:
            for types, value in zip(props, row, strict=True):
                if types[0] == "list":
                    out += _ply_pack(endian, types[1], len(value))
                    for v in value:
                        out += _ply_pack(endian, types[2], v)
                else:
                    out += _ply_pack(endian, types[0], value)
    return bytes(out)


def _ply_text(value: Any, kind: str) -> str:
    return repr(float(value)) if _PLY_STRUCT[kind] in "fd" else str(int(value))


def _ply_pack(endian: str, kind: str, value: Any) -> bytes:
    code = _PLY_STRUCT[kind]
    if code in "fd":
        try:
            return struct.pack(endian + code, float(value))
        except OverflowError:  # beyond float32: what a writer rounding to float32 gives
            return struct.pack(endian + code, math.copysign(math.inf, value))
    bits = 8 * struct.calcsize(code)
    wrapped = int(value) % 2**bits
    if code.islower() and wrapped >= 2 ** (bits - 1):
        wrapped -= 2**bits
    return struct.pack(endian + code, wrapped)


def reencode_ply(data: bytes, fmt: str) -> bytes | None:
    """``data`` written in another PLY format (``ascii``, ``binary_little_endian``, ``binary_big_endian``)."""
    parts = split_ply(data)
    parsed = ply_elements(parts[0]) if parts else None
    if parts is None or parsed is None:
        return None
    rows = decode_ply(parsed[0], parsed[1], parts[1])
    if rows is None:
        return None
    lines = [b"format " + fmt.encode() + b" 1.0" if line.startswith(b"format ") else line for line in parts[0]]
    return join_ply(lines, encode_ply(fmt, parsed[1], rows))


PLY_INTS = [-1, 0, 1, 2, 3, 255, 256, 65535, 2**31 - 1, 2**31, 2**32 - 1]
PLY_FLOATS = [float("nan"), float("inf"), float("-inf"), 3.4e38, -0.0, 1e-45, 1e300]


@st.composite
def mutated_ply(draw: Any, seed: bytes) -> bytes:
    """A PLY with values changed (re-encoded in its format), header counts/types/format changed, or bytes."""
    parts = split_ply(seed)
    parsed = ply_elements(parts[0]) if parts else None
    if parts is None or parsed is None or draw(st.integers(0, 5)) == 0:
        return bytes(draw(mutated_bytes(seed, PLY_TOKENS)))
    lines, body = list(parts[0]), parts[1]
    fmt, elements = parsed
    rows = decode_ply(fmt, elements, body)
    if rows is not None and draw(st.booleans()):  # values inside the body, still well formed
        rows = [[list(r) for r in element_rows] for element_rows in rows]
        for _ in range(draw(st.integers(1, 3))):
            k = draw(st.integers(0, len(rows) - 1))
            if not rows[k]:
                continue
            row = rows[k][draw(st.integers(0, len(rows[k]) - 1))]
            p = draw(st.integers(0, len(row) - 1))
            types = elements[k][2][p]
            floats = _PLY_STRUCT[types[-1]] in "fd"
            if types[0] == "list":
                choice = draw(st.integers(0, 3))
                if choice == 0:
                    row[p] = []
                elif choice == 1:
                    row[p] = row[p][:1] * draw(st.sampled_from([1, 2, 255, 300]))
                elif row[p]:
                    row[p][draw(st.integers(0, len(row[p]) - 1))] = draw(
                        st.sampled_from(PLY_FLOATS if floats else [*PLY_INTS, elements[0][1]])
                    )
            else:
                row[p] = draw(st.sampled_from(PLY_FLOATS if floats else PLY_INTS))
        body = encode_ply(fmt, elements, rows)
    for _ in range(draw(st.integers(0 if rows is not None else 1, 3))):  # the header, the body kept
        op = draw(st.sampled_from(["format", "count", "count", "type", "drop", "duplicate", "insert", "swap"]))
        k = draw(st.integers(0, len(lines) - 1))
        words = lines[k].split(b" ")
        if op == "format":
            fmts = [f.encode() for f in PLY_FORMATS]
            version = draw(st.sampled_from([b"1.0", b"2.0", b"", b"1e9"]))
            at = next((i for i, line in enumerate(lines) if line.startswith(b"format")), 1)
            lines[at] = b" ".join([b"format", draw(st.sampled_from(fmts)), version])
        elif op == "count":
            counted = [i for i, line in enumerate(lines) if line.startswith(b"element")]
            if counted:
                at = draw(st.sampled_from(counted))
                words = lines[at].split(b" ")
                old = int(words[-1]) if words[-1].isdigit() else 1
                value = draw(st.sampled_from([0, 1, old - 1, old + 1, 2 * old, 2**31 - 1, 2**32, 2**63, -1]))
                lines[at] = b" ".join([*words[:-1], str(value).encode()])
        elif op == "type" and words[0] == b"property" and len(words) >= 3:
            words[draw(st.integers(1, len(words) - 2))] = draw(st.sampled_from(PLY_TYPES)).encode()
            lines[k] = b" ".join(words)
        elif op == "drop" and 0 < k < len(lines) - 1:
            del lines[k]
        elif op == "duplicate" and 0 < k < len(lines) - 1:
            lines.insert(k, lines[k])
        elif op == "insert":
            lines.insert(max(1, min(k, len(lines) - 1)), draw(st.sampled_from(PLY_LINES)))
        elif op == "swap" and len(lines) > 3:
            j = draw(st.integers(1, len(lines) - 2))
            k = max(1, min(k, len(lines) - 2))
            lines[j], lines[k] = lines[k], lines[j]
    if draw(st.integers(0, 3)) == 0:
        body = bytes(draw(mutated_buffer(body, 2, ">" if fmt == "binary_big_endian" else "<")))
    return join_ply(lines, body)


# -- GLB: chunk lengths and types, the JSON chunk as JSON, the BIN chunk as words -----------------------------

GLB_JSON, GLB_BIN = 0x4E4F534A, 0x004E4942
GLTF_TOKENS = [
    b'"uri": "', b'"bufferView": ', b'"byteOffset": ', b'"count": ', b'"componentType": ', b"data:", b";base64,",
    b"%00", b"{", b"}", b"[", b"]", b'"', b",", b"null", b"1e999", b"-1", b"[" * 2000, b"\\u0000", b"\\ud800",
]  # fmt: skip
GLTF_VALUES: list[Any] = [
    5120, 5121, 5122, 5123, 5125, 5126, 5124, 0, 34962, 34963, "SCALAR", "VEC2", "VEC3", "VEC4", "MAT4", "X", 4, 7,
    -1, 2**31 - 1, 2**53, 1.5, "2.0", "1.0", "3.0", "data:application/octet-stream;base64,AAAA",
    "data:application/octet-stream;base64,!!!", "data:application/octet-stream,%00%01%02", "data:;base64,",
    "data:image/png;base64,iVBORw0KGgo=", "cube.bin", "../outside.bin", "/etc/passwd", "file:///etc/passwd",
    "https://example.com/x.bin", "textures/missing.png", "a%2F..%2F..%2Fx.bin", ["KHR_draco_mesh_compression"],
    {"POSITION": 0}, {"POSITION": 99}, [0, 0], [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1], [0.0] * 16,
]  # fmt: skip


def split_glb(data: bytes) -> tuple[int, list[tuple[int, bytes]]] | None:
    """The version and ``(type, payload)`` chunks of a well-formed GLB, or ``None``."""
    if len(data) < 12 or data[:4] != b"glTF":
        return None
    version, length = struct.unpack_from("<II", data, 4)
    if length != len(data):
        return None
    chunks, offset = [], 12
    while offset + 8 <= length:
        size, kind = struct.unpack_from("<II", data, offset)
        if offset + 8 + size > length:
            return None
        chunks.append((kind, data[offset + 8 : offset + 8 + size]))
        offset += 8 + size + (-size % 4)
    return version, chunks


def join_glb(version: int, chunks: list[tuple[int, bytes]]) -> bytes:
    """A GLB of ``chunks``, each padded to 4 bytes (JSON with spaces), every length correct."""
    body = bytearray()
    for kind, payload in chunks:
        pad = (b" " if kind == GLB_JSON else b"\0") * (-len(payload) % 4)
        body += struct.pack("<II", len(payload) + len(pad), kind) + payload + pad
    return b"glTF" + struct.pack("<II", version, 12 + len(body)) + bytes(body)


@st.composite
def mutated_glb(draw: Any, seed: bytes) -> bytes:
    """A GLB with its JSON chunk changed as JSON, its BIN chunk as words, chunks or lengths changed."""
    parts = split_glb(seed)
    if parts is None or draw(st.integers(0, 5)) == 0:
        return bytes(draw(mutated_bytes(seed, [b"glTF", b"JSON", b"BIN\0", b'"uri"', b'"bufferView"'], 4)))
    version, chunks = parts[0], list(parts[1])
    for _ in range(draw(st.integers(1, 3))):
        op = draw(st.sampled_from(["json", "json", "json", "bin", "drop", "duplicate", "reverse", "type", "version"]))
        k = draw(st.integers(0, len(chunks) - 1)) if chunks else 0
        if op == "json" and chunks and chunks[0][0] == GLB_JSON:
            chunks[0] = (GLB_JSON, mutated_document_json(draw, chunks[0][1].rstrip(b" "), GLTF_VALUES))
        elif op == "bin" and chunks:
            chunks[k] = (chunks[k][0], draw(mutated_buffer(chunks[k][1])))
        elif op == "drop" and chunks:
            del chunks[k]
        elif op == "duplicate" and chunks:
            chunks.append(chunks[k])
        elif op == "reverse":
            chunks.reverse()
        elif op == "type" and chunks:
            chunks[k] = (draw(st.sampled_from([GLB_JSON, GLB_BIN, 0, 0xFFFFFFFF])), chunks[k][1])
        elif op == "version":
            version = draw(st.sampled_from([0, 1, 3, 2**32 - 1]))
    data = bytearray(join_glb(version, chunks))
    if draw(st.integers(0, 2)) == 0:  # a length field lies (total or a chunk's), or the file is cut short
        offsets, at = [8], 12
        while at + 8 <= len(data):
            offsets.append(at)
            at += 8 + int.from_bytes(data[at : at + 4], "little")
        field = draw(st.sampled_from(offsets))
        old = int.from_bytes(data[field : field + 4], "little")
        value = draw(st.sampled_from([0, 1, 7, old - 1, old + 1, old + 4, 2**31, 2**32 - 1]))
        data[field : field + 4] = (value % 2**32).to_bytes(4, "little")
        if draw(st.booleans()):
            del data[draw(st.integers(0, len(data))) :]
    return bytes(data)
