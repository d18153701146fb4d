"""The committed format-1.0 files must stay readable, with exactly this content, forever."""

import hashlib
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from meshtool.packfile import load

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
    assert data[:8] == b"\x89MBN\r\n\x1a\n" and data[8:12] == b"\x01\x00\x00\x00"
