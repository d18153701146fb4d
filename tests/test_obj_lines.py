"""The OBJ reader's block helpers (meshtool/read/obj/lines.py), each against results written out by hand.

The reader has fast paths (one numpy call per block) and a line-by-line fallback that give the same arrays, so
whole-file tests cannot tell whether the fast path ran; these tests pin each helper's own result.
"""

from __future__ import annotations

import numpy as np
import pytest

from meshtool.read.obj.lines import VN, VT, F, V, _blank, classify, float_table, gather, numbers, values_per_line
from meshtool.read.obj.lines import vector_block as block_of


def test_blank_replaces_each_keyword_and_the_slashes() -> None:
    assert _blank(b"v 1 2 3\nv 4 5 6\n", b"v", False) == b"  1 2 3\n  4 5 6\n"
    assert _blank(b"vt 0.5 1\nvt 0 0\n", b"vt", False) == b"   0.5 1\n   0 0\n"
    assert _blank(b"f 1/2 3//4 5/6/7\n", b"f", True) == b"  1 2 3  4 5 6 7\n"
    assert _blank(b"v 1 2 3\n", b"v", False, 1) == b"  1 2 3\n"


def test_blank_keeps_keyword_letters_inside_values() -> None:
    """'t' of ``infinity`` is not the keyword's: only each line's leading keyword is blanked."""
    assert _blank(b"vt 1 infinity\nvt 2 3\n", b"vt", False) == b"   1 infinity\n   2 3\n"
    assert _blank(b"vn 1 nan 0\n", b"vn", False) == b"   1 nan 0\n"
    assert _blank(b"v 1 v 2\n", b"v", False) == b"  1 v 2\n"  # garbage stays garbage (the parser refuses it)
    faces = b"f 1/2 3/4 5/6\nf 4/5 6/7 8/9 inf\n"  # the 'f' of inf: the keyword is replaced line by line
    assert _blank(faces, b"f", True) == b"  1 2 3 4 5 6\n  4 5 6 7 8 9 inf\n"


def test_float_table_reads_a_regular_block() -> None:
    table = float_table(b"v 1 2 3\nv 4.5 -6e-1 7\n", b"v", 2)
    assert table is not None and table.dtype == np.float64
    assert table.tolist() == [[1.0, 2.0, 3.0], [4.5, -0.6, 7.0]]
    one = float_table(b"vt 0.25 0.75\n", b"vt", 1)
    assert one is not None and one.shape == (1, 2)
    column = float_table(b"vt 0.5\nvt 0.25\n", b"vt", 2)
    assert column is not None and column.tolist() == [[0.5], [0.25]]


@pytest.mark.parametrize(
    "block",
    [
        b"v 1 2 3\nv 4 5\n",  # counts differ
        b"v\nv\n",  # bare keywords
        b"v 1 2 3 # comment\n",
        b"v nan(1) 2 3\n",
        b"v 1 2 \xc2\xb3\n",  # a non-ASCII digit
        b"v 1 2 3x\n",
        b"v 1 2 3\nv\n",  # one bare keyword among values: loadtxt would skip the line
        b"v 1/2 3 4\n",  # a slash is not part of a vertex
        b"v 1 2 3 X\n",
    ],
    ids=["ragged", "bare", "comment", "nan-payload", "non-ascii", "garbage", "one-bare", "slash", "letter"],
)
def test_float_table_leaves_irregular_blocks_to_the_caller(block: bytes) -> None:
    assert float_table(block, b"v", block.count(b"\n")) is None


def test_numbers_reads_every_token_or_nothing() -> None:
    ints = numbers(b"f 1 2 3\nf 4 5 6 7\n", b"f", np.int64)
    assert ints is not None and ints.dtype == np.int64 and ints.tolist() == [1, 2, 3, 4, 5, 6, 7]
    slashed = numbers(b"f 1/2 3/4 5/6\n", b"f", np.int64, blank_slashes=True)
    assert slashed is not None and slashed.tolist() == [1, 2, 3, 4, 5, 6]
    floats = numbers(b"v 1 2.5 -3e2\n", b"v", np.float64)
    assert floats is not None and floats.tolist() == [1.0, 2.5, -300.0]
    for bad in (b"f 1 2 3-4\n", b"f 1 # 2\n", b"v 1 2 x\n", b"v nan(3) 1 2\n"):
        assert numbers(bad, bad[:1], np.float64) is None, bad


@pytest.mark.parametrize(
    ("block", "total", "expected"),
    [
        (b"v 1 2 3\nv 4 5\n", 5, [3, 2]),
        (b"v 1  2 3\nv 4 5 6 \n", 6, [3, 3]),  # doubled and trailing spaces: counted token by token
        (b"v\t1 2\t3\n", 3, [3]),  # tabs
        (b"v 1\t2 3\nv 4  5 6\n", 6, [3, 3]),  # a tab and a doubled space whose space counts add up to 6
    ],
    ids=["single spaces", "extra spaces", "tabs", "compensating"],
)
def test_values_per_line(block: bytes, total: int, expected: list[int]) -> None:
    assert values_per_line(block, total).tolist() == expected


def _reference(text: bytes, keyword: bytes) -> tuple[bytes, list[int]]:
    """The lines of one statement kind, joined, and their 1-based numbers: plain Python."""
    lines = text.split(b"\n")[:-1]
    picked = [(k + 1, line) for k, line in enumerate(lines) if line.split(b" ", 1)[0] == keyword]
    return b"".join(line + b"\n" for _, line in picked), [k for k, _ in picked]


@pytest.mark.parametrize("runs", [3, 200], ids=["few runs (joined)", "interleaved (byte mask)"])
def test_gather_picks_the_lines_of_one_kind(runs: int) -> None:
    rows = []
    for k in range(runs):
        rows += [f"v {k} {k + 1} {k + 2}", f"vt 0.{k} 0.5", f"vn 0 0 {k}", "# note"]
    rows += [f"f {k + 1} {k + 2} {k + 3}" for k in range(runs - 2)]
    text = ("\n".join(rows) + "\n").encode()
    lines = classify(text)
    for kind, keyword in ((V, b"v"), (VT, b"vt"), (VN, b"vn"), (F, b"f")):
        block, numbers_ = gather(lines, kind)
        expected_block, expected_lines = _reference(text, keyword)
        assert block == expected_block and numbers_.tolist() == expected_lines
    assert gather(classify(b"v 1 2 3\n"), F)[0] == b""  # no statement of that kind: an empty block


def test_vector_block_counts_come_with_the_values() -> None:
    lines = classify(b"v 1 2 3\nv 4 5 6 0.1 0.2 0.3\nvt 0.5 0.25\nvt 1 0\n")
    values, counts, numbers_ = block_of(lines, V, "v", "x.obj")
    assert values.tolist() == [1, 2, 3, 4, 5, 6, 0.1, 0.2, 0.3] and counts.tolist() == [3, 6]
    assert numbers_.tolist() == [1, 2]
    values, counts, numbers_ = block_of(lines, VT, "vt", "x.obj")
    assert values.tolist() == [0.5, 0.25, 1, 0] and counts.tolist() == [2, 2] and numbers_.tolist() == [3, 4]
    values, counts, numbers_ = block_of(lines, VN, "vn", "x.obj")  # no normals: three empty arrays
    assert values.shape == (0,) and counts.shape == (0,) and numbers_.shape == (0,)
    ragged = classify(b"v 1 2 3\nv 4\tnan 5 6\n")  # no table (counts differ, a tab): numbers, then token counts
    values, counts, _ = block_of(ragged, V, "v", "x.obj")
    assert np.array_equal(values, [1, 2, 3, 4, np.nan, 5, 6], equal_nan=True) and counts.tolist() == [3, 4]
