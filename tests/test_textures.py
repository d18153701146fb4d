import io

import numpy as np
import pytest
from PIL import Image

from meshtool.errors import TextureError
from meshtool.repair.textures import to_png

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


# -- issue 21: hostile images ------------------------------------------------------------------------------


def png_chunk(kind: bytes, body: bytes) -> bytes:
    import zlib

    return len(body).to_bytes(4, "big") + kind + body + zlib.crc32(kind + body).to_bytes(4, "big")


def png_header_only(width: int, height: int) -> bytes:
    """A PNG whose IHDR declares ``width`` x ``height`` 8-bit RGB, with one tiny (wrong) IDAT."""
    import zlib

    ihdr = width.to_bytes(4, "big") + height.to_bytes(4, "big") + bytes([8, 2, 0, 0, 0])
    return (
        b"\x89PNG\r\n\x1a\n"
        + png_chunk(b"IHDR", ihdr)
        + png_chunk(b"IDAT", zlib.compress(b"\0" * 64))
        + png_chunk(b"IEND", b"")
    )


def jpeg_claiming(width: int, height: int) -> bytes:
    """A small real JPEG whose frame header is patched to declare ``width`` x ``height`` (a cut-short file)."""
    data = bytearray(encode(Image.fromarray(RGB, "RGB"), "JPEG", quality=90))
    sof = data.index(b"\xff\xc0")
    data[sof + 5 : sof + 9] = height.to_bytes(2, "big") + width.to_bytes(2, "big")
    return bytes(data)


def test_trailing_bytes_after_a_png_are_dropped_with_a_finding():
    png = encode(Image.fromarray(RGB, "RGB"), "PNG")
    out = to_png(png + b"\0" * 5_000_000, "t.png")
    assert out.data == png and not out.converted
    (finding,) = out.findings
    assert finding.code == "texture-trailing-data" and "5000000 bytes" in finding.message
    assert finding.path == "t.png"
    np.testing.assert_array_equal(np.asarray(decode(out.data)), RGB)
    assert to_png(png, "t.png").findings == ()


def test_too_many_pixels_is_refused_before_decoding():
    with pytest.raises(TextureError, match=r"20000x100 pixels is over the texture limit \(16384 per side"):
        to_png(png_header_only(20000, 100), "wide.png")
    with pytest.raises(TextureError, match=r"16000x9000 pixels is over the texture limit"):
        to_png(png_header_only(16000, 9000), "bomb.png")  # each side fits, the area does not
    with pytest.raises(TextureError, match=r"over the texture limit .*decompression-bomb guard"):
        to_png(png_header_only(20000, 20000), "bomb.png")  # Pillow refuses first, in the same words
    with pytest.raises(TextureError, match="over the texture limit"):
        to_png(png_header_only(64, 64), "small.png", max_side=32)


def test_pillows_decompression_bomb_guard_becomes_a_texture_error():
    big = png_header_only(20000, 10000)  # 200 Mpx: over Pillow's own error threshold (about 179 Mpx)
    with pytest.raises(TextureError, match="decompression-bomb guard"):
        to_png(big, "bomb.png", max_side=10**6, max_pixels=10**12)


def test_truncated_jpeg_claiming_9000_by_9000_is_refused():
    data = jpeg_claiming(9000, 9000)
    assert len(data) < 1000
    assert Image.open(io.BytesIO(data)).size == (9000, 9000)  # what a decoder would have produced
    with pytest.raises(TextureError, match=r"truncated JPEG: \d+ bytes cannot hold the 9000x9000 image"):
        to_png(data, "cut.jpg")


@pytest.mark.parametrize("options", [{"quality": 1, "optimize": True}, {"progressive": True, "optimize": True}])
def test_small_but_complete_jpegs_still_convert(options):
    """The truncation bound (one bit per 8x8 block) holds for the most compressible real JPEGs."""
    flat = Image.new("L", (2048, 2048), 0)
    data = encode(flat, "JPEG", **options)
    png = to_png(data, "flat.jpg")
    assert png.size == (2048, 2048) and png.converted


def test_bulky_ancillary_chunks_are_not_passed_through():
    png = encode(Image.fromarray(RGB, "RGB"), "PNG")
    iend = png.rindex(b"IEND") - 4
    bulky = png[:iend] + png_chunk(b"tEXt", b"Comment\0" + b"z" * 1_000_000) + png[iend:]
    out = to_png(bulky, "bulky.png")
    assert out.converted and len(out.data) < 10_000
    np.testing.assert_array_equal(np.asarray(decode(out.data)), RGB)
