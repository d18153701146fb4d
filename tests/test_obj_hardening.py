"""Hostile OBJ input (issue 21): bounded work, strict number and index syntax, binary bytes anywhere.

Each test reproduces an attack from the issue with a small generated input. Tests that once hung run under
a watchdog (``faulthandler``, which also fires inside C code such as earcut) so a regression fails the run
instead of blocking it.
"""

from __future__ import annotations

import faulthandler
import os
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

from meshtool.errors import ObjParseError
from meshtool.read.obj.faces import MAX_FACE_CORNERS
from meshtool.read.obj.lines import reject_control_bytes
from meshtool.read.obj.parse import MAX_MTLLIBS, parse_obj
from meshtool.repair.mesh import build_mesh

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


# ------------------------------------------------------------------------------------------------------
# 2. non-finite and extreme numbers

TETRA_FACES = "f 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n"


def tetra(first: str, *others: str) -> str:
    rest = list(others) or ["v 0 1 0", "v 0 0 1"]
    return "\n".join([first, "v 0 0 0", *rest]) + "\n" + TETRA_FACES


def write_obj(tmp_path, name: str, text: str, mtl: str | None = None):
    path = tmp_path / name
    path.write_text(text)
    if mtl is not None:
        path.with_suffix(".mtl").write_text(mtl)
    return path


@pytest.mark.parametrize(
    ("text", "line"),
    [
        (tetra("v 1e308 0 0", "v -1e308 0 0", "v 0 0 1e308"), 1),  # qhull failed: exit 3
        (tetra("v 1e-300 0 0", "v 1e300 0 0", "v 0 0 1e-300"), 3),  # spanning 1e-300..1e300
        (tetra("v 1e39 0 0"), 1),  # +-inf in float32 positions
        (tetra("v 0 0 0.5", "v 0 2e6 0", "v 0 0 1"), 3),  # 2000 km
    ],
)
def test_coordinates_beyond_the_limit_are_refused_with_their_line(tmp_path, text, line):
    from meshtool.repair.normalise import prepare

    src = write_obj(tmp_path, "far.obj", text)
    with watchdog(), pytest.raises(ObjParseError) as err:
        prepare(src)
    assert (err.value.path, err.value.line, err.value.code) == ("far.obj", line, "coordinate-range")


def test_coordinate_limit_applies_after_units_and_scale(tmp_path):
    from meshtool.repair.normalise import MAX_COORDINATE_M, NormaliseOptions, prepare

    src = write_obj(tmp_path, "mm.obj", tetra("v 2e6 0 0"))  # 2e6 mm = 2 km: fine
    asset = prepare(src, NormaliseOptions(units="mm", up="z"))
    assert asset.mesh.positions[:, 0].max() == pytest.approx(2000.0)
    with pytest.raises(ObjParseError) as err:  # 2 km scaled by 1000 = 2000 km
        prepare(src, NormaliseOptions(units="mm", up="z", scale=1000.0))
    assert err.value.line == 1 and "scale 1000" in err.value.message
    assert f"{MAX_COORDINATE_M:g}" in err.value.message


def test_far_vertex_no_face_uses_is_not_refused(tmp_path):
    from meshtool.repair.normalise import NormaliseOptions, prepare

    src = write_obj(tmp_path, "unused.obj", tetra("v 1 0 0") + "v 1e300 0 0\n")
    asset = prepare(src, NormaliseOptions(up="z"))
    assert np.abs(asset.mesh.positions).max() == 1.0


def test_non_finite_or_huge_texcoords_and_normals_are_dropped_with_findings():
    text = (
        "v 0 0 0\nv 1 0 0\nv 0 1 0\n"
        "vt 0 0\nvt nan 1\nvt 1e39 0\n"
        "vn 0 0 1\nvn 0 0 inf\n"
        "f 1/1/1 2/1/1 3/1/1\nf 1/2/2 2/3/1 3/1/1\n"
    )
    obj = parse_obj(text.encode(), "attr.obj")
    assert obj.corner_vt.tolist() == [0, 0, 0, -1, -1, 0]
    assert obj.corner_vn.tolist() == [0, 0, 0, -1, 0, 0]
    by_code = {f.code: f for f in obj.findings}
    assert by_code["vt-invalid"].line == 5 and by_code["vn-invalid"].line == 8
    mesh, _ = build_mesh(obj)
    assert np.isfinite(mesh.texcoords).all() and np.isfinite(mesh.normals).all()


def test_huge_vertex_colours_become_white():
    obj = parse_obj(b"v 0 0 0 1e39 0 0\nv 1 0 0 0.5 0.5 0.5\nv 0 1 0 0.1 0.2 0.3\nf 1 2 3\n", "c.obj")
    assert obj.colors.tolist() == [[1, 1, 1], [0.5, 0.5, 0.5], [0.1, 0.2, 0.3]]
    assert [f.line for f in obj.findings if f.code == "vertex-colors-invalid"] == [1]


def test_non_finite_mtl_colours_never_reach_the_clean_mtl(tmp_path):
    from meshtool.repair.normalise import NormaliseOptions, normalise

    mtl = "newmtl a\nKd nan inf 0.5\nKs 1_0 0 0\nNs infinity\nillum nan\nKa 0.1 0.2 0.3\n"
    src = write_obj(tmp_path, "kd.obj", "mtllib kd.mtl\nusemtl a\n" + tetra("v 1 0 0"), mtl)
    asset = normalise(src, NormaliseOptions(up="z"))
    text = asset.files["kd.mtl"].decode()
    assert "nan" not in text.lower() and "inf" not in text.lower()
    assert "Kd" not in text and "Ks" not in text and "Ka 0.1 0.2 0.3" in text
    invalid = sorted(f.line for f in asset.findings if f.code == "mtl-statement-invalid")
    assert invalid == [2, 3, 4, 5]


def test_qhull_failure_becomes_a_bounding_box_with_a_warning(monkeypatch):
    from scipy.spatial import QhullError

    from meshtool.hulls import compute as hulls

    points = np.random.default_rng(0).random((40, 3))

    def refuse(*args, **kwargs):
        raise QhullError("QH6421 qhull internal error")

    monkeypatch.setattr(hulls, "_numpy_hull", lambda *_args: None)  # qhull's path (the numpy hull declined)
    monkeypatch.setattr(hulls, "_qhull", refuse)
    vertices, faces, notes = hulls.convex_hull(points, hulls.HullOptions())
    assert notes == ["boxed"] and len(vertices) == 8 and len(faces) == 12
    np.testing.assert_allclose(vertices.min(axis=0), points.min(axis=0))
    np.testing.assert_allclose(vertices.max(axis=0), points.max(axis=0))


@pytest.mark.parametrize("bad", [np.nan, np.inf, 1e308])
def test_hulls_of_unhullable_points_raise_the_package_error(bad):
    from meshtool.errors import MeshtoolError
    from meshtool.hulls.compute import HullOptions, compute_hulls

    obj = parse_obj(f"v {bad} 0 0\nv -1 0 0\nv 0 1 0\nv 0 0 1\n".encode(), "q.obj")
    mesh, _ = build_mesh(obj)  # points only: kept as they are
    mesh.positions = obj.positions
    with pytest.raises(MeshtoolError) as err:
        compute_hulls(mesh, HullOptions(), "q.obj")
    assert err.value.path == "q.obj" and err.value.code == "hull-input"


# ------------------------------------------------------------------------------------------------------
# 5. the CLIs on every attack: exit 1 with one error line naming file:line, or exit 0 with a finding

PAD = "# padding so that the byte lies far beyond the first 64 KiB\n" * 2000

ATTACKS = {
    # name: (OBJ text, MTL text or None, exit code, "file:line" of the error, or a finding code)
    "hang4": (TRIANGLE + cycling_face(10_000), None, 0, "polygon-fanned"),
    "hang5": (TRIANGLE + cycling_face(100_000), None, 1, "hang5.obj:4"),
    "names": (
        "mtllib " + " ".join(f"m{i}.mtl" for i in range(100_000)) + "\n" + tetra("v 1 0 0"),
        None,
        0,
        "mtllib-too-many",
    ),
    "huge": (tetra("v 1e308 0 0", "v -1e308 0 0", "v 0 0 1e308"), None, 1, "huge.obj:1"),
    "span": (tetra("v 1e-300 0 0", "v 1e300 0 0", "v 0 0 1e-300"), None, 1, "span.obj:3"),
    "float32": (tetra("v 1e39 0 0"), None, 1, "float32.obj:1"),
    "underscore": ("v 0 0 0\n" * 10 + "f 1_0 2 3\n", None, 1, "underscore.obj:11"),
    "hexindex": (TRIANGLE + "f 1 2 0x3\n", None, 1, "hexindex.obj:4"),
    "bigindex": (TRIANGLE + "f 1 2 99999999999999999999\n", None, 1, "bigindex.obj:4"),
    "nul": (TRIANGLE + "f 1 2 3\n" + PAD + "g a\x00b\nf 1 2 3\n", None, 1, "nul.obj:2005"),
    "mtlnan": (
        "mtllib mtlnan.mtl\nusemtl a\n" + tetra("v 1 0 0"),
        "newmtl a\nKd nan inf 0.5\n",
        0,
        "mtl-statement-invalid",
    ),
    "attrnan": (
        tetra("v 1 0 0").replace("f 1 2 3", "vt nan 0\nvn 0 0 inf\nf 1/1/1 2/1/1 3/1/1"),
        None,
        0,
        "vt-invalid",
    ),
}


@pytest.mark.parametrize("command", ["normalize", "obj2bin"])
@pytest.mark.parametrize("attack", sorted(ATTACKS))
def test_cli_answers_every_attack_with_one_error_line_or_a_finding(tmp_path, monkeypatch, command, attack):
    from click.testing import CliRunner

    from meshtool.cli.main import main, obj2bin

    text, mtl, code, expected = ATTACKS[attack]
    src = tmp_path / "in" / f"{attack}.obj"
    src.parent.mkdir()
    src.write_text(text)
    if mtl is not None:
        src.with_suffix(".mtl").write_text(mtl)
    monkeypatch.setenv("MESHTOOL_VERBOSE", "1")
    monkeypatch.delenv("MESHTOOL_DEBUG", raising=False)
    if command == "normalize":
        cli, args = main, ["normalize", str(src), "--up", "z", "-o", str(tmp_path / "out")]
    else:
        cli, args = obj2bin, [str(src), "--up", "z", "-o", str(tmp_path / "out.mbin")]
    with watchdog():
        result = CliRunner().invoke(cli, args)
    output = result.output + (result.stderr if result.stderr_bytes is not None else "")
    assert "Traceback" not in output and "internal error" not in output
    assert result.exit_code == code, output[-2000:]
    errors = [line for line in result.stderr.splitlines() if line.startswith("error:")]
    if code == 1:
        assert len(errors) == 1 and errors[0].startswith(f"error: {expected}: "), errors
    else:
        assert errors == [] and f"[{expected}]" in result.stderr
        if attack == "mtlnan" and command == "normalize":
            written = (tmp_path / "out" / "mtlnan" / "mtlnan.mtl").read_text().lower().splitlines()
            assert written[1:] == ["", "newmtl a"]  # the bad Kd dropped: the default colour


def test_installed_commands_on_the_hang_and_the_qhull_attack(tmp_path):
    """The console scripts themselves (not click's runner): exit codes and stderr as a user sees them."""
    bin_dir = Path(sys.executable).parent
    hang = write_obj(tmp_path, "hang.obj", TRIANGLE + cycling_face(10_000))
    huge = write_obj(tmp_path, "huge.obj", tetra("v 1e308 0 0", "v -1e308 0 0", "v 0 0 1e308"))
    env = {k: v for k, v in os.environ.items() if k != "MESHTOOL_DEBUG"}
    runs = [
        ([bin_dir / "meshtool", "normalize", hang, "-o", tmp_path / "out"], 0, None),
        ([bin_dir / "obj2bin", hang, "-o", tmp_path / "hang.mbin"], 0, None),
        ([bin_dir / "meshtool", "normalize", huge, "-o", tmp_path / "out2"], 1, "error: huge.obj:1: "),
        ([bin_dir / "obj2bin", huge, "-o", tmp_path / "huge.mbin"], 1, "error: huge.obj:1: "),
    ]
    for args, code, error in runs:
        done = subprocess.run([str(a) for a in args], capture_output=True, text=True, timeout=120, env=env)
        assert done.returncode == code, done.stderr
        assert "Traceback" not in done.stderr + done.stdout
        errors = [line for line in done.stderr.splitlines() if line.startswith("error:")]
        if error is None:
            assert errors == []
        else:
            assert len(errors) == 1 and errors[0].startswith(error), errors
    assert not (tmp_path / "huge.mbin").exists()
