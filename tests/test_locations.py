"""Where a message points, and what it names: URDF element lines, no line 0, the right format, absolute URIs."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from click.testing import CliRunner

from meshtool.cli.main import main, obj2bin
from meshtool.errors import FormatError, MeshtoolError
from meshtool.findings import Finding, Severity
from meshtool.repair.normalise import NormaliseOptions, prepare
from meshtool.urdf.import_robot import element_lines, import_urdf

FORMATS = Path(__file__).resolve().parent.parent / "fixtures" / "formats"
INERTIAL = '<inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial>'


def _massless_b(declaration: bool) -> str:
    lines = [
        '<?xml version="1.0"?>' if declaration else None,
        '<robot name="r">',
        f'  <link name="a">{INERTIAL}</link>',
        '  <link name="b"/>',
        '  <joint name="j" type="revolute">',
        '    <parent link="a"/><child link="b"/><axis xyz="0 0 1"/>',
        '    <limit lower="-1" upper="1" effort="1" velocity="1"/>',
        "  </joint>",
        "</robot>",
    ]
    return "\n".join(line for line in lines if line is not None) + "\n"


@pytest.mark.parametrize(("declaration", "line"), [(True, 4), (False, 3)])
def test_mujoco_refusal_names_the_urdf_line_of_the_link(tmp_path: Path, declaration: bool, line: int) -> None:
    urdf = tmp_path / "bad.urdf"
    urdf.write_text(_massless_b(declaration))
    assert urdf.read_text().splitlines()[line - 1].strip() == '<link name="b"/>'  # the file's own numbering
    result = CliRunner().invoke(main, ["urdf", str(urdf), "-o", str(tmp_path / "out")])
    assert result.exit_code == 1
    (error,) = result.stderr.strip().splitlines()
    assert error.startswith(f"error: {urdf}:{line}: MuJoCo refuses the model: ") and "(element 'b')" in error


def test_a_joint_error_names_the_joint_line_not_an_earlier_name_that_contains_it(tmp_path: Path) -> None:
    text = (
        '<robot name="r">\n'  # 1
        f'  <link name="arm_base">{INERTIAL}</link>\n'  # 2: holds the text "arm" first
        f'  <link name="arm_tip">{INERTIAL}</link>\n'  # 3
        '  <joint name="arm" type="revolute">\n'  # 4
        '    <parent link="arm_base"/><child link="arm_tip"/><axis xyz="0 0 0"/>\n'
        '    <limit lower="-1" upper="1" effort="1" velocity="1"/>\n'
        "  </joint>\n"
        '  <transmission name="t"><joint name="arm"/></transmission>\n'
        "</robot>\n"
    )
    urdf = tmp_path / "arm.urdf"
    urdf.write_text(text)
    lines = element_lines(text.encode())
    assert lines[("joint", "arm")] == 4 and lines[("link", "arm_base")] == 2 and lines[("link", "arm_tip")] == 3
    with pytest.raises(MeshtoolError) as caught:
        import_urdf(urdf)
    assert "zero axis" in caught.value.message and caught.value.line == 4


def test_a_finding_or_error_without_a_line_shows_none(tmp_path: Path) -> None:
    assert Finding("x", Severity.WARNING, "m", "tex.dae", 0).where == "tex.dae"
    assert Finding("x", Severity.WARNING, "m", "a.obj", 3).where == "a.obj:3"
    assert str(FormatError("bad", path="tex.dae", line=0)).startswith("tex.dae: bad")
    src = tmp_path / "tex.dae"  # the COLLADA fixture without its textures/ folder: the texture is missing
    shutil.copy(FORMATS / "dae" / "cm_zup" / "link_cm_zup.dae", src)
    result = CliRunner().invoke(obj2bin, [str(src), "-o", str(tmp_path / "t.mbin"), "--no-check", "--json"])
    assert result.exit_code == 0, result.output
    (missing,) = [f for f in json.loads(result.stdout)["findings"] if f["code"] == "texture-missing"]
    assert missing["path"] == "tex.dae" and missing["line"] is None
    text = CliRunner().invoke(obj2bin, [str(src), "-o", str(tmp_path / "t.mbin"), "--no-check"])
    assert "warning: tex.dae: texture 'textures/paint.png' not found [texture-missing]" in text.stderr
    assert "tex.dae:0" not in text.stderr


def test_ply_up_axis_default_names_ply() -> None:
    asset = prepare(FORMATS / "ply" / "colored_big_endian.ply", NormaliseOptions())
    (up,) = [f for f in asset.findings if f.code == "up-axis"]
    assert up.message.endswith("no evidence of the frame: PLY defines no up axis; Y-up assumed, as for OBJ")
    assert "OBJ convention" not in up.message


def test_gltf_buffer_at_an_absolute_uri_is_refused_as_outside_the_root(tmp_path: Path) -> None:
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    shutil.copy(FORMATS / "gltf" / "external" / "cube.bin", outside / "far.bin")
    tree = json.loads((FORMATS / "gltf" / "external" / "cube.gltf").read_text())
    tree["buffers"][0]["uri"] = (outside / "far.bin").as_uri()  # file:///.../elsewhere/far.bin
    for key in ("images", "textures", "samplers"):
        tree.pop(key, None)
    for material in tree.get("materials", []):
        material.get("pbrMetallicRoughness", {}).pop("baseColorTexture", None)
    asset = tmp_path / "asset"
    asset.mkdir()
    (asset / "abs.gltf").write_text(json.dumps(tree))
    result = CliRunner().invoke(obj2bin, [str(asset / "abs.gltf"), "-o", str(tmp_path / "a.mbin"), "--no-check"])
    assert result.exit_code == 1
    (error,) = result.stderr.strip().splitlines()
    assert f"buffer 0 '{(outside / 'far.bin').as_uri()}' is an absolute URI outside the asset's root" in error
    assert "was not found" not in error and "--search-path" in error
    allowed = [str(asset / "abs.gltf"), "-o", str(tmp_path / "a.mbin"), "--no-check", "--search-path", str(outside)]
    assert CliRunner().invoke(obj2bin, allowed).exit_code == 0  # what the hint says works
