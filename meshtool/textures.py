"""Texture conversion: any image Pillow reads to an 8-bit PNG MuJoCo can load.

MuJoCo reads PNG (and KTX) only. BMP, TGA, JPEG and GIF are converted; PNGs that are already 8-bit RGB or
RGBA pass through byte for byte; palette, grey, 16-bit and other PNG modes are converted to 8-bit RGB(A)
(16-bit channels keep their high byte). This module works on bytes and never touches the file system.
"""

from __future__ import annotations

import io
import warnings
from dataclasses import dataclass

import numpy as np
from PIL import Image, UnidentifiedImageError

from meshtool.errors import TextureError

_PASS_MODES = ("RGB", "RGBA")


@dataclass(frozen=True, slots=True)
class PngTexture:
    """A texture ready to write.

    Attributes:
        data: PNG file bytes.
        source_format: Format Pillow detected (``BMP``, ``TGA``, ``JPEG``, ``PNG``...).
        source_mode: Pillow mode of the source (``P``, ``I;16``, ``RGB``...).
        mode: Mode of the PNG written (``RGB`` or ``RGBA``).
        size: (width, height) in pixels.
        converted: False when the source bytes were passed through unchanged.
    """

    data: bytes
    source_format: str
    source_mode: str
    mode: str
    size: tuple[int, int]
    converted: bool


def to_png(data: bytes, name: str) -> PngTexture:
    """Convert image bytes to an 8-bit RGB or RGBA PNG.

    Args:
        data: The image file's bytes.
        name: Name for error messages.

    Returns:
        The PNG and what was done.

    Raises:
        TextureError: When the data is not an image Pillow can decode (or is a decompression bomb).
    """
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", Image.DecompressionBombWarning)
            image = Image.open(io.BytesIO(data))
            image.load()
    except (
        UnidentifiedImageError,
        OSError,
        ValueError,
        SyntaxError,
        Image.DecompressionBombError,
        Image.DecompressionBombWarning,
    ) as exc:
        raise TextureError(f"not a readable image ({exc})", path=name, hint="re-save it as PNG") from None
    fmt = image.format or "unknown"
    source_mode = image.mode
    if fmt == "PNG" and source_mode in _PASS_MODES and _is_8bit_png(data):
        return PngTexture(data, fmt, source_mode, source_mode, image.size, False)
    rgb = _to_8bit(image)
    out = io.BytesIO()
    rgb.save(out, format="PNG", compress_level=6)
    return PngTexture(out.getvalue(), fmt, source_mode, rgb.mode, rgb.size, True)


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
        return image.copy()
    return image.convert("RGBA" if has_alpha or "transparency" in image.info else "RGB")
