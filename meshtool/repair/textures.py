"""Texture conversion: any image Pillow reads to an 8-bit PNG MuJoCo can load.

MuJoCo reads PNG (and KTX) only. BMP, TGA, JPEG and GIF are converted; PNGs that are already 8-bit RGB or
RGBA pass through byte for byte; palette, grey, 16-bit and other PNG modes are converted to 8-bit RGB(A)
(16-bit channels keep their high byte). This module works on bytes and never touches the file system.

Hostile images are bounded before they are decoded:

- **Decoded size**: at most :data:`MAX_SIDE` pixels per side and :data:`MAX_PIXELS` pixels in all (checked
  from the header, before any pixel is decoded; Pillow's own decompression-bomb guard becomes the same
  error). The file size is bounded by the reader (:class:`meshtool.files.safeopen.ReadLimits`).
- **Trailing bytes**: a PNG passed through is cut at the end of its ``IEND`` chunk; the bytes after it are
  dropped with a ``texture-trailing-data`` finding. A PNG larger than its raw pixels (plus 1 % and 64 KiB)
  is re-encoded instead of passed through, so bulky ancillary chunks never reach the output.
- **Truncated JPEG**: Huffman-coded JPEG needs at least one bit per 8x8 block; a file too short for the
  size its header declares (libjpeg would silently fill the rest with grey) is refused.
"""

from __future__ import annotations

import io
import warnings
import zlib
from dataclasses import dataclass, field

import numpy as np
from PIL import Image, UnidentifiedImageError

from meshtool.errors import TextureError
from meshtool.findings import Finding, warning
from meshtool.repair.pnginfo import MAX_PIXELS, MAX_SIDE, over_limit, png_end

__all__ = ["MAX_PIXELS", "MAX_SIDE", "PngTexture", "to_png"]

_PASS_MODES = ("RGB", "RGBA")
#: zlib settings of a converted texture's PNG, the one image encode a conversion makes (issue 28). Level 1
#: with run-length matching costs a third of level 6's CPU (1024 x 1024 JPEG: about 36 ms against 106 ms)
#: for about 3 % more bytes; zlib's output is a function of its input and settings, so the same source
#: still gives the same bytes. MuJoCo decodes the same pixels either way.
PNG_COMPRESS_LEVEL = 1
PNG_COMPRESS_TYPE = zlib.Z_RLE

_PNG_OVERHEAD = 1 << 16  # bytes a passed-through PNG may hold beyond its raw pixels (chunks, zlib framing)
_JPEG_HUFFMAN_SOF = frozenset({0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7})
_JPEG_LOSSLESS_SOF = frozenset({0xC3, 0xC7})


@dataclass(frozen=True, slots=True)
class PngTexture:
    """A texture ready to write.

    Attributes:
        data: PNG file bytes.
        source_format: Format Pillow detected (``BMP``, ``TGA``, ``JPEG``, ``PNG``...).
        source_mode: Pillow mode of the source (``P``, ``I;16``, ``RGB``...).
        mode: Mode of the PNG written (``RGB`` or ``RGBA``).
        size: (width, height) in pixels.
        converted: False when the source bytes were passed through unchanged (trailing bytes after the
            PNG's end excepted).
        findings: What was dropped (``texture-trailing-data``).
    """

    data: bytes
    source_format: str
    source_mode: str
    mode: str
    size: tuple[int, int]
    converted: bool
    findings: tuple[Finding, ...] = field(default=())


def to_png(data: bytes, name: str, max_side: int = MAX_SIDE, max_pixels: int = MAX_PIXELS) -> PngTexture:
    """Convert image bytes to an 8-bit RGB or RGBA PNG.

    Args:
        data: The image file's bytes.
        name: Name for error messages.
        max_side: Most pixels along either side.
        max_pixels: Most pixels in all (width x height).

    Returns:
        The PNG and what was done.

    Raises:
        TextureError: When the data is not an image Pillow can decode, is larger than the limits (also
            Pillow's decompression-bomb guard), or is a JPEG too short for its declared size.
    """
    hint = "re-save it as PNG"
    try:
        with warnings.catch_warnings():
            # The limits below are checked from the header before decoding; Pillow's warning threshold
            # (about 89 million pixels) is below them, its error threshold above.
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            image = Image.open(io.BytesIO(data))
            width, height = image.size
            too_big = over_limit(width, height, max_side, max_pixels)
            if too_big:
                raise TextureError(too_big, path=name, hint="downscale the image")
            if image.format == "JPEG":
                _check_jpeg_length(data, width, height, name)
            image.load()
    except Image.DecompressionBombError as exc:
        raise TextureError(
            f"over the texture limit ({max_side} per side, {max_pixels} in all; Pillow's decompression-bomb "
            f"guard: {str(exc).rstrip('.')})",
            path=name,
            hint="downscale the image",
        ) from None
    except TextureError:
        raise
    except (UnidentifiedImageError, OSError, ValueError, SyntaxError, EOFError, MemoryError) as exc:
        # Pillow's "cannot identify" message names a memory address: the same input must give the same message
        why = "unknown image format" if isinstance(exc, UnidentifiedImageError) else str(exc)
        raise TextureError(f"not a readable image ({why})", path=name, hint=hint) from None
    fmt = image.format or "unknown"
    source_mode = image.mode
    if fmt == "PNG" and source_mode in _PASS_MODES and _is_8bit_png(data):
        end = png_end(data)
        width, height = image.size
        channels = len(source_mode)
        if end is not None and end > width * height * channels * 1.01 + height + _PNG_OVERHEAD:
            end = None  # bulky ancillary chunks (text, ICC, APNG frames): re-encoded below, pixels only
        if end == len(data):
            return PngTexture(data, fmt, source_mode, source_mode, image.size, False)
        if end is not None:
            dropped = warning(
                "texture-trailing-data",
                f"{len(data) - end} bytes after the end of the PNG image dropped",
                name,
            )
            return PngTexture(data[:end], fmt, source_mode, source_mode, image.size, False, (dropped,))
    rgb = _to_8bit(image)
    out = io.BytesIO()
    rgb.save(out, format="PNG", compress_level=PNG_COMPRESS_LEVEL, compress_type=PNG_COMPRESS_TYPE)
    return PngTexture(out.getvalue(), fmt, source_mode, rgb.mode, rgb.size, True)


def _check_jpeg_length(data: bytes, width: int, height: int, name: str) -> None:
    """Refuse a Huffman-coded JPEG with fewer bytes than its declared size needs.

    Every 8x8 block of the largest component costs at least one bit in Huffman coding (the DC difference
    code is at least one bit long), and every sample one bit in lossless mode. Arithmetic-coded JPEG has no
    such bound and is not checked.
    """
    sof = _jpeg_sof(data)
    if sof is None or sof not in _JPEG_HUFFMAN_SOF:
        return
    units = width * height if sof in _JPEG_LOSSLESS_SOF else -(-width // 8) * -(-height // 8)
    needed = -(-units // 8)
    if len(data) < needed:
        raise TextureError(
            f"truncated JPEG: {len(data)} bytes cannot hold the {width}x{height} image its header declares "
            f"(at least {needed} bytes of image data needed)",
            path=name,
            hint="the file is cut short; export it again",
        )


def _jpeg_sof(data: bytes) -> int | None:
    """The start-of-frame marker (``0xC0``..``0xCF``, not DHT/JPG/DAC) of a JPEG, walking its segments."""
    pos = 2
    while pos + 4 <= len(data):
        if data[pos] != 0xFF:
            return None
        marker = data[pos + 1]
        if marker == 0xFF:  # fill byte
            pos += 1
            continue
        if marker in (0x01, 0xD8) or 0xD0 <= marker <= 0xD7:
            pos += 2
            continue
        if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
            return marker
        if marker in (0xD9, 0xDA):
            return None
        pos += 2 + int.from_bytes(data[pos + 2 : pos + 4], "big")
    return None


def _is_8bit_png(data: bytes) -> bool:
    """Whether a PNG's IHDR says 8 bits per channel (byte 24 of the file)."""
    return len(data) > 24 and data[24] == 8


def _to_8bit(image: Image.Image) -> Image.Image:
    mode = image.mode
    if mode in ("I;16", "I;16B", "I;16L", "I;16N", "I"):
        array = np.asarray(image, dtype=np.uint32)
        peak = 65535 if mode.startswith("I;16") or array.max(initial=0) > 255 else 255
        shift = 8 if peak == 65535 else 0
        return Image.fromarray((array >> shift).astype(np.uint8), "L").convert("RGB")
    if mode == "F":
        array = np.clip(np.asarray(image, dtype=np.float64), 0.0, 255.0)
        return Image.fromarray(array.astype(np.uint8), "L").convert("RGB")
    has_alpha = mode in ("RGBA", "LA", "PA", "La", "RGBa") or (mode == "P" and "transparency" in image.info)
    if mode in ("RGBA", "RGB") and image.info.get("transparency") is None:
        return image  # saving reads it; a copy cost a pass over the pixels
    return image.convert("RGBA" if has_alpha or "transparency" in image.info else "RGB")
