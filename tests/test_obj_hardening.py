"""Hostile OBJ input (issue 21): bounded work, strict number and index syntax, binary bytes anywhere.

Each test reproduces an attack from the issue with a small generated input. Tests that once hung run under
a watchdog (``faulthandler``, which also fires inside C code such as earcut) so a regression fails the run
instead of blocking it.
"""

from __future__ import annotations

import faulthandler
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import pytest

from meshtool.errors import ObjParseError
from meshtool.mesh import build_mesh
from meshtool.obj.faces import MAX_FACE_CORNERS
from meshtool.obj.lines import reject_control_bytes
from meshtool.obj.parse import MAX_MTLLIBS, parse_obj

TRIANGLE = "v 0 0 0\nv 1 0 0\nv 0 1 0\n"


@contextmanager
def watchdog(seconds: int = 60) -> Iterator[None]:
    """Abort the test process with a traceback when the block runs longer than ``seconds`` (a hang)."""
    faulthandler.dump_traceback_later(seconds, exit=True)
    try:
        yield
    finally:
        faulthandler.cancel_dump_traceback_later()


def cycling_face(corners: int) -> str:
    """One face that walks around the same three vertices ``corners`` times (the issue's 20 KB hang)."""
    return "f " + " ".join(str(1 + i % 3) for i in range(corners)) + "\n"


def codes(findings) -> set[str]:
    return {f.code for f in findings}


# ------------------------------------------------------------------------------------------------------
# 1. bounded work


def test_face_of_10k_corners_over_three_vertices_is_one_triangle():
    text = TRIANGLE + cycling_face(10_000)
    assert 19_000 < len(text) < 21_000  # the 20 KB file of the issue
    with watchdog():
        obj = parse_obj(text.encode(), "hang.obj")
        mesh, findings = build_mesh(obj)
    (face,) = mesh.faces.tolist()  # the only area the face covers, once, wound like the polygon
    assert face in ([0, 1, 2], [1, 2, 0], [2, 0, 1])
    (fanned,) = [f for f in findings if f.code == "polygon-fanned"]
    assert fanned.line == 4 and fanned.path == "hang.obj"


def test_face_at_the_corner_limit_is_read_and_one_past_it_is_refused_with_its_line():
    with watchdog():
        obj = parse_obj((TRIANGLE + "\n" + cycling_face(MAX_FACE_CORNERS)).encode(), "big.obj")
        mesh, _ = build_mesh(obj)
        assert mesh.faces.shape == (1, 3)
        with pytest.raises(ObjParseError) as err:
            parse_obj((TRIANGLE + "\n" + cycling_face(MAX_FACE_CORNERS + 1)).encode(), "big.obj")
    assert err.value.line == 5 and err.value.code == "limit-face-corners"
    assert str(MAX_FACE_CORNERS) in err.value.message


def test_degenerate_face_of_100k_corners_is_refused_quickly():
    with watchdog(), pytest.raises(ObjParseError) as err:
        parse_obj((TRIANGLE + cycling_face(100_000)).encode(), "huge.obj")
    assert err.value.line == 4


def test_mtllib_line_with_100k_names_keeps_the_first_names_with_a_finding():
    names = " ".join(f"m{i}.mtl" for i in range(100_000))
    with watchdog():
        obj = parse_obj(f"mtllib {names}\n{TRIANGLE}f 1 2 3\n".encode(), "many.obj")
    assert [r.name for r in obj.mtllibs] == [f"m{i}.mtl" for i in range(MAX_MTLLIBS)]
    (too_many,) = [f for f in obj.findings if f.code == "mtllib-too-many"]
    assert too_many.line == 1 and "100000" in too_many.message


def test_mtllib_limit_counts_every_statement():
    text = "".join(f"mtllib a{i}.mtl b{i}.mtl\n" for i in range(MAX_MTLLIBS)) + TRIANGLE + "f 1 2 3\n"
    obj = parse_obj(text.encode(), "t.obj")
    assert len(obj.mtllibs) == MAX_MTLLIBS
    assert obj.mtllibs[-1].name == f"b{MAX_MTLLIBS // 2 - 1}.mtl"
    (too_many,) = [f for f in obj.findings if f.code == "mtllib-too-many"]
    assert too_many.line == MAX_MTLLIBS // 2 + 1  # the first statement that did not fit


# ------------------------------------------------------------------------------------------------------
# 3. numbers and indices: OBJ syntax, not Python's


@pytest.mark.parametrize(
    ("face", "word"),
    [
        ("f 1_0 2 3", "1_0"),  # int() reads this as 10
        ("f 1 2 0x3", "0x3"),
        ("f 1 2 3.0", "3.0"),
        ("f 1 2 \u0663", "\u0663"),  # ARABIC-INDIC DIGIT THREE: int() reads it as 3
        ("f 1/1_0 2/1 3/1", "1/1_0"),
        ("f 1//+_1 2//1 3//1", "1//+_1"),
        ("f 1 2 3e0", "3e0"),
    ],
)
def test_face_index_must_be_ascii_digits(face, word):
    text = "v 0 0 0\n" * 12 + "vt 0 0\nvn 0 0 1\n" + face + "\n"
    with pytest.raises(ObjParseError) as err:
        parse_obj(text.encode(), "idx.obj")
    assert err.value.line == 15
    assert repr(word) in err.value.message


@pytest.mark.parametrize("index", ["99999999999999999999", "-99999999999999999999", "2147483648"])
def test_face_index_beyond_any_file_is_an_error_with_its_line(index):
    for corner in (index, f"1/{index}"):
        with pytest.raises(ObjParseError) as err:
            parse_obj(f"{TRIANGLE}vt 0 0\nf 1/1 2/1 {corner}\n".encode(), "big.obj")
        assert err.value.line == 5


@pytest.mark.parametrize(
    ("line", "word"),
    [("v 1_0 0 0", "1_0"), ("v 0x10 0 0", "0x10"), ("v \u0661 0 0", "\u0661"), ("vt 0 1_5", "1_5")],
)
def test_coordinates_must_be_obj_numbers(line, word):
    text = TRIANGLE + line + "\nf 1 2 3\n"
    with pytest.raises(ObjParseError) as err:
        parse_obj(text.encode(), "num.obj")
    assert err.value.line == 4 and repr(word) in err.value.message


@pytest.mark.parametrize("word", ["nan", "infinity", "-inf", "1.#INF", "+NaN"])
def test_non_finite_coordinate_of_a_used_vertex_is_an_error_naming_its_line(word):
    obj = parse_obj(f"v 0 0 0\nv {word} 0 0\nv 0 1 0\nf 1 2 3\n".encode(), "nf.obj")
    with pytest.raises(ObjParseError) as err:
        build_mesh(obj)
    assert err.value.line == 2 and err.value.code == "non-finite"


def test_well_formed_indices_still_read_both_ways():
    text = TRIANGLE + "vt 0 0\nf +1/+1 2/1 -1/-1\nf 1 +2 3\n"
    obj = parse_obj(text.encode(), "ok.obj")
    assert obj.corner_v.tolist() == [0, 1, 2, 0, 1, 2]
    assert obj.corner_vt.tolist() == [0, 0, 0, -1, -1, -1]


# ------------------------------------------------------------------------------------------------------
# 4. binary bytes after the first 64 KiB


@pytest.mark.parametrize(
    "statement", ["v 1 1\x00 1", "g name\x00", "usemtl a\x00b", "mtllib a\x00.mtl", "f 1 2 3\x00", "# c\x07"]
)
def test_nul_after_64_kib_is_an_error_naming_its_line(statement):
    padding = "# padding so that the byte lies far beyond the first 64 KiB\n" * 2000
    text = TRIANGLE + "f 1 2 3\n" + padding + statement + "\nf 1 2 3\n"
    assert text.index(statement) > 1 << 16
    with pytest.raises(ObjParseError) as err:
        parse_obj(text.encode(), "nul.obj")
    assert err.value.line == 5 + 2000


def test_line_reader_rejects_control_bytes_itself():
    reject_control_bytes(b"v 0 0 0\n\tv\x0b\x0c 1\n", "ok.obj")  # tab, VT, FF are whitespace
    with pytest.raises(ObjParseError) as err:
        reject_control_bytes(b"v 0 0 0\nv 1 1 1\ng a\x00b\n", "x.obj")
    assert (err.value.path, err.value.line) == ("x.obj", 3)
    assert "0x00" in err.value.message and "column 4" in err.value.message


def test_cycling_face_corner_count_matches_the_issue():
    assert len(np.unique([int(w) for w in cycling_face(10_000).split()[1:]])) == 3
