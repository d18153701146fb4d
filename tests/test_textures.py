import io

import numpy as np
import pytest
from PIL import Image

from meshtool.errors import TextureError
from meshtool.textures import to_png

RGB = (np.arange(8 * 6 * 3) * 7 % 256).astype(np.uint8).reshape(6, 8, 3)


def encode(img: Image.Image, fmt: str, **kw) -> bytes:
    buf = io.BytesIO()
    img.save(buf, format=fmt, **kw)
    return buf.getvalue()


def decode(data: bytes) -> Image.Image:
    img = Image.open(io.BytesIO(data))
    assert img.format == "PNG"
    return img


@pytest.mark.parametrize("fmt", ["BMP", "TGA", "GIF"])
def test_lossless_formats_keep_every_pixel(fmt):
    src = Image.fromarray(RGB, "RGB")
    if fmt == "GIF":
        src = src.quantize(256)
        expected = np.asarray(src.convert("RGB"))
    else:
        expected = RGB
    png = to_png(encode(src, fmt), f"t.{fmt.lower()}")
    assert png.converted and png.mode == "RGB" and png.size == (8, 6)
    np.testing.assert_array_equal(np.asarray(decode(png.data)), expected)


def test_jpeg_becomes_rgb_png():
    png = to_png(encode(Image.fromarray(RGB, "RGB"), "JPEG", quality=95), "t.jpg")
    img = decode(png.data)
    assert (png.source_format, img.mode, img.size) == ("JPEG", "RGB", (8, 6))


def test_palette_png_with_transparency_becomes_rgba():
    pal = Image.fromarray(RGB, "RGB").quantize(16)
    png = to_png(encode(pal, "PNG", transparency=0), "p.png")
    assert png.source_mode == "P" and png.mode == "RGBA"
    out = np.asarray(decode(png.data))
    assert out[..., 3].min() == 0 and out[..., 3].max() == 255


def test_sixteen_bit_grey_keeps_the_high_byte():
    grey = (np.arange(48, dtype=np.uint16).reshape(6, 8) * 1365).astype(np.uint16)
    png = to_png(encode(Image.fromarray(grey), "PNG"), "g16.png")
    out = np.asarray(decode(png.data))
    assert png.converted and out.shape == (6, 8, 3) and out.dtype == np.uint8
    np.testing.assert_array_equal(out[..., 0], grey >> 8)


def test_eight_bit_rgb_png_passes_through_unchanged():
    data = encode(Image.fromarray(RGB, "RGB"), "PNG")
    png = to_png(data, "rgb.png")
    assert not png.converted and png.data == data


def test_conversion_is_deterministic():
    data = encode(Image.fromarray(RGB, "RGB"), "BMP")
    assert to_png(data, "a.bmp").data == to_png(data, "a.bmp").data


def test_not_an_image():
    with pytest.raises(TextureError, match="not a readable image"):
        to_png(b"definitely not an image", "x.png")
