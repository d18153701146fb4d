"""PNG facts read from the bytes without decoding a pixel, and the texture size limits.

No imaging library is imported here: the ``.mbin`` verification (:mod:`meshtool.packfile.verify`) and simrun
use these on every load, and :mod:`meshtool.repair.textures` (Pillow) uses the same limits and the same walk.

A PNG is the 8-byte signature and then chunks of ``length (4, big-endian) | type (4) | data | CRC (4)``; the
first chunk is ``IHDR`` with the width and height as big-endian 32-bit integers at bytes 16..24 of the
file (PNG specification, W3C Recommendation 2003, sections 5.2-5.3 and 11.2.2).
"""

from __future__ import annotations

MAX_SIDE = 16384
"""Most pixels along either side of a texture."""
MAX_PIXELS = 1 << 27
"""Most pixels in a texture (134,217,728: 512 MiB as 8-bit RGBA, e.g. 16384 x 8192)."""

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: Offset of the IHDR width in a PNG file (signature 8, chunk length 4, chunk type 4).
IHDR_WIDTH_OFFSET = 16
_MAX_CHUNKS = 100_000  # a PNG with more chunks than this is not walked further


def png_size(data: bytes | memoryview) -> tuple[int, int] | None:
    """(width, height) in pixels from the ``IHDR`` chunk, or ``None`` when the bytes do not start a PNG."""
    head = bytes(data[:24])
    if len(head) < 24 or head[:8] != PNG_SIGNATURE or head[12:16] != b"IHDR":
        return None
    return int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")


def over_limit(width: int, height: int, max_side: int = MAX_SIDE, max_pixels: int = MAX_PIXELS) -> str | None:
    """Why a ``width`` x ``height`` image is over the texture limits, or ``None`` when it is within them."""
    if width > max_side or height > max_side or width * height > max_pixels:
        return f"{width}x{height} pixels is over the texture limit ({max_side} per side, {max_pixels} in all)"
    return None


def png_end(data: bytes | memoryview) -> int | None:
    """Offset just past the ``IEND`` chunk, found by walking the chunks; ``None`` if the walk fails."""
    if bytes(data[:8]) != PNG_SIGNATURE:
        return None
    pos = len(PNG_SIGNATURE)
    for _ in range(_MAX_CHUNKS):
        if pos + 12 > len(data):
            return None
        length = int.from_bytes(data[pos : pos + 4], "big")
        kind = bytes(data[pos + 4 : pos + 8])
        pos += 12 + length
        if kind == b"IEND":
            return pos if pos <= len(data) else None
    return None
