"""Hostile PLY and STL files (issue 27): every break is one error line with file and location, exit 1.

Every input is generated here, small. A handful go through the CLI in a child process with a time and
memory bound (:mod:`bounded`); the many-input loops (every truncation, header mutations) run in-process and
expect :class:`MeshtoolError` and nothing else.
"""

from __future__ import annotations

import random
import struct
import tracemalloc
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pytest
from bounded import Outcome, run_bounded

from meshtool.errors import FormatError, MeshtoolError
from meshtool.read.ply import read_ply
from meshtool.read.stl import read_stl

CUBE_V = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]
CUBE_F = [
    (0, 2, 1), (0, 3, 2), (4, 5, 6), (4, 6, 7), (0, 1, 5), (0, 5, 4),
    (2, 3, 7), (2, 7, 6), (1, 2, 6), (1, 6, 5), (0, 4, 7), (0, 7, 3),
]  # fmt: skip
_ORDER = {"<": "binary_little_endian", ">": "binary_big_endian"}
_PACK = {"char": "b", "uchar": "B", "short": "h", "int": "i", "uint": "I", "float": "f"}


def ascii_ply(
    vertices: Sequence[tuple[object, ...]] = CUBE_V,
    faces: Sequence[tuple[int, ...]] = CUBE_F,
    *,
    nv: int | None = None,
    nf: int | None = None,
    fmt: str = "ascii 1.0",
) -> bytes:
    """An ASCII PLY: ``x y z`` vertices, ``vertex_indices`` faces; ``nv``/``nf`` override the declared counts."""
    head = (
        f"ply\nformat {fmt}\nelement vertex {len(vertices) if nv is None else nv}\n"
        "property float x\nproperty float y\nproperty float z\n"
        f"element face {len(faces) if nf is None else nf}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    rows = [" ".join(str(c) for c in v) for v in vertices] + [" ".join(map(str, (len(f), *f))) for f in faces]
    return (head + "".join(r + "\n" for r in rows)).encode()


def binary_ply(
    vertices: Sequence[tuple[float, ...]] = CUBE_V,
    faces: Sequence[tuple[int, ...]] = CUBE_F,
    *,
    order: str = "<",
    said: str | None = None,
    nv: int | None = None,
    nf: int | None = None,
    count: str = "uchar",
    index: str = "int",
) -> bytes:
    """A binary PLY written in byte ``order``, its header naming ``said`` (default: the same)."""
    head = (
        f"ply\nformat {_ORDER[said or order]} 1.0\nelement vertex {len(vertices) if nv is None else nv}\n"
        "property float x\nproperty float y\nproperty float z\n"
        f"element face {len(faces) if nf is None else nf}\nproperty list {count} {index} vertex_indices\nend_header\n"
    ).encode()
    body = b"".join(struct.pack(order + "3f", *v) for v in vertices)
    body += b"".join(struct.pack(order + _PACK[count] + _PACK[index] * len(f), len(f), *f) for f in faces)
    return head + body


def strips_ply(rows: list[list[int]], *, encoding: str = "binary_little_endian", nv: int = 8) -> bytes:
    """Triangle strips as Stanford's igea.ply stores them: ``element tristrips`` with an ``int int`` list."""
    grid = [(float(k // 2), float(k % 2), 0.0) for k in range(nv)]  # a 2 x (nv / 2) grid in z = 0
    head = (
        f"ply\nformat {encoding} 1.0\nelement vertex {nv}\nproperty float x\nproperty float y\nproperty float z\n"
        f"element tristrips {len(rows)}\nproperty list int int vertex_indices\nend_header\n"
    ).encode()
    if encoding == "ascii":
        body = "".join(" ".join(map(str, v)) + "\n" for v in grid)
        body += "".join(" ".join(map(str, (len(r), *r))) + "\n" for r in rows)
        return head + body.encode()
    order = "<" if encoding == "binary_little_endian" else ">"
    data = b"".join(struct.pack(order + "3f", *v) for v in grid)
    data += b"".join(struct.pack(f"{order}i{len(r)}i", len(r), *r) for r in rows)
    return head + data


def stl_ascii(*vertex_lines: str) -> bytes:
    """One ASCII facet whose three ``vertex`` lines are given (the first vertex line is line 4)."""
    body = "\n".join(f"vertex {v}" for v in vertex_lines)
    return f"solid s\nfacet normal 0 0 1\nouter loop\n{body}\nendloop\nendfacet\nendsolid s\n".encode()


def triangles(data: bytes, name: str = "x.ply") -> list[tuple[int, ...]]:
    mesh = read_ply(data, name)
    return [tuple(int(i) for i in t) for t in mesh.corner_v.reshape(-1, 3)]


def cli(tmp_path: Path, name: str, data: bytes, command: str = "normalize") -> Outcome:
    """``meshtool normalize FILE -o OUT`` (or ``obj2bin`` / ``validate``) in a bounded child process."""
    path = tmp_path / name
    path.write_bytes(data)
    if command == "obj2bin":
        argv = ["obj2bin", str(path), "-o", str(tmp_path / "out.mbin")]
    elif command == "validate":
        argv = ["meshtool", "validate", str(path)]
    else:
        argv = ["meshtool", "normalize", str(path), "-o", str(tmp_path / "out")]
    return run_bounded(argv, seconds=60, memory_mb=1500)


def refused(outcome: Outcome, *words: str) -> str:
    """Exit 1 with one ``error:`` line containing ``words``; the line."""
    assert outcome.code == 1, (outcome.code, outcome.err[-2000:])
    lines = [line for line in outcome.err.splitlines() if line.startswith("error:")]
    assert len(lines) == 1 and "Traceback" not in outcome.err, outcome.err
    for word in words:
        assert word in lines[0], (word, lines[0])
    return lines[0]


def error_of(data: bytes, name: str = "x.ply") -> FormatError:
    reader = read_stl if name.endswith(".stl") else read_ply
    with pytest.raises(FormatError) as caught:
        reader(data, name)
    text = str(caught.value)
    assert "\n" not in text and text.startswith(name), text
    return caught.value


# ----------------------------------------------------------------------------------------------------------
# the breaks of the issue, one test each


def test_face_index_out_of_range_is_an_error_naming_the_face(tmp_path: Path) -> None:
    bad = [*CUBE_F[:-1], (0, 7, 8)]
    refused(cli(tmp_path, "oob.ply", ascii_ply(faces=bad)), "oob.ply:29:", "face 12 refers to vertex 8", "8 vertices")
    offset = len(binary_ply()) - 4  # the last index of the last face
    line = refused(cli(tmp_path, "oobb.ply", binary_ply(faces=bad), "obj2bin"), f"oobb.ply: byte {offset}:", "face 12")
    assert "vertex 8" in line


def test_negative_index_does_not_wrap_around(tmp_path: Path) -> None:
    faces = [(0, 1, -1), *CUBE_F]
    refused(cli(tmp_path, "neg.ply", ascii_ply(faces=faces)), "neg.ply:18:", "face 1 refers to vertex -1", "start at 0")
    err = error_of(binary_ply(faces=faces))
    assert err.offset is not None and "face 1 refers to vertex -1" in err.message


def test_wrong_byte_order_is_an_error_with_offset(tmp_path: Path) -> None:
    swapped = binary_ply(order=">", said="<")  # uchar counts read fine, the indices do not
    refused(cli(tmp_path, "bo.ply", swapped), "bo.ply: byte ", "face 1 refers to vertex 33554432", "byte order")
    swapped_int = binary_ply(order=">", said="<", count="int")  # the list length itself is swapped
    err = error_of(swapped_int)
    assert err.offset is not None and "50,331,648 values runs past the end" in err.message
    little_as_big = binary_ply(order="<", said=">")
    assert error_of(little_as_big).offset is not None


@pytest.mark.parametrize("encoding", ["ascii", "binary_little_endian", "binary_big_endian", "binary_mixed_int"])
def test_every_truncation_is_the_whole_mesh_or_a_clean_error(encoding: str) -> None:
    """Every prefix of a small PLY: an error, or (ASCII, only the last line cut) the same faces and a warning."""
    vertices = [*CUBE_V, *[(2.5, 2.0, float(k)) for k in range(5)]]  # 13 vertices: the last index has 2 digits
    faces = [*CUBE_F, (0, 2, 12)]
    if encoding == "ascii":
        data = ascii_ply(vertices, faces)
    elif encoding == "binary_mixed_int":  # rows of different sizes, int lengths: read row by row
        data = binary_ply(vertices, [(0, 1, 2, 3), *faces, (8, 9, 10, 11, 12)], count="int")
    else:
        data = binary_ply(vertices, faces, order="<" if encoding.endswith("little_endian") else ">")
    whole = read_ply(data, "t.ply")
    read = []
    for cut in range(len(data)):
        try:
            mesh = read_ply(data[:cut], "t.ply")
        except MeshtoolError as exc:
            assert "\n" not in str(exc) and str(exc).startswith("t.ply"), str(exc)
            continue
        read.append(cut)
        assert [f.code for f in mesh.findings] == ["ply-unterminated"], cut  # never silently
        assert mesh.face_sizes.size == whole.face_sizes.size, cut  # never fewer triangles
        if cut == len(data) - 1:  # only the final line end cut: the whole mesh
            np.testing.assert_array_equal(mesh.corner_v, whole.corner_v)
            np.testing.assert_array_equal(mesh.positions, whole.positions)
    # "3 0 2 12" cut to "3 0 2 1" still reads (the warning says the last value may be incomplete)
    assert read == ([len(data) - 2, len(data) - 1] if encoding == "ascii" else [])


def test_truncated_ascii_ply_through_the_cli(tmp_path: Path) -> None:
    data = ascii_ply()
    cut = data[: data.rindex(b"3 4 5 6")]  # mid-way through the faces
    refused(cli(tmp_path, "cut.ply", cut), "cut.ply:19:", "after 2 of the 12 'face' rows")
    refused(cli(tmp_path, "cutb.ply", binary_ply()[:300]), "cutb.ply: byte ", "runs past the end")


@pytest.mark.parametrize(
    ("header", "words"),
    [
        ("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n", ["no 'end_header'"]),
        ("ply\nformat utf8 1.0\nend_header\n", [":2:", "unknown format 'utf8 1.0'"]),
        ("ply\nformat ascii\nend_header\n", [":2:", "unknown format"]),
        ("ply\nelement vertex 0\nend_header\n", ["no 'format' line"]),
        ("ply\nformat ascii 1.0\nformat ascii 1.0\nend_header\n", [":3:", "second 'format'"]),
        ("ply\nformat ascii 1.0\nproperty float x\nend_header\n", [":3:", "'property' before any 'element'"]),
        ("ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\nend_header\n", [":4:", "unknown property type"]),
        ("ply\nformat ascii 1.0\nelement vertex -3\nend_header\n", [":3:", "'-3' is not a whole number"]),
        ("ply\nformat ascii 1.0\nelement vertex 1e3\nend_header\n", [":3:", "not a whole number"]),
        ("ply\nformat ascii 1.0\nelement vertex " + "9" * 5000 + "\nend_header\n", [":3:", "not a whole number"]),
        ("ply\nformat ascii 1.0\nelement vertex\nend_header\n", [":3:", "needs a name and a count"]),
        ("ply\nformat ascii 1.0\nelement vertex 0\nelement vertex 0\nend_header\n", [":4:", "second element"]),
        ("ply\nformat ascii 1.0\nelement v 1\nproperty float x\nproperty float x\nend_header\n", [":5:", "second"]),
        ("ply\nformat ascii 1.0\nelement f 1\nproperty list float int i\nend_header\n", [":4:", "not an integer"]),
        ("ply\nformat ascii 1.0\nelement f 1\nproperty list uchar int\nend_header\n", [":4:", "'property list'"]),
        ("ply\nformat ascii 1.0\nelement junk 5\nend_header\n", [":3:", "no properties"]),
        ("ply\nformat ascii 1.0\nelemnt vertex 1\nend_header\n", [":3:", "unknown header keyword 'elemnt'"]),
        ("ply\nformat ascii 1.0\n\xe9l\xe9ment vertex 1\nend_header\n", [":3:", "non-ASCII"]),
        ("ply\nformat ascii 1.0\nelement vertex 1\x00\nend_header\n", [":3:", "control bytes"]),
        ("ply\nformat ascii 1.0\nend_header\n", [":2:", "no 'vertex' element"]),
        ("ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nend_header\n", [":3:", "no x, y and z"]),
        (
            "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\n"
            "element face 1\nproperty list uchar int corners\nend_header\n3 0 1 2\n",
            [":7:", "no 'vertex_indices' list"],
        ),
        ("ply\nformat ascii 1.0\nend_headerX\n", [":3:", "malformed 'end_header'"]),
        ("ply\nformat ascii 1.0\nend_header junk\n", [":3:", "malformed 'end_header'"]),
        ("plyx\nformat ascii 1.0\nend_header\n", ["not a PLY file"]),
    ],
)
def test_malformed_header_is_one_error_naming_the_line(header: str, words: list[str]) -> None:
    err = error_of(header.encode("latin-1"), "h.ply")
    for word in words:
        assert word in str(err), (word, str(err))


def test_malformed_header_through_the_cli(tmp_path: Path) -> None:
    data = ascii_ply().replace(b"property float y", b"property float32x y")
    refused(cli(tmp_path, "h.ply", data), "h.ply:5:", "unknown property type 'float32x'")
    checked = cli(tmp_path, "h.ply", data, "validate")
    assert checked.code == 1 and "Traceback" not in checked.err, checked.err
    assert "h.ply:5" in checked.out and "unknown property type" in checked.out, checked.out


def test_fuzzed_headers_only_ever_raise_meshtool_errors() -> None:
    """Random edits of header words (the attackers' KeyError/ValueError exits 3): an error or a mesh, no bug."""
    rng = random.Random(27)
    seeds = [ascii_ply(), binary_ply(), strips_ply([[0, 1, 2, 3, -1, 4, 5, 6, 7]])]
    words = [b"ply", b"format", b"element", b"property", b"list", b"uchar", b"int", b"float", b"vertex", b"face",
             b"end_header", b"-1", b"0", b"99999999999999999999", b"x", b"vertex_indices", b"\xff", b"\x00", b"",
             b"tristrips", b"binary_big_endian", b"ascii", b"comment", b"double", b"char"]  # fmt: skip
    outcomes = {"ok": 0, "error": 0}
    for _ in range(1500):
        data = rng.choice(seeds)
        end = data.index(b"end_header")
        head = data[:end].split(b" ")
        for _ in range(rng.randint(1, 3)):
            head[rng.randrange(len(head))] = rng.choice(words)
        mutated = b" ".join(head) + data[end:]
        try:
            read_ply(mutated, "f.ply")
            outcomes["ok"] += 1
        except MeshtoolError as exc:
            assert "\n" not in str(exc) and str(exc).startswith("f.ply"), str(exc)
            outcomes["error"] += 1
    assert outcomes["error"] > 1000


def test_lying_vertex_count_is_an_error(tmp_path: Path) -> None:
    """A vertex count that is too high reads faces as vertices; too low, vertices as faces: both refused."""
    refused(cli(tmp_path, "hi.ply", ascii_ply(nv=10)), "hi.ply:18:", "'vertex' row 9 has 4 values")
    assert "'face' row 1 has 3 values" in str(error_of(ascii_ply(nv=6)))
    high, low = error_of(binary_ply(nv=10)), error_of(binary_ply(nv=6))
    assert high.offset is not None and "face 1 has 0 corner(s)" in high.message
    assert low.offset is not None and "runs past the end" in low.message
    for nv in range(0, 21):  # whatever the lie: an error, never a mesh
        if nv != 8:
            error_of(ascii_ply(nv=nv))
            error_of(binary_ply(nv=nv))


def test_lying_face_count() -> None:
    """Too many faces declared: an error naming where the data ended; too few: the rest is reported."""
    err = error_of(ascii_ply(nf=20))
    assert err.line == 29 and "after 12 of the 20 'face' rows" in err.message
    assert error_of(binary_ply(nf=20)).offset is not None
    mesh = read_ply(ascii_ply(nf=5), "x.ply")
    assert mesh.face_sizes.size == 5
    assert [f.code for f in mesh.findings] == ["ply-trailing-data"] and "from line 23" in mesh.findings[0].message
    assert [f.code for f in read_ply(binary_ply(nf=5), "x.ply").findings] == ["ply-trailing-data"]


def test_huge_count_in_a_small_file_is_refused_at_once(tmp_path: Path) -> None:
    """10^12 vertices declared in a file of a few hundred bytes: refused before anything is allocated."""
    for data, where in ((ascii_ply(nv=10**12), "huge.ply:29:"), (binary_ply(nv=10**12), "huge.ply: byte 182:")):
        assert len(data) < 500
        tracemalloc.start()
        try:
            err = error_of(data, "huge.ply")
            peak = tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()
        assert peak < 1 << 20, peak  # nothing of the declared size allocated (numpy's buffers are traced too)
        assert str(err).startswith(where) and "1,000,000,000,000 'vertex' rows" in str(err)
        refused(cli(tmp_path, "huge.ply", data), where, "1,000,000,000,000")
    strips = strips_ply([[0, 1, 2]]).replace(b"element tristrips 1", b"element tristrips 999999999999")
    assert "999,999,999,999 'tristrips' rows" in str(error_of(strips))


@pytest.mark.parametrize(
    ("row", "words"),
    [
        ("-3 0 1 2", ["length -3 is not a whole number of 0 or more"]),
        ("2.5 0 1 2", ["length 2.5 is not a whole number"]),
        ("1e9 0 1 2", ["list 'vertex_indices' of 1000000000 values runs past the end of its line (4 values)"]),
        ("3 0 1", ["list 'vertex_indices' of 3 values runs past the end of its line (3 values)"]),
        ("3", ["list 'vertex_indices' of 3 values runs past the end of its line (1 value)"]),
        ("3 0 1 2 7", ["'face' row 1 has 5 values but its properties take 4"]),
        ("3 0 1.5 2", ["face 1 refers to vertex 1.5, which is not a whole number"]),
        ("3 0 1 1_0", ["'1_0' is not a number"]),
        ("3 0 1 0x2", ["'0x2' is not a number"]),
        ("3 0 1 \u0662", ["is not a number"]),
    ],
)
def test_ascii_face_lists_are_checked(row: str, words: list[str]) -> None:
    data = ascii_ply().replace(b"3 0 2 1\n", row.encode() + b"\n", 1)
    err = error_of(data)
    assert err.line == 18, str(err)
    for word in words:
        assert word in str(err), (word, str(err))


def test_binary_face_lists_are_checked() -> None:
    negative = error_of(binary_ply(faces=[(0, 1, 2)], count="int").replace(b"\x03\x00\x00\x00", b"\xfd\xff\xff\xff"))
    assert negative.offset == len(binary_ply(faces=[], count="int")) and "negative length (-3)" in negative.message
    huge = binary_ply(faces=[(0, 1, 2)], count="int")
    huge = huge[:-16] + struct.pack("<i", 2**31 - 1) + huge[-12:]
    assert "2,147,483,647 values runs past the end" in error_of(huge).message
    corners = 70_000
    many = binary_ply(vertices=CUBE_V, faces=[tuple(k % 8 for k in range(corners))], count="int")
    err = error_of(many)
    assert err.code == "limit-face-corners" and "70,000 corners" in err.message and err.offset is not None
    floats = binary_ply(faces=[(0, 1, 2)]).replace(b"uchar int", b"uchar float")
    floats = floats[:-12] + struct.pack("<3f", 0, 1, 2.5)
    assert "vertex 2.5, which is not a whole number" in error_of(floats).message


def test_short_faces_binary_error_ascii_warning() -> None:
    err = error_of(binary_ply(faces=[(0, 1), *CUBE_F]))
    assert "face 1 has 2 corner(s)" in err.message and err.offset is not None
    mesh = read_ply(ascii_ply(faces=[(0, 1), *CUBE_F]), "x.ply")
    assert mesh.face_sizes.size == 12 and [f.code for f in mesh.findings] == ["face-too-small"]


def test_texture_file_comment_may_be_utf8_other_lines_not() -> None:
    data = ascii_ply().replace(b"format ascii 1.0\n", "format ascii 1.0\ncomment TextureFile t\u00ebx.png\n".encode())
    assert read_ply(data, "x.ply").materials[0].maps["map_Kd"].file == "t\u00ebx.png"
    assert "non-ASCII" in str(error_of(data.replace(b"comment TextureFile", b"TextureFile")))


def test_ascii_ply_without_final_line_end_says_so() -> None:
    mesh = read_ply(ascii_ply().rstrip(b"\n"), "x.ply")
    assert mesh.face_sizes.size == 12 and [f.code for f in mesh.findings] == ["ply-unterminated"]
    assert read_ply(ascii_ply(), "x.ply").findings == []


# ----------------------------------------------------------------------------------------------------------
# triangle strips


# A strip 0 1 2 3 4 5 over the grid (k // 2, k % 2): triangles alternate winding, all facing +z after the flip.
STRIP_ROWS = [[0, 1, 2, 3, -1, 2, 3, 4, 5, 5, 6, 6, 7, 6], [1, 3, 0]]
STRIP_TRIANGLES = [
    (0, 1, 2), (2, 1, 3),  # strip 0 1 2 3 (second triangle flipped)
    (2, 3, 4), (4, 3, 5),  # after -1: strip 2 3 4 5 ...
    # 5 5 6 / 5 6 6 / 6 6 7 are degenerate (dropped); 6 7 6 is degenerate too
    (1, 3, 0),  # the second row is its own strip
]  # fmt: skip


@pytest.mark.parametrize("encoding", ["binary_little_endian", "binary_big_endian", "ascii"])
def test_tristrips_are_read_with_alternating_winding(encoding: str) -> None:
    data = strips_ply(STRIP_ROWS, encoding=encoding)
    assert triangles(data) == STRIP_TRIANGLES
    mesh = read_ply(data, "s.ply")
    assert mesh.location == "triangle" and mesh.face_lines.tolist() == [1, 2, 3, 4, 5]
    assert mesh.record["tristrips"] == 2 and mesh.record["strip_triangles"] == 5


def test_tristrips_wind_consistently() -> None:
    """Independent of the hand list: a long strip over a flat grid gives triangles that all face +z."""
    n = 40
    data = strips_ply([list(range(n))], nv=n)
    mesh = read_ply(data, "s.ply")
    p = mesh.positions[mesh.corner_v.reshape(-1, 3)]
    normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    signs = np.sign(normal[:, 2])
    assert normal.shape[0] == n - 2 and signs[0] != 0 and (signs == signs[0]).all()  # the odd ones were flipped


def test_tristrips_through_the_cli(tmp_path: Path) -> None:
    outcome = cli(tmp_path, "igea.ply", strips_ply(STRIP_ROWS))
    assert outcome.code == 0, outcome.err
    assert "5 triangles" in outcome.out
    refused(cli(tmp_path, "bad.ply", strips_ply([[0, 1, 9]])), "bad.ply: byte ", "strip 1 refers to vertex 9")
    assert "start at 0 (-1 ends a strip)" in error_of(strips_ply([[0, 1, -2]])).message
    assert error_of(strips_ply([[0, 1, 9]], encoding="ascii")).line == 18


# ----------------------------------------------------------------------------------------------------------
# STL


def test_stl_number_with_underscore_is_an_error_naming_the_line(tmp_path: Path) -> None:
    data = stl_ascii("0 0 0", "1_0 0 0", "0 1 0")
    refused(cli(tmp_path, "u.stl", data), "u.stl:5:", "'1_0' is not a number")
    assert error_of(stl_ascii("0 0 0", "1 0 0", "0 \u0661 0"), "n.stl").line == 6  # an Arabic-Indic 1
    assert read_stl(stl_ascii("0 0 0", "10 0 0", "0 1 0").replace(b"solid s", b"solid my_part"), "ok.stl")


def test_stl_line_numbers_count_only_real_line_ends() -> None:
    """A form feed or \\x1c inside a line does not shift the line an error names (str.splitlines would)."""
    data = stl_ascii("0 0 0", "1 0 0", "0 x 0").replace(b"solid s", b"solid s\x1c\x0c")
    assert error_of(data, "l.stl").line == 6
