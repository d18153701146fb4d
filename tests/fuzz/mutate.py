"""Mutation strategies for the fuzz harness (hypothesis): seeds from fixtures, changed the way hostile files are.

A fuzz input is a seed (a fixture file, or a folder of them) with a short list of mutations drawn by
hypothesis: byte flips, inserted tokens from a per-format dictionary (numbers at the edges of float range,
NaN, huge counts, path tricks, NUL bytes, keywords), deleted, duplicated and swapped line ranges, truncation.
Because the mutations are a list, hypothesis shrinks a crash to the fewest mutations that still cause it.

``.mbin`` inputs are mutated structurally (section payloads, shapes, META/MATL JSON values) and then
written back with correct checksums and layout, so that mutations reach the code behind ``verify=True``
instead of stopping at the first CRC check.

Mesh formats are mutated with what they are made of: binary STL's triangle count, float fields, attribute
words and size; PLY values re-encoded in the file's own format, header element counts, property types and
the format/byte-order line; GLB chunks (the JSON chunk as JSON, the BIN chunk as words) with lying length
fields; glTF JSON values (component types, indices, ``data:`` and escaping URIs) and its buffers; COLLADA and
URDF parsed as XML trees (attributes and number lists set to extremes, elements duplicated, dropped or moved,
``instance_node`` cycles, deep chains, missing links, mimic cycles, ``package://`` variants).

Those mesh mutators live in :mod:`mutate_mesh` (STL, PLY, glTF/GLB) and :mod:`mutate_xml` (COLLADA, URDF);
this module keeps the generic machinery (byte and token mutations, documents, binary buffers) and the OBJ,
MTL, ``.mbin``, TOML (scenes, commands) and ``.simlog`` mutators.
"""

from __future__ import annotations

import json
import struct
import zlib
from typing import Any

from hypothesis import strategies as st

NUMBERS = [
    b"0", b"-0", b"1", b"-1", b"2", b"3", b"65535", b"65536", b"4294967295", b"4294967296", b"-2147483649",
    b"1e308", b"-1e308", b"1e309", b"3.5e38", b"1e-300", b"5e-324", b"nan", b"NaN", b"-nan", b"inf", b"-inf",
    b"Infinity", b"1_0", b"0x10", b"1e", b"--1", b".", b"", b"99999999999999999999999",
]  # fmt: skip
COMMON = [b"\x00", b"\xff\xfe", b"\xef\xbb\xbf", b"\r", b"\n", b"\r\n", b"\\", b"/", b"../", b"..\\", b"\t", b" "]
OBJ_TOKENS = [
    b"v ", b"vt ", b"vn ", b"f ", b"l ", b"p ", b"o ", b"g ", b"s ", b"usemtl ", b"mtllib ", b"vp ", b"curv ",
    b"f 1 2 3\n", b"f -1 -2 -3\n", b"f 1/1/1 2/2/2 3/3/3\n", b"f 1//1 2//2 3//3\n", b"f 0 0 0\n", b"v 0 0 0\n",
    b"f 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1\n",
    b"v 1e308 -1e308 1e308\n", b"v nan inf -inf\n", b"mtllib a b c d e f g h i j k l m n o p q r s t\n",
    b"mtllib ../../../../etc/passwd\n", b"mtllib /dev/zero\n", b"mtllib C:\\x\\y.mtl\n", b"#", b"\\\n",
]  # fmt: skip
MTL_TOKENS = [
    b"newmtl ", b"Kd ", b"Ka ", b"Ks ", b"Ke ", b"Ns ", b"d ", b"Tr ", b"illum ", b"Ni ", b"map_Kd ", b"map_Ka ",
    b"map_Bump ", b"bump ", b"map_d ", b"norm ", b"-s 1 1 1 ", b"-o ", b"-bm ", b"-clamp on ", b"-blendu ",
    b"Kd nan inf -inf\n", b"map_Kd ../outside.png\n", b"map_Kd /etc/passwd\n", b"map_Kd file:///x.png\n",
    b"map_Kd " + b"a" * 300 + b".png\n", b"newmtl \n", b"Tr 1\n", b"d -1\n", b"illum 99999999999\n",
]  # fmt: skip
TOML_TOKENS = [
    b"1e200", b"-1e200", b"1e-12", b"0.0", b"-1.0", b"nan", b"inf", b"-inf", b"[]", b"[1.0]", b"[0, 0, 0]",
    b"[nan, nan, nan]", b'""', b'"x"', b"true", b"{}", b"[[entities]]\n", b"[world]\n", b"[assets]\n",
    b'type = "mesh"\n', b'type = "box"\n', b'type = "robot"\n', b'type = "heightfield"\n', b'parent = "x"\n',
    b'scale = 1e200\n', b"timestep = 1e-12\n", b'eye = [0, 0, 0]\ntarget = [0, 0, 0]\n', b"\xff\xfe", b"\x00",
    b'"../../../etc/passwd"', b'"/dev/zero"', b"9223372036854775808", b"-9223372036854775809",
]  # fmt: skip
SIMLOG_TOKENS = [
    b'"frame_period": -1', b'"frame_period": 0', b'"state_size": -1', b'"state_size": 1e9', b'"commands": [[]]',
    b"nan", b"NaN", b"Infinity", b"-Infinity", b'"controller": "/etc/passwd"', b"{}", b"[]", b"null", b"\x00",
    b"\xff\xff\xff\xff", b"\x00\x00\x00\x80", b"\x01", b"\x02", b"\x03",
]  # fmt: skip


COMMAND_TOKENS = [
    b"[[commands]]\n", b"[[expect]]\n", b"[commands]\n", b'service = "ArmService"\n', b'service = "GPS"\n',
    b'call = "tick"\n', b'call = "reset"\n', b'call = "restore"\n', b'call = "snapshot"\n', b'call = "__init__"\n',
    b'call = "busy"\n', b'call = "odometry"\n', b'entity = "base/arm"\n', b'entity = ""\n', b"args = [[1, 2], 3]\n",
    b"args = [{}]\n", b"args = [[[]]]\n", b"t = 1e300\n", b"t = 604800.0000001\n", b"t = -0.0\n", b"t = true\n",
]  # fmt: skip
COMMAND_VALUES: list[Any] = [
    "DriveService", "ArmService", "GPS", "Camera", "move_to", "set_joint_targets", "drive_distance", "cmd_vel",
    "rotate_degrees", "enable", "tick", "reset", "snapshot", "restore", "joint_states", "odometry", "encoders",
    "speed_loop", "servo_design", "__class__", "base/arm", "base", "boebot", "p3dx", "base/", "/", [0.0] * 6,
    [[0.0] * 6, 1.0], [[0.0] * 6, 0.0], [[0.0] * 7, 1.0], [[], 1.0], [1e300, 1e300], [0.0, 1e-300], [True, "x"],
    604800.0, 604800.5, 1e-320, [["a"] * 6, 1.0],
]  # fmt: skip


@st.composite
def mutated_bytes(draw: Any, seed: bytes, tokens: list[bytes], max_ops: int = 8) -> bytes:
    """``seed`` with up to ``max_ops`` mutations drawn from byte and token operations."""
    data = bytearray(seed)
    vocabulary = tokens + NUMBERS + COMMON
    for _ in range(draw(st.integers(0, max_ops))):
        op = draw(st.sampled_from(["flip", "insert", "replace_number", "delete", "duplicate", "truncate", "swap"]))
        n = len(data)
        at = draw(st.integers(0, n)) if n else 0
        if op == "flip" and n:
            k = min(at, n - 1)
            data[k] = draw(st.integers(0, 255))
        elif op == "insert":
            token = draw(st.sampled_from(vocabulary)) if draw(st.booleans()) else draw(st.binary(max_size=8))
            data[at:at] = token * draw(st.sampled_from([1, 1, 1, 2, 16, 1000]))
        elif op == "replace_number" and n:
            data = bytearray(_replace_number(bytes(data), at, draw(st.sampled_from(NUMBERS))))
        elif op == "delete" and n:
            span = draw(st.integers(1, max(1, min(n - min(at, n - 1), 256))))
            del data[at : at + span]
        elif op == "duplicate" and n:
            start, end = sorted((at, draw(st.integers(0, n))))
            data[end:end] = data[start:end][:4096] * draw(st.sampled_from([1, 2, 50]))
        elif op == "truncate" and n:
            del data[at:]
        elif op == "swap" and n:
            lines = bytes(data).split(b"\n")
            i, j = draw(st.integers(0, len(lines) - 1)), draw(st.integers(0, len(lines) - 1))
            lines[i], lines[j] = lines[j], lines[i]
            data = bytearray(b"\n".join(lines))
    return bytes(data)


def _replace_number(data: bytes, at: int, number: bytes) -> bytes:
    """Replace the number (run of digits, sign, dot, exponent) nearest after ``at`` with ``number``."""
    digits = b"0123456789"
    k = at
    while k < len(data) and data[k] not in digits:
        k += 1
    if k >= len(data):
        return data
    start = k
    while start > 0 and data[start - 1] in b"+-.":
        start -= 1
    end = k
    while end < len(data) and data[end] in digits + b".eE+-":
        end += 1
    return data[:start] + number + data[end:]


# -- .mbin: structure-aware mutations, written back with valid checksums --------------------------------------

HEADER = struct.Struct("<8sHHIIIQI28s")
ENTRY = struct.Struct("<4sBBHQQQQII16s")


def split_pack(data: bytes) -> tuple[tuple[Any, ...], list[list[Any]], list[bytes]] | None:
    """The header fields, table rows and section payloads of a well-formed ``.mbin`` (``None`` otherwise)."""
    if len(data) < 64:
        return None
    header = list(HEADER.unpack_from(data, 0))
    count, table = header[4], header[5]
    if table + 64 * count > len(data):
        return None
    rows, payloads = [], []
    for k in range(count):
        row = list(ENTRY.unpack_from(data, table + 64 * k))
        offset, length = row[6], row[7]
        if offset + length > len(data):
            return None
        rows.append(row)
        payloads.append(data[offset : offset + length])
    return tuple(header), rows, payloads


def join_pack(header: tuple[Any, ...], rows: list[list[Any]], payloads: list[bytes]) -> bytes:
    """Lay sections out 64-byte aligned after the table and write every checksum and length correctly."""
    table_offset = 64
    offset = table_offset + 64 * len(rows)
    body = bytearray()
    fixed = []
    for row, payload in zip(rows, payloads, strict=True):
        offset += -offset % 64
        pad = offset - (table_offset + 64 * len(rows)) - len(body)
        body += b"\0" * pad
        row = list(row)
        row[6], row[7], row[8] = offset, len(payload), zlib.crc32(payload)
        fixed.append(row)
        body += payload
        offset += len(payload)
    table = b"".join(ENTRY.pack(*row) for row in fixed)
    size = table_offset + len(table) + len(body)
    head = list(header)
    head[4], head[5], head[6] = len(rows), table_offset, size
    first32 = HEADER.pack(*head[:7], 0, b"\0" * 28)[:32]
    head[7] = zlib.crc32(first32 + table)
    return HEADER.pack(*head) + table + bytes(body)


JSON_VALUES: list[Any] = [
    None, True, -1, 0, 2**31, 2**64, 1e308, -1e308, float("nan"), float("inf"), "", "x" * 300, "../x.png",
    [], {}, [1, 2], {"a": 1}, [[0, 0, 0]], 3.5,
]  # fmt: skip


def _mutate_json(draw: Any, value: Any, depth: int = 0) -> Any:
    if isinstance(value, dict) and value and depth < 6:
        key = draw(st.sampled_from(sorted(value)))
        out = dict(value)
        if draw(st.integers(0, 9)) == 0:
            out.pop(key)
        else:
            out[key] = _mutate_json(draw, value[key], depth + 1)
        return out
    if isinstance(value, list) and value and depth < 6:
        k = draw(st.integers(0, len(value) - 1))
        out = list(value)
        out[k] = _mutate_json(draw, value[k], depth + 1)
        return out
    return draw(st.sampled_from(JSON_VALUES))


@st.composite
def mutated_pack(draw: Any, seed: bytes) -> bytes:
    """A structurally mutated ``.mbin`` with correct checksums (or raw byte mutations, 1 in 5)."""
    parts = split_pack(seed)
    if parts is None or draw(st.integers(0, 4)) == 0:
        return bytes(draw(mutated_bytes(seed, [b"META", b"POS ", b"IDX ", b"SUBM", b"HULV", b"HULF"])))
    header, rows, payloads = parts
    rows = [list(r) for r in rows]
    payloads = list(payloads)
    for _ in range(draw(st.integers(1, 4))):
        k = draw(st.integers(0, len(rows) - 1))
        kind, dtype = rows[k][0], rows[k][1]
        op = draw(st.sampled_from(["json", "value", "shape", "drop", "duplicate", "bytes", "dtype"]))
        if op == "json" and dtype == 0 and rows[k][9] == 0:
            try:
                document = json.loads(payloads[k])
            except ValueError:
                continue
            text = json.dumps(_mutate_json(draw, document)).encode("utf-8")
            payloads[k] = text
            rows[k][4] = len(text)
        elif op == "value" and payloads[k]:
            raw = bytearray(payloads[k])
            width = {1: 1, 2: 2, 3: 4, 4: 2, 5: 4}.get(dtype, 1)
            at = draw(st.integers(0, max(0, len(raw) // width - 1))) * width
            extremes = [b"\xff" * width, b"\x00" * width, b"\x7f\x7f\x7f\x7f"[:width], b"\x00\x00\xc0\x7f"[:width]]
            value = draw(st.sampled_from(extremes))
            raw[at : at + width] = value
            payloads[k] = bytes(raw)
        elif op == "shape":
            rows[k][4] = draw(st.sampled_from([0, 1, 2, 3, rows[k][4] + 1, max(0, rows[k][4] - 1), 2**32]))
            rows[k][5] = draw(st.sampled_from([rows[k][5], 0, 1, 2, 3, 4]))
        elif op == "drop" and len(rows) > 1:
            del rows[k], payloads[k]
        elif op == "duplicate":
            rows.append(list(rows[k]))
            payloads.append(payloads[k])
        elif op == "bytes":
            payloads[k] = bytes(draw(mutated_bytes(payloads[k][:65536], [], 3)))
            if rows[k][9] == 0:
                itemsize = {0: 1, 1: 1, 2: 2, 3: 4, 4: 2, 5: 4}.get(dtype, 1)
                cols = rows[k][5] if rows[k][2] == 2 and rows[k][5] else 1
                rows[k][4] = len(payloads[k]) // max(1, itemsize * cols)
        elif op == "dtype":
            rows[k][1] = draw(st.integers(0, 6))
        del kind
    return join_pack(header, rows, payloads)


# -- structured documents: TOML scenes, the .simlog JSON header -----------------------------------------------

TOML_VALUES: list[Any] = [
    True, 0, -1, 1, 2**63 - 1, -(2**63), 1e200, -1e200, 1e-12, 0.0, -0.0, float("nan"), float("inf"),
    float("-inf"), "", "x", "../../../etc/passwd", "/dev/zero", "a" * 300, "\u00e9\u0000", [], [0.0, 0.0, 0.0],
    [float("nan")] * 3, [1e200] * 3, [0, 0], [[0, 0], [0]], {}, {"type": "box"}, [{"type": "box"}],
]  # fmt: skip


def _mutate_document(draw: Any, value: Any, values: list[Any], depth: int = 0) -> Any:
    """One value somewhere inside a JSON/TOML document replaced, dropped, duplicated or added."""
    if isinstance(value, dict) and value and depth < 8 and draw(st.integers(0, 4)):
        out = dict(value)
        key = draw(st.sampled_from(sorted(value)))
        op = draw(st.integers(0, 9))
        if op == 0:
            out.pop(key)
        elif op == 1:
            out[draw(st.sampled_from(["x", "type", "name", "scale", "size", "pose", key + "_"]))] = draw(
                st.sampled_from(values)
            )
        else:
            out[key] = _mutate_document(draw, value[key], values, depth + 1)
        return out
    if isinstance(value, list) and value and depth < 8 and draw(st.integers(0, 4)):
        out_list = list(value)
        k = draw(st.integers(0, len(value) - 1))
        op = draw(st.integers(0, 9))
        if op == 0:
            del out_list[k]
        elif op == 1:
            out_list.append(value[k])
        else:
            out_list[k] = _mutate_document(draw, value[k], values, depth + 1)
        return out_list
    return draw(st.sampled_from(values))


@st.composite
def mutated_toml(draw: Any, seed: bytes, extra: list[Any] | None = None) -> bytes:
    """A TOML document with 1-4 values changed structurally (parsed, changed, written back; ``extra``: more
    values to draw from)."""
    import tomllib

    import tomli_w

    try:
        document = tomllib.loads(seed.decode("utf-8"))
    except (UnicodeDecodeError, tomllib.TOMLDecodeError):
        return seed
    for _ in range(draw(st.integers(1, 4))):
        document = _mutate_document(draw, document, TOML_VALUES + (extra or []))
    try:
        return tomli_w.dumps(document).encode("utf-8")
    except Exception:  # a shape TOML cannot write (a table inside an inline array, ...): keep the seed
        return seed


def mutated_json(draw: Any, seed: bytes) -> bytes:
    """A JSON document with 1-4 values changed structurally (NaN and infinities written as JSON allows)."""
    try:
        document = json.loads(seed)
    except ValueError:
        return seed
    for _ in range(draw(st.integers(1, 4))):
        document = _mutate_document(draw, document, JSON_VALUES + TOML_VALUES)
    return json.dumps(document).encode("utf-8")


def mutated_document_json(draw: Any, seed: bytes, extra: list[Any]) -> bytes:
    """Like :func:`mutated_json`, with ``extra`` values (a format's own codes, names and URIs) in the pool."""
    try:
        document = json.loads(seed)
    except ValueError:
        return seed
    for _ in range(draw(st.integers(1, 4))):
        document = _mutate_document(draw, document, JSON_VALUES + TOML_VALUES + extra)
    return json.dumps(document).encode("utf-8")


# -- binary buffers: words set to extremes ----------------------------------------------------------------

#: 4-byte words that break readers: NaN, infinities, the float32 maximum, the smallest subnormal, -0.0,
#: 0xFFFFFFFF, INT32_MIN and INT32_MAX.
WORDS = [
    struct.pack("<f", float("nan")), struct.pack("<f", float("inf")), struct.pack("<f", float("-inf")),
    struct.pack("<f", 3.4e38), struct.pack("<f", -3.4e38), b"\x01\x00\x00\x00", struct.pack("<f", -0.0),
    b"\xff\xff\xff\xff", b"\x00\x00\x00\x80", b"\xff\xff\xff\x7f", b"\x00\x00\x00\x00",
]  # fmt: skip


@st.composite
def mutated_buffer(draw: Any, seed: bytes, max_ops: int = 4, endian: str = "<") -> bytes:
    """A binary buffer with 1..``max_ops`` aligned words or halves set to extremes, truncated or grown."""
    data = bytearray(seed)
    for _ in range(draw(st.integers(1, max_ops))):
        op = draw(st.sampled_from(["word", "word", "word", "half", "byte", "truncate", "append"]))
        n = len(data)
        if op == "word" and n >= 4:
            at = draw(st.integers(0, n // 4 - 1)) * 4
            word = draw(st.sampled_from(WORDS))
            data[at : at + 4] = word if endian == "<" else word[::-1]
        elif op == "half" and n >= 2:
            at = draw(st.integers(0, n // 2 - 1)) * 2
            data[at : at + 2] = draw(st.sampled_from([b"\xff\xff", b"\x00\x80", b"\xff\x7f", b"\x00\x00"]))
        elif op == "byte" and n:
            data[draw(st.integers(0, n - 1))] = draw(st.integers(0, 255))
        elif op == "truncate" and n:
            del data[draw(st.integers(0, n - 1)) :]
        elif op == "append":
            data += draw(st.binary(max_size=16)) * draw(st.sampled_from([1, 4, 1000]))
    return bytes(data)
