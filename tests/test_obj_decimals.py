"""The OBJ reader's exact decimal fast path (meshtool/read/obj/decimals.py) and uniform faces (faces.py).

Ground truth is Python's own ``float`` (correctly rounded) and the reader's general face path; every value
is compared bit for bit (``tobytes``), so ``-0.0`` and the last bit of rounding count.
"""

from __future__ import annotations

import random

import numpy as np
import pytest

from meshtool.read.obj import faces
from meshtool.read.obj.decimals import decimal_numbers
from meshtool.read.obj.lines import VN, VT, V, classify, float_blocks, vector_block

EXACT = [
    "1", "-0", "-0.0", "+0.000", "0.", "-.5", ".25", "+1.", "007.100", "9007199254740992", "-9007199254740992",
    "0.1234567890123456", "1e5", "1E5", "1e+5", "1e-5", "-1.5e-3", ".5e2", "5.e2", "-0e3", "1.23e-20",
    "9e22", "1e-22", "123.456e10", "1.e+05", "-1.3728e-05", "3E-2", "1e05", "1e-0005", "0.1", "0.3",
    "2.675", "1.000000000000002", "0.000001",
    # past the fast path (17 digits, powers beyond 22): read one by one with float
    "9007199254740993", "99999999999999999999", "-99999999999999999999", "0.00000000000000000000001",
    "1.0000000000000002", "9e23", "2.710505e-20", "1e-400", "1e999999999999999999999",
]  # fmt: skip
REFUSED = [
    "-", "+", ".", "+.", "-.", "1.2.3", "5-3", "--1", "-+1", "1-", "e5", "1e", "1e+", "1e5e3", "1e5.3", "1ee5", "+e1",
    ".e1", "-.e2", "1e+-5", "nan", "inf", "1_0", "0x10", "1#",
]  # fmt: skip


def _read(tokens: list[str]) -> np.ndarray | None:
    parsed = decimal_numbers(("v " + " ".join(tokens) + "\n").encode(), {118: 1})
    return None if parsed is None else parsed[0]


@pytest.mark.parametrize("token", EXACT)
def test_plain_decimals_are_read_as_float_reads_them(token: str) -> None:
    values = _read([token])
    assert values is not None
    assert values.tobytes() == np.array([float(token)]).tobytes()


@pytest.mark.parametrize("token", REFUSED)
def test_anything_else_is_left_to_the_general_parsers(token: str) -> None:
    assert _read(["1.5", token, "2"]) is None


def test_random_decimals_bit_for_bit() -> None:
    rng = random.Random(41)
    read = 0
    for _ in range(2000):
        tokens = [
            rng.choice(
                [
                    repr(rng.uniform(-1e3, 1e3)),
                    f"{rng.uniform(-1, 1):.{rng.randint(0, 16)}f}",
                    f"{rng.uniform(-1e-3, 1e-3):.{rng.randint(0, 8)}e}",
                    str(rng.randint(-(10**15), 10**15)),
                ]
            )
            for _ in range(rng.randint(1, 9))
        ]
        values = _read(tokens)
        assert values is not None, tokens
        read += 1
        assert values.tobytes() == np.array([float(t) for t in tokens]).tobytes(), tokens
    assert read == 2000


def test_counts_per_line_and_keyword_letters_elsewhere() -> None:
    parsed = decimal_numbers(b"v 1 2 3\nv 4 5\nv 6 7 8 9\n", {118: 3})
    assert parsed is not None
    assert parsed[0].tolist() == [1, 2, 3, 4, 5, 6, 7, 8, 9] and parsed[1].tolist() == [3, 2, 4]
    assert decimal_numbers(b"v 1 v 2\n", {118: 1}) is None  # a 'v' that is not a keyword
    assert decimal_numbers(b"v\nv 1\n", {118: 2}) is None  # a bare keyword: the caller reports it


def test_float_blocks_match_each_kind_read_alone() -> None:
    text = b"vn 0 0 1\nv 1.5 -2 3e-3\nvt 0.25 .5\nv -0 0 1\nvn 1 0 0\nvt 1 0 0\nf 1/1/1 2/2/2 1/2/1\n"
    lines = classify(text)
    read = float_blocks(lines)
    assert read is not None
    for kind, keyword in ((V, "v"), (VT, "vt"), (VN, "vn")):
        alone = vector_block(lines, kind, keyword, "x.obj")
        for got, expected in zip(read[kind], alone, strict=True):
            assert got.dtype == expected.dtype and got.tobytes() == expected.tobytes()
    assert float_blocks(classify(b"v 1 2 nan\nvn 0 0 1\n")) is None


@pytest.mark.parametrize(
    "block",
    [
        b"f 1/2/3 4/5/6 7/8/9\nf -1/-2/-3 1/1/1 2/2/2 3/3/3\n",
        b"f 1//3 4//6 7//9\n",
        b"f 1/2 4/5 7/8 2/2\n",
        b"f 1/2/3 4//6 7/8/9\n",  # mixed: the general path
        b"f 1/2/3 4/5/6 7/8/\n",  # an empty last field
        b"f 1/2/3  4/5/6 7/8/9 \n",  # doubled and trailing spaces
        b"f +1/2/3 4/5/6 7/8/9\n",
    ],
)
def test_uniform_faces_agree_with_the_general_path(block: bytes) -> None:
    n_lines = block.count(b"\n")
    uniform = faces._uniform_faces(block, n_lines)
    general = faces._fast_faces(block.replace(b"f ", b"f  ", 1), n_lines)  # a doubled space: not uniform-read
    if uniform is None:
        return
    assert general is not None
    for got, expected in zip(uniform, general, strict=True):
        assert got.dtype == expected.dtype and np.array_equal(got, expected)


def test_uniform_faces_leave_zero_and_odd_corners_to_the_line_path() -> None:
    assert faces._uniform_faces(b"f 1/0/1 2/2/2 3/3/3\n", 1) is None
    assert faces._uniform_faces(b"f 1/2/3/4 2/2/2 3/3/3\n", 1) is None
    assert faces._uniform_faces(b"f /1/1 2/2/2 3/3/3\n", 1) is None
    assert faces._uniform_faces(b"f 1/1/1 2/2/2 3/3/3 # c\n", 1) is None
