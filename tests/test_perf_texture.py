"""A textured asset's ``prepare`` (issue 28): one image encode at a cheap zlib setting, counted, not timed.

The fuze's 1024 x 1024 JPEG made ``prepare`` cost 0.17 s CPU, 0.11 s of it Pillow's PNG encoder at zlib
level 6. A JPEG still becomes a PNG (MuJoCo reads PNG only), once, at level 1 with run-length matching:
the calls are counted with cProfile and the level is read from the PNG's own zlib header (RFC 1950:
FLEVEL 0 is "fastest"), and the pixels MuJoCo decodes from it are the JPEG's.
"""

from __future__ import annotations

import cProfile
import io
import pstats
import zlib
from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np
from PIL import Image

from meshtool.repair.normalise import NormalisedAsset, NormaliseOptions, prepare

SIDE = 64


def _textured_obj(folder: Path, texture: str, image: bytes) -> Path:
    """A unit square with UVs and one material whose ``map_Kd`` is ``texture``."""
    (folder / texture).write_bytes(image)
    (folder / "square.mtl").write_text(f"newmtl skin\nKd 1 1 1\nmap_Kd {texture}\n")
    obj = folder / "square.obj"
    obj.write_text(
        "mtllib square.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
        "usemtl skin\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n"
    )
    return obj


def _pixels() -> np.ndarray:
    yy, xx = np.mgrid[0:SIDE, 0:SIDE]
    return np.stack([xx * 4, yy * 4, (xx + yy) * 2], axis=-1).astype(np.uint8)


def _encoded(fmt: str) -> bytes:
    out = io.BytesIO()
    Image.fromarray(_pixels(), "RGB").save(out, format=fmt)
    return out.getvalue()


def _calls(run: Callable[[], NormalisedAsset]) -> tuple[NormalisedAsset, dict[str, int]]:
    """``run()``'s result and its calls per ``file:function`` (C methods as cProfile names them)."""
    profile = cProfile.Profile()
    result = profile.runcall(run)
    stats = pstats.Stats(profile).stats  # type: ignore[attr-defined]
    return result, {f"{Path(file).name}:{func}": calls[1] for (file, _line, func), calls in stats.items()}


def _count(calls: dict[str, int], name: str) -> int:
    return sum(n for key, n in calls.items() if key.endswith(name))


def _chunks(png: bytes, kind: bytes) -> list[bytes]:
    """The bodies of a PNG's chunks of one kind, in order."""
    found, pos = [], 8
    while pos + 8 <= len(png):
        length = int.from_bytes(png[pos : pos + 4], "big")
        if png[pos + 4 : pos + 8] == kind:
            found.append(png[pos + 8 : pos + 8 + length])
        pos += 12 + length
    return found


def _idat_flevel(png: bytes) -> int:
    """FLEVEL (bits 6-7 of the zlib header's FLG byte, RFC 1950) of a PNG's first IDAT chunk."""
    cmf, flg = _chunks(png, b"IDAT")[0][:2]
    assert cmf & 0x0F == 8 and (cmf * 256 + flg) % 31 == 0  # deflate, a valid zlib header
    return flg >> 6


def test_a_jpeg_texture_is_encoded_once_at_the_fastest_zlib_level(tmp_path: Path) -> None:
    jpeg = _encoded("JPEG")
    obj = _textured_obj(tmp_path, "skin.jpg", jpeg)
    asset, calls = _calls(lambda: prepare(obj, NormaliseOptions()))
    assert _count(calls, "PngImagePlugin.py:_save") == 1
    assert _count(calls, "<method 'encode' of 'ImagingEncoder' objects>") >= 1
    assert _count(calls, "<method 'copy' of 'ImagingCore' objects>") == 0  # no pixel copy before the encode
    png = asset.textures["skin.png"]
    assert _idat_flevel(png) == 0  # level 6, the old setting, writes FLEVEL 2
    again = prepare(obj, NormaliseOptions())
    assert again.textures == asset.textures  # the same input, the same bytes
    decoded = np.asarray(Image.open(io.BytesIO(jpeg)).convert("RGB"))
    np.testing.assert_array_equal(np.asarray(Image.open(io.BytesIO(png))), decoded)


def test_mujoco_reads_the_jpegs_pixels_from_the_png(tmp_path: Path) -> None:
    jpeg = _encoded("JPEG")
    asset = prepare(_textured_obj(tmp_path, "skin.jpg", jpeg), NormaliseOptions())
    (tmp_path / "out.png").write_bytes(asset.textures["skin.png"])
    model = mujoco.MjModel.from_xml_string(
        f'<mujoco><asset><texture name="t" type="2d" file="{tmp_path / "out.png"}"/></asset></mujoco>'
    )
    assert (model.tex_width[0], model.tex_height[0], model.tex_nchannel[0]) == (SIDE, SIDE, 3)
    texels = model.tex_data[: SIDE * SIDE * 3].reshape(SIDE, SIDE, 3)
    decoded = np.asarray(Image.open(io.BytesIO(jpeg)).convert("RGB"))
    assert np.array_equal(texels, decoded) or np.array_equal(texels, decoded[::-1])


def test_an_eight_bit_rgb_png_texture_is_not_encoded_at_all(tmp_path: Path) -> None:
    png = _encoded("PNG")
    obj = _textured_obj(tmp_path, "skin.png", png)
    asset, calls = _calls(lambda: prepare(obj, NormaliseOptions()))
    assert _count(calls, "PngImagePlugin.py:_save") == 0
    assert _chunks(asset.textures["skin.png"], b"IDAT") == _chunks(png, b"IDAT")  # (a colour-space chunk is added)


def test_old_setting_would_fail_the_level_check() -> None:
    """The FLEVEL reader tells the settings apart (so the first test checks what it claims)."""
    image = Image.fromarray(_pixels(), "RGB")
    levels = {}
    for level in (1, 6, 9):
        out = io.BytesIO()
        image.save(out, format="PNG", compress_level=level, compress_type=zlib.Z_RLE if level == 1 else -1)
        levels[level] = _idat_flevel(out.getvalue())
    assert levels == {1: 0, 6: 2, 9: 3}
