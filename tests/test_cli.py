import json
import shutil
from pathlib import Path

import pytest
from click.testing import CliRunner
from PIL import Image

from meshtool.cli.main import main

HEAD = str(Path("head") / "Head 1.obj")


@pytest.fixture
def run():
    runner = CliRunner()

    def invoke(*args):
        return runner.invoke(main, [str(a) for a in args], catch_exceptions=False)

    return invoke


def test_normalize_text_output(run, fixtures, tmp_path):
    result = run("normalize", fixtures / HEAD, "-o", tmp_path, "--units", "cm")
    assert result.exit_code == 0
    assert result.stdout == (
        f"wrote {tmp_path / 'head_1'}: 61 vertices, 80 triangles, 1 material(s), 1 texture(s), "
        "extent 0.16 x 0.2 x 0.24 m\n"
    )
    assert result.stderr == (
        "warning: Head 1.obj: up axis y (rotated +90 degrees about X to Z-up): exported by 3ds Max, whose OBJ "
        "export is Y-up by default [up-axis]\nnote: 3 more note(s) on how the input was read (-v shows them)\n"
    )
    assert sorted(p.name for p in (tmp_path / "head_1").iterdir()) == [
        "asset.json",
        "head_1.mtl",
        "head_1.obj",
        "head_1.png",
    ]


def test_warnings_go_to_stderr(run, fixtures, tmp_path):
    result = run("normalize", fixtures / HEAD, "-o", tmp_path)
    assert result.exit_code == 0
    assert result.stderr.strip() == (
        "warning: Head 1.obj: up axis y (rotated +90 degrees about X to Z-up): exported by 3ds Max, whose OBJ "
        "export is Y-up by default [up-axis]\nwarning: Head 1.obj: 24.0 m tall: if it was modelled in "
        "centimetres, pass --units cm (0.24 m) [scale-suspicious]\n"
        "note: 3 more note(s) on how the input was read (-v shows them)"
    )


def test_json_output(run, fixtures, tmp_path):
    result = run(
        "normalize",
        fixtures / "missing_texture" / "panel.obj",
        "-o",
        tmp_path,
        "--json",
        "--name",
        "My Panel",
        "--up",
        "y",
    )
    assert result.exit_code == 0
    report = json.loads(result.stdout)
    assert set(report) == {"status", "output", "findings", "stats"}
    assert report["status"] == "ok" and report["output"] == str(tmp_path / "my_panel")
    assert report["stats"]["triangles"] == 2 and report["stats"]["textures"] == 0
    assert report["stats"]["bbox"]["extent"] == [1.0, 0.0, 1.0]
    (missing,) = [f for f in report["findings"] if f["code"] == "texture-missing"]
    assert missing == {
        "code": "texture-missing",
        "severity": "warning",
        "message": "texture 'brushed.png' not found",
        "path": "panel.mtl",
        "line": 3,
    }


@pytest.mark.parametrize(
    ("case", "line"),
    [
        (
            "bad_index/bad.obj",
            "error: bad.obj:5: face refers to vertex 7 but the file defines 3 (the file is truncated or corrupt)",
        ),
        (
            "garbage/garbage.obj",
            "error: garbage.obj: byte 6: binary data, not a text file "
            "(pass a text OBJ/MTL file; binary formats are not OBJ)",
        ),
        ("empty/empty.obj", "error: empty.obj: empty OBJ file, no geometry: no statements (export the mesh again)"),
        ("nope/missing.obj", None),
    ],
)
def test_input_errors_exit_1_with_one_line(run, fixtures, tmp_path, case, line):
    result = run("normalize", fixtures / case, "-o", tmp_path / "out")
    assert result.exit_code == 1
    assert result.stdout == ""
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ")
    if line:
        assert lines[0] == line
    assert "Traceback" not in result.stderr
    assert not (tmp_path / "out").exists()


def test_json_error(run, fixtures, tmp_path):
    result = run("normalize", fixtures / "nan" / "nan.obj", "-o", tmp_path, "--json")
    assert result.exit_code == 1
    report = json.loads(result.stdout)
    assert report["status"] == "error" and report["output"] is None
    assert report["error"]["type"] == "ObjParseError" and report["error"]["line"] == 2


def test_strict(run, fixtures, tmp_path):
    result = run("normalize", fixtures / "missing_mtl" / "box.obj", "-o", tmp_path, "--strict")
    assert result.exit_code == 1
    assert result.stderr == (
        "error: box.obj: 3 warning(s) in strict mode, first: warning: box.obj:1: mtl 'gone.mtl' not found "
        "[mtl-missing] (fix the input or drop --strict)\n"
    )
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "args",
    [["normalize"], ["normalize", "x.obj"], ["normalize", "x.obj", "-o", "o", "--units", "furlong"], ["frobnicate"]],
)
def test_usage_errors_exit_2(run, args):
    assert run(*args).exit_code == 2


def test_bad_option_value_is_exit_1(run, fixtures, tmp_path):
    result = run("normalize", fixtures / HEAD, "-o", tmp_path, "--scale", "-1")
    assert result.exit_code == 1
    assert result.stderr == "error: scale must be a positive finite number, got -1.0\n"


def test_search_path_lets_references_leave_the_asset_folder(run, fixtures, tmp_path):
    asset = tmp_path / "asset"
    shared = tmp_path / "shared"
    asset.mkdir()
    shared.mkdir()
    shutil.copy(fixtures / "case_mismatch" / "textures" / "wood.png", shared / "wood.png")
    (asset / "m.obj").write_text("mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl w\nf 1 2 3\n")
    (asset / "m.mtl").write_text("newmtl w\nmap_Kd ../shared/wood.png\n")
    refused = json.loads(run("normalize", asset / "m.obj", "-o", tmp_path / "a", "--json").stdout)
    assert refused["stats"]["textures"] == 0
    codes = [f["code"] for f in refused["findings"] if f["code"] in ("reference-outside-root", "texture-missing")]
    assert codes == ["reference-outside-root", "texture-missing"]
    allowed = run("normalize", asset / "m.obj", "-o", tmp_path / "b", "--json", "--search-path", shared)
    report = json.loads(allowed.stdout)
    assert report["stats"]["textures"] == 1
    written, source = (Image.open(p) for p in (tmp_path / "b" / "m" / "wood.png", shared / "wood.png"))
    assert written.tobytes() == source.tobytes()  # same pixels; the PNG gains an sRGB chunk (a colour map)
    assert written.info.get("srgb") == 0
