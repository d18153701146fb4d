import codecs

import numpy as np
import pytest

from meshtool.errors import ObjParseError
from meshtool.read.obj.parse import parse_mtllib_names, parse_obj

CUBE = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvn 0 0 1\n"


def codes(obj):
    return {f.code for f in obj.findings}


def test_all_four_index_forms_and_negative_indices():
    text = CUBE + "f 1 2 3\nf 1/1 2/2 3/3\nf 1//1 2//1 3//1\nf 1/1/1 2/2/1 3/3/1\nf -4/-3/-1 -3/-2/-1 -2/-1/-1\n"
    obj = parse_obj(text.encode(), "t.obj")
    assert obj.face_sizes.tolist() == [3] * 5
    assert obj.corner_v.tolist() == [0, 1, 2] * 5
    assert obj.corner_vt.tolist() == [-1, -1, -1, 0, 1, 2, -1, -1, -1, 0, 1, 2, 0, 1, 2]
    assert obj.corner_vn.tolist() == [-1, -1, -1, -1, -1, -1, 0, 0, 0, 0, 0, 0, 0, 0, 0]
    assert obj.face_lines.tolist() == [9, 10, 11, 12, 13]


def test_negative_indices_resolve_against_elements_read_so_far():
    obj = parse_obj(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 5 5 5\nv 6 5 5\nv 5 6 5\nf -3 -2 -1\n")
    assert obj.corner_v.tolist() == [0, 1, 2, 3, 4, 5]


def test_polygons_keep_their_corners_and_lines():
    obj = parse_obj(CUBE + "f 1 2 3 4\n\n# c\nf 4 3 2\n")
    assert obj.face_sizes.tolist() == [4, 3]
    assert obj.corner_v.tolist() == [0, 1, 2, 3, 3, 2, 1]
    assert obj.face_lines.tolist() == [9, 12]


def test_vertex_w_and_colours_do_not_shift_data():
    obj = parse_obj(b"v 1 2 3 0.5\nv 4 5 6 0.1 0.2 0.3\nv 7 8 9\nf 1 2 3\n")
    np.testing.assert_array_equal(obj.positions, [[1, 2, 3], [4, 5, 6], [7, 8, 9]])
    np.testing.assert_array_equal(obj.colors, [[1, 1, 1], [0.1, 0.2, 0.3], [1, 1, 1]])
    assert {"vertex-w-ignored", "vertex-colors-partial"} <= codes(obj)


def test_non_finite_colours_become_white():
    obj = parse_obj(b"v 0 0 0 nan 0 0\nv 1 0 0 0.5 0.5 0.5\nv 0 1 0 inf 1 1\nf 1 2 3\n", "c.obj")
    np.testing.assert_array_equal(obj.colors, [[1, 1, 1], [0.5, 0.5, 0.5], [1, 1, 1]])
    (f,) = [f for f in obj.findings if f.code == "vertex-colors-invalid"]
    assert f.line == 1 and f.message.startswith("2 vertex colour(s)")


def test_groups_objects_materials_and_mtllibs(fixtures):
    obj = parse_obj((fixtures / "features" / "features.obj").read_bytes(), "features.obj")
    assert [m.name for m in obj.mtllibs] == ["lib a.mtl", "lib b.mtl"]
    assert obj.material_names == ["first", "second"]
    assert obj.part_names == ["default", "Thing", "front back"]
    assert obj.face_material.tolist() == [0, 0, 1, 1]
    assert obj.face_part.tolist() == [2, 2, 2, 2]
    # continuation joined: the first face has 3 corners with uv and normals; the error line numbers stay
    assert obj.face_sizes.tolist() == [3, 3, 3, 3]
    assert obj.face_lines.tolist() == [16, 18, 23, 24]
    assert obj.corner_vt[:3].tolist() == [0, 1, 2]
    np.testing.assert_array_equal(obj.texcoords, [[0, 0], [1, 0], [1, 1]])
    assert {"lines-skipped", "points-skipped", "line-continuation", "vertex-colors-partial"} <= codes(obj)


def test_mtllib_names_split_at_mtl():
    assert parse_mtllib_names("Head 1.mtl") == ["Head 1.mtl"]
    assert parse_mtllib_names("a.mtl b.MTL  c d.mtl") == ["a.mtl", "b.MTL", "c d.mtl"]
    assert parse_mtllib_names("./fuze.obj.mtl") == ["./fuze.obj.mtl"]
    assert parse_mtllib_names(r"mtl\ filename\ with\ whitespace.mtl") == ["mtl filename with whitespace.mtl"]
    assert parse_mtllib_names('"quoted name.mtl"') == ["quoted name.mtl"]
    assert parse_mtllib_names("materials.txt") == ["materials.txt"]


def test_crlf_equals_lf(fixtures):
    crlf = (fixtures / "crlf_ngon" / "shapes.obj").read_bytes()
    assert b"\r\n" in crlf
    a = parse_obj(crlf)
    b = parse_obj(crlf.replace(b"\r\n", b"\n"))
    assert a.line_endings == "crlf" and b.line_endings == "lf"
    np.testing.assert_array_equal(a.positions, b.positions)
    np.testing.assert_array_equal(a.corner_v, b.corner_v)


@pytest.mark.parametrize(
    ("bom", "codec"),
    [(codecs.BOM_UTF8, "utf-8"), (codecs.BOM_UTF16_LE, "utf-16-le"), (codecs.BOM_UTF16_BE, "utf-16-be")],
)
def test_byte_order_marks(bom, codec):
    text = "g Größe\n" + CUBE + "f 1 2 3\n"
    obj = parse_obj(bom + text.encode(codec))
    assert obj.part_names == ["default", "Größe"]
    assert obj.positions.shape == (4, 3)


def test_latin1_fallback_keeps_names():
    obj = parse_obj(("usemtl Métal\n" + CUBE + "f 1 2 3\n").encode("latin-1"), "x.obj")
    assert obj.encoding == "latin-1"
    assert obj.material_names == ["Métal"]
    assert "encoding-latin1" in codes(obj)


def test_inline_comments_and_msvc_nan_spellings_use_line_parser():
    obj = parse_obj(b"v 0 0 0 # origin\nv 1.#IND -1.#INF 0\nv 1 0 0\nv 0 1 0\nf 1 3 4 # tri\n")
    assert obj.positions.shape == (4, 3)
    assert np.isnan(obj.positions[1, 0]) and obj.positions[1, 1] == -np.inf
    assert obj.corner_v.tolist() == [0, 2, 3]


def test_special_number_forms():
    obj = parse_obj(b"v .5 +1 -2.5e-3\nv 1E2 0 -0\nv 1 1 1\nf 1 2 3\n")
    np.testing.assert_array_equal(obj.positions[:2], [[0.5, 1, -0.0025], [100, 0, 0]])


def test_face_with_too_few_corners_is_skipped():
    obj = parse_obj(CUBE + "f 1 2\nf 1 2 3\n", "t.obj")
    assert obj.face_sizes.tolist() == [3]
    (finding,) = [f for f in obj.findings if f.code == "face-too-small"]
    assert finding.line == 9


def test_attribute_indices_without_attributes_are_dropped():
    obj = parse_obj(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1/1 2/2/1 3/3/1\n", "t.obj")
    assert obj.corner_vt.tolist() == [-1, -1, -1]
    assert obj.corner_vn.tolist() == [-1, -1, -1]
    assert {"vt-missing", "vn-missing"} <= codes(obj)


def test_forward_reference_is_resolved_with_a_note():
    obj = parse_obj(b"v 0 0 0\nf 1 2 3\nv 1 0 0\nv 0 1 0\n")
    assert obj.corner_v.tolist() == [0, 1, 2]
    assert "forward-reference" in codes(obj)


def test_free_form_and_unknown_statements_are_findings():
    obj = parse_obj(CUBE + "cstype bspline\nfoo bar\nf 1 2 3\n", "t.obj")
    assert {"freeform-skipped", "unknown-statement"} <= codes(obj)


@pytest.mark.parametrize(
    ("data", "line", "words"),
    [
        (b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 7\n", 5, "vertex 7 but the file defines 3"),
        (b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", 4, "index 0 is invalid"),
        (b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/0 2/1 3/1\nvt 0 0\n", 4, "index 0 is invalid"),
        (b"v 0 0 0\nv 1 0 0\nf -3 -2 -1\n", 3, "reaches before the first vertex"),
        (b"v 0 0 0\nv 1 x 0\n", 2, "malformed number 'x'"),
        (b"v 0 0\n", 1, "needs x y z"),
        (b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3.5\n", 4, "malformed face corner '3.5'"),
        (b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3-4\n", 4, "malformed face corner"),
        (b"hello world\nthis is not a mesh\n", 1, "not an OBJ file"),
    ],
)
def test_errors_name_the_line(data, line, words):
    with pytest.raises(ObjParseError) as info:
        parse_obj(data, "bad.obj")
    assert info.value.line == line
    assert words in str(info.value)
    assert str(info.value).startswith(f"bad.obj:{line}: ")
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("name", ["empty.obj", "comments.obj"])
def test_empty_files(fixtures, name):
    with pytest.raises(ObjParseError, match="empty OBJ file"):
        parse_obj((fixtures / "empty" / name).read_bytes(), name)


def test_binary_garbage_names_the_byte_offset(fixtures):
    with pytest.raises(ObjParseError) as info:
        parse_obj((fixtures / "garbage" / "garbage.obj").read_bytes(), "garbage.obj")
    assert "binary data" in str(info.value)
    assert info.value.offset == 6  # the \x1a of the PNG signature
    assert isinstance(info.value, ValueError)


def test_fast_and_line_by_line_paths_agree():
    rng = np.random.default_rng(5)
    v = rng.normal(size=(50, 3))
    f = rng.integers(1, 51, size=(40, 4))
    body = "".join(f"v {a!r} {b!r} {c!r}\n" for a, b, c in v.tolist())
    faces = "".join("f " + " ".join(str(i) for i in row) + "\n" for row in f.tolist())
    fast = parse_obj((body + faces).encode())
    slow = parse_obj((body + faces.replace("\n", " # c\n")).encode())
    np.testing.assert_array_equal(fast.positions, v)
    np.testing.assert_array_equal(fast.corner_v, f.ravel() - 1)
    np.testing.assert_array_equal(slow.corner_v, fast.corner_v)
