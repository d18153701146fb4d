"""The committed format-1.0 and 1.1 files must stay readable, with exactly this content, forever."""

import hashlib
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest
import xxhash
from PIL import Image

from meshtool.packfile import load
from meshtool.packfile.encode import dequantize_box, exact_grid

GOLDEN = Path(__file__).resolve().parent.parent / "fixtures" / "golden"


@pytest.mark.parametrize("name", ["head.mbin", "head_plain_meta.mbin"])
def test_head(name):
    """The same head, with deflated JSON sections and (the first 1.0 files) plain ones."""
    with load(GOLDEN / name) as p:
        assert p.version == (1, 0) and not p.quantized
        assert p.positions.shape == (61, 3) and p.positions.dtype == np.float32
        assert p.indices.shape == (80, 3) and p.indices.dtype == np.uint16
        assert p.normals is None and p.colors is None and p.uvs.shape == (61, 2)
        np.testing.assert_array_equal(
            p.positions[:3],
            np.array([[0, 0, 0.24], [0.028284, -0.035355, 0.223923], [0.04, 0, 0.223923]], dtype=np.float32),
        )
        np.testing.assert_array_equal(p.indices[:2], [[0, 1, 2], [3, 4, 1]])
        extent = p.positions.max(axis=0) - p.positions.min(axis=0)
        np.testing.assert_array_equal(extent, np.array([0.16, 0.2, 0.24], dtype=np.float32))
        assert p.submeshes.tolist() == [[0, 80, 0, 1]]
        assert [m["name"] for m in p.materials] == ["Head_Material"]
        assert p.materials[0]["maps"]["map_Kd"]["texture"] == 0
        assert p.meta["textures"] == ["head_1.png"]
        image = Image.open(__import__("io").BytesIO(bytes(p.textures[0])))
        assert (image.format, image.size, image.mode) == ("PNG", (16, 16), "RGB")
        assert p.meta["transform"]["units"] == "cm" and p.meta["transform"]["up"] == "y"
        assert [s["path"] for s in p.meta["sources"]] == ["Head 1.obj", "Head 1.mtl", "Head 1.bmp"]
        assert all(s.crc_ok for s in p.sections)


def test_crate_quantized():
    with load(GOLDEN / "crate_quantized.mbin") as p:
        assert p.quantized and p.raw["POS "].dtype == np.uint16 and p.raw["UV  "].dtype == np.uint16
        idx = next(s for s in p.sections if s.kind == "IDX ")
        assert idx.encoding == 3 and idx.length < 12 * 3 * 2  # deflated
        assert p.indices.shape == (12, 3) and int(p.indices.max()) == 19
        assert p.positions.shape == (20, 3)
        assert {tuple(r) for r in p.positions.tolist()} == {
            (x, y, z) for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)
        }
        assert p.submeshes.tolist() == [[0, 4, 0, 1], [4, 2, 1, 1], [6, 2, 1, 2], [8, 4, 2, 2]]
        assert [m["name"] for m in p.materials] == ["painted", "wood", "checker"]
        assert p.meta["textures"] == ["checker.png", "wood_grain.png"]
        assert p.meta["parts"] == ["default", "Body", "Lid"]
        assert p.meta["quantization"]["positions"]["max_abs_error_m"] == [0.0, 0.0, 0.0]


def test_features():
    with load(GOLDEN / "features.mbin") as p:
        assert p.colors is not None and p.colors.shape == (12, 4)
        assert p.colors[:3].tolist() == [[255, 0, 0, 255], [0, 255, 0, 255], [0, 0, 255, 255]]
        assert p.normals.shape == (12, 3)
        assert p.submeshes.tolist() == [[0, 2, 0, 2], [2, 2, 1, 2]]


PINNED = {
    "crate_quantized-1.1.mbin": "02045fa1f6ac918fe74303584569f204ed58b5131b3a53aa33f6d3a493a08df1",
    "features-1.1.mbin": "0e6355853de02ed9944a4c5daa0a322399c47f92b26101e00a3ac7e57fb70d37",
    "head-1.1.mbin": "3104ef0455fa25150c1cb0e14d70733f8ef13bf82ff762e75764e4afccdd5346",
    "crate_quantized.mbin": "d2e0a9e9848d7108729fc0ebfc2161ec69fcb2d3cb2e51215ca948f1bd29023f",
    "features.mbin": "0c5a5990c9dc0a5d3d2360351c2a47a12ccedfa8e3416cb964f5512adc31fe42",
    "head.mbin": "5f3b8ab5f7f7f33121b354ee15290d77c37b51e2f3a5768d6ae9e55c50b286ef",
    "head_plain_meta.mbin": "3fed7b85cac363419c0dee35e02980c026809bf9db8d6b1246762e93abda7ff3",
}


@pytest.mark.parametrize("name", sorted(PINNED))
def test_goldens_are_the_committed_bytes(name):
    """The goldens are data written once: their bytes only change with a deliberate, major format change."""
    data = (GOLDEN / name).read_bytes()
    assert hashlib.sha256(data).hexdigest() == PINNED[name]
    minor = b"\x01\x00" if name.endswith("-1.1.mbin") else b"\x00\x00"
    assert data[:8] == b"\x89MBN\r\n\x1a\n" and data[8:12] == b"\x01\x00" + minor


# ------------------------------------------------------------------------------------------------ format 1.1


def _table(data):
    count = struct.unpack_from("<I", data, 16)[0]
    return [ENTRY.unpack_from(data, 64 + 64 * k) for k in range(count)]


ENTRY = struct.Struct("<4sBBH2QQQII16s")


@pytest.mark.parametrize("name", ["head-1.1.mbin", "crate_quantized-1.1.mbin", "features-1.1.mbin"])
def test_1_1_checksums_are_xxh3_low_32_bits(name):
    """docs/mbin-spec.md 1.1: every checksum is the low 32 bits of XXH3-64 (seed 0); 1.0 used CRC-32."""
    data = (GOLDEN / name).read_bytes()
    table = _table(data)
    for kind, *_, offset, length, crc, _enc, _res in table:
        assert crc == xxhash.xxh3_64_intdigest(data[offset : offset + length]) & 0xFFFFFFFF, kind
        if length:
            assert crc != zlib.crc32(data[offset : offset + length])
    head_crc = struct.unpack_from("<I", data, 32)[0]
    assert head_crc == xxhash.xxh3_64_intdigest(data[:32] + data[64 : 64 + 64 * len(table)]) & 0xFFFFFFFF


def test_1_0_checksums_are_crc32():
    data = (GOLDEN / "head.mbin").read_bytes()
    for _kind, *_, offset, length, crc, _enc, _res in _table(data):
        assert crc == zlib.crc32(data[offset : offset + length])


def test_head_1_1_holds_the_seed_head():
    """The seed head (fixtures/head, --units cm): the source's own numbers, Y-up rotated to Z-up, cm to m."""
    with load(GOLDEN / "head-1.1.mbin") as p, load(GOLDEN / "head.mbin") as old:
        assert p.version == (1, 1) and not p.quantized
        assert p.positions.shape == (61, 3) and p.indices.shape == (80, 3) and p.indices.dtype == np.uint16
        np.testing.assert_array_equal(p.positions, old.positions)  # same geometry as the 1.0 file
        np.testing.assert_array_equal(p.indices, old.indices)
        extent = p.positions.max(axis=0) - p.positions.min(axis=0)
        np.testing.assert_array_equal(extent, np.array([0.16, 0.2, 0.24], dtype=np.float32))
        assert len(p.hulls) == 1 and p.meta["hull_parts"] == [0]
        assert all(s.crc_ok for s in p.sections)


def test_crate_1_1_quantised_on_an_exact_grid():
    """Quantised 1.1: plain indices, and every decoded corner within the recorded error of the cube's +-0.5."""
    with load(GOLDEN / "crate_quantized-1.1.mbin") as p:
        assert p.quantized and p.version == (1, 1)
        idx = next(s for s in p.sections if s.kind == "IDX ")
        assert idx.encoding == 0 and p.indices.shape == (12, 3)
        q = p.meta["quantization"]["positions"]
        step = (np.array(q["hi"]) - np.array(q["lo"])) / 65535
        assert all(e <= s / 2 for e, s in zip(q["max_abs_error_m"], step, strict=True))
        corners = np.sign(p.positions) * 0.5
        assert (np.abs(p.positions - corners) <= np.array(q["max_abs_error_m"]) + 1e-12).all()
        assert all(exact_grid(a, b) for a, b in zip(q["lo"], q["hi"], strict=True))
        # the fast float32 decode equals the format's float64 formula for every code
        codes = np.repeat(np.arange(65536, dtype=np.uint16)[:, None], 3, axis=1)
        lo, hi = np.array(q["lo"]), np.array(q["hi"])
        formula = (lo + codes.astype(np.float64) * ((hi - lo) / 65535)).astype(np.float32)
        np.testing.assert_array_equal(dequantize_box(codes, q["lo"], q["hi"]), formula)


def test_features_1_1():
    with load(GOLDEN / "features-1.1.mbin") as p:
        assert p.colors is not None and p.colors[:3].tolist() == [[255, 0, 0, 255], [0, 255, 0, 255], [0, 0, 255, 255]]
        assert p.normals.shape == (12, 3) and p.submeshes.tolist() == [[0, 2, 0, 2], [2, 2, 1, 2]]


def test_make_goldens_reassembles_every_golden_exactly():
    """scripts/make_goldens.py rebuilds every committed file from its stored sections byte for byte."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("make_goldens", GOLDEN.parent.parent / "scripts" / "make_goldens.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    for path in sorted(GOLDEN.glob("*.mbin")):
        assert module.reassemble(path) == path.read_bytes(), path.name
