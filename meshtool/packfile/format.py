"""The ``.mbin`` container layout: constants and structured little-endian dtypes (see docs/mbin-spec.md)."""

from __future__ import annotations

import zlib
from typing import Any

import numpy as np
import xxhash

MAGIC = b"\x89MBN\r\n\x1a\n"  # 8 bytes, PNG-style
#: The version this writer writes; readers read every minor version of major 1 (see :func:`checksum`).
MAJOR, MINOR = 1, 1
ALIGN = 64
HEADER_SIZE = 64
ENTRY_SIZE = 64
FLAG_QUANTIZED = 1

HEADER = np.dtype(
    [
        ("magic", "S8"),
        ("major", "<u2"),
        ("minor", "<u2"),
        ("flags", "<u4"),
        ("section_count", "<u4"),
        ("table_offset", "<u4"),
        ("file_length", "<u8"),
        ("table_crc", "<u4"),
        ("reserved", "V28"),
    ]
)
ENTRY = np.dtype(
    [
        ("kind", "S4"),
        ("dtype", "u1"),
        ("ndim", "u1"),
        ("index", "<u2"),
        ("shape", "<u8", (2,)),
        ("offset", "<u8"),
        ("length", "<u8"),
        ("crc", "<u4"),
        ("encoding", "<u4"),
        ("reserved", "V16"),
    ]
)
ENTRY_FIELDS: tuple[str, ...] = (
    "kind",
    "dtype",
    "ndim",
    "index",
    "shape",
    "offset",
    "length",
    "crc",
    "encoding",
    "reserved",
)
assert len(MAGIC) == 8 and HEADER.itemsize == HEADER_SIZE and ENTRY.itemsize == ENTRY_SIZE

#: dtype code -> numpy dtype (little-endian). Code 0 is an opaque byte string (JSON, PNG).
DTYPES: dict[int, np.dtype[np.generic]] = {
    0: np.dtype("u1"),
    1: np.dtype("u1"),
    2: np.dtype("<u2"),
    3: np.dtype("<u4"),
    4: np.dtype("<i2"),
    5: np.dtype("<f4"),
}
CODES = {"bytes": 0, "u8": 1, "u16": 2, "u32": 3, "i16": 4, "f32": 5}

#: Encodings (the ``encoding`` field): how stored numbers map to values.
ENC_PLAIN = 0  # values as stored
ENC_UNORM16_BOX = 1  # u16 q -> lo + q * (hi - lo) / 65535, lo/hi in META "quantization"
ENC_OCT_SNORM16 = 2  # i16 (x, y) octahedral unit vector, q / 32767
ENC_DEFLATE = 3  # the data is a zlib stream of the plain little-endian array (or byte string)
#: A deflated section may not claim more than this many times its stored length (hostile-size guard).
MAX_INFLATE_RATIO = 64

KIND_META = b"META"
KIND_POSITIONS = b"POS "
KIND_NORMALS = b"NRM "
KIND_UVS = b"UV  "
KIND_COLORS = b"COL "
KIND_INDICES = b"IDX "
KIND_SUBMESHES = b"SUBM"
KIND_MATERIALS = b"MATL"
KIND_TEXTURE = b"TEX "
KIND_HULL_TABLE = b"HULT"
KIND_HULL_VERTICES = b"HULV"
KIND_HULL_FACES = b"HULF"

REQUIRED = (
    KIND_META,
    KIND_POSITIONS,
    KIND_INDICES,
    KIND_SUBMESHES,
    KIND_MATERIALS,
    KIND_HULL_TABLE,
    KIND_HULL_VERTICES,
    KIND_HULL_FACES,
)
OPTIONAL = (KIND_NORMALS, KIND_UVS, KIND_COLORS, KIND_TEXTURE)
#: Sections in file order (textures in index order).
ORDER = (
    KIND_POSITIONS,
    KIND_NORMALS,
    KIND_UVS,
    KIND_COLORS,
    KIND_INDICES,
    KIND_SUBMESHES,
    KIND_HULL_TABLE,
    KIND_HULL_VERTICES,
    KIND_HULL_FACES,
    KIND_TEXTURE,
    KIND_MATERIALS,
    KIND_META,
)


def checksum(data: Any, minor: int) -> int:
    """The 32-bit checksum the table stores for ``data`` (a bytes-like object) in a file of version 1.``minor``.

    1.0: CRC-32 (ISO-HDLC, zlib's ``crc32``). 1.1 and later: the low 32 bits of XXH3-64 (seed 0), which runs
    at memory speed (about 20x zlib's CRC-32 on this project's machines).
    """
    if minor == 0:
        return zlib.crc32(data)
    return xxhash.xxh3_64_intdigest(data) & 0xFFFFFFFF


def align(n: int) -> int:
    """``n`` rounded up to a multiple of :data:`ALIGN`."""
    return -(-n // ALIGN) * ALIGN
