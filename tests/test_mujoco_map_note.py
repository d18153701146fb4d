"""MuJoCo ignores normal and bump maps: obj2bin, meshtool mjcf and meshtool urdf say so once, as a note."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from click.testing import CliRunner

from meshtool.cli.main import main, obj2bin

FIXTURES = Path(__file__).resolve().parent.parent / "fixtures"
TILE = FIXTURES / "realworld" / "normal_maps"  # norm, map_Bump, map_Disp, map_Pr and a colour map
CODE = "[mujoco-ignores-map]"


def notes(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if CODE in line]


def test_obj2bin_says_once_that_mujoco_ignores_the_normal_and_bump_maps(tmp_path: Path) -> None:
    out = tmp_path / "tile.mbin"
    args = [str(TILE / "tile.obj"), "-o", str(out), "--no-check", "--strict", "--up", "y"]  # no guessed rotation
    result = CliRunner().invoke(obj2bin, args)
    assert result.exit_code == 0, result.output  # a note, not a warning: --strict passes
    (line,) = notes(result.stderr)
    assert line.startswith("note: tile.obj: MuJoCo ignores normal and bump maps: ")
    assert "tile_normal.png (normal map of 'tile')" in line and "tile_bump.png (bump map of 'tile')" in line
    assert "tile_albedo.png" not in line  # the colour map is what MuJoCo shows
    as_json = CliRunner().invoke(obj2bin, [str(TILE / "tile.obj"), "-o", str(out), "--no-check", "--json"])
    found = [f for f in json.loads(as_json.stdout)["findings"] if f["code"] == "mujoco-ignores-map"]
    assert [f["severity"] for f in found] == ["info"]


def test_a_folder_gets_one_note_for_all_its_assets(tmp_path: Path) -> None:
    src = tmp_path / "src"
    for name in ("a", "b"):
        shutil.copytree(TILE, src / name)
    result = CliRunner().invoke(obj2bin, [str(src), "-o", str(tmp_path / "out"), "--no-check"])
    assert result.exit_code == 0, result.output
    (line,) = notes(result.stderr)
    assert line.endswith(f"(and in 1 more file(s)) {CODE}")


def test_mjcf_of_a_pack_with_a_normal_map_says_so_once(tmp_path: Path) -> None:
    pack = tmp_path / "tile.mbin"
    assert CliRunner().invoke(obj2bin, [str(TILE / "tile.obj"), "-o", str(pack), "--no-check"]).exit_code == 0
    result = CliRunner().invoke(main, ["mjcf", str(pack), "-o", str(tmp_path / "mjcf")])
    assert result.exit_code == 0, result.output
    (line,) = notes(result.stderr)
    assert line.startswith("note: tile.mbin: MuJoCo ignores normal and bump maps: ")


def test_urdf_with_a_normal_mapped_mesh_says_so_once(tmp_path: Path) -> None:
    shutil.copytree(TILE, tmp_path / "robot" / "meshes")
    link = '<link name="{0}"><visual><geometry><mesh filename="meshes/tile.obj"/></geometry></visual>'
    link += '<inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial></link>'
    joint = '<joint name="j" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/>'
    joint += '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>'
    urdf = tmp_path / "robot" / "r.urdf"
    urdf.write_text(f'<robot name="r">{link.format("a")}{link.format("b")}{joint}</robot>\n')
    result = CliRunner().invoke(main, ["urdf", str(urdf), "-o", str(tmp_path / "out")])
    assert result.exit_code == 0, result.output
    (line,) = notes(result.stderr)
    assert "tile_normal.png (normal map of 'tile')" in line


def test_no_note_without_normal_or_bump_maps(tmp_path: Path) -> None:
    src = FIXTURES / "realworld" / "meshlab_tr" / "fuze.obj"  # a colour map only
    result = CliRunner().invoke(obj2bin, [str(src), "-o", str(tmp_path / "fuze.mbin"), "--no-check"])
    assert result.exit_code == 0, result.output
    assert notes(result.stderr) == []
