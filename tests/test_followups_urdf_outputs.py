"""``meshtool urdf -o DIR`` never destroys a file meshtool did not write (issue 21 item 3, the URDF importer).

Before the first file is written every output is checked: the user's ``NAME.xml``, PNG or ``.obj`` mesh is
refused (exit 1, the file intact, nothing written) unless ``--force``; a source is refused even then; the
files of a previous import (the XML's stamp lists them with their SHA-256) are replaced, unless the user
changed them since.
"""

from __future__ import annotations

import os
from pathlib import Path

import mujoco
from click.testing import CliRunner, Result

from meshtool.cli.main import main
from meshtool.files.outdir import GENERATORS
from meshtool.mjcf.model_desc import stamped_files

PKG = Path(__file__).resolve().parent.parent / "fixtures" / "urdf" / "tiny_arm_description"
ARM = PKG / "urdf" / "tiny_arm.urdf"


def _urdf(out: Path, *extra: str) -> Result:
    return CliRunner().invoke(main, ["urdf", str(ARM), "-o", str(out), *extra])


def _error_lines(result: Result) -> list[str]:
    return [line for line in result.output.splitlines() if line.startswith("error:")]


def test_the_xml_lists_what_it_was_written_with(tmp_path: Path) -> None:
    assert _urdf(tmp_path).exit_code == 0
    listed = stamped_files((tmp_path / "tiny_arm.xml").read_bytes(), GENERATORS)
    assert listed is not None
    on_disk = {p.name for p in tmp_path.iterdir() if p.is_file() and p.name != "tiny_arm.xml"}
    assert set(listed) == on_disk and on_disk  # the .obj meshes and PNG textures beside it
    assert mujoco.MjModel.from_xml_path(str(tmp_path / "tiny_arm.xml")).nbody > 1  # the comment is harmless


def test_a_user_xml_is_refused_and_nothing_is_written(tmp_path: Path) -> None:
    mine = tmp_path / "tiny_arm.xml"
    mine.write_text("<mujoco model='mine'/>\n")
    result = _urdf(tmp_path)
    assert result.exit_code == 1, result.output
    (line,) = _error_lines(result)
    assert "tiny_arm.xml" in line and "not replacing it" in line and "--force" in line
    assert mine.read_text() == "<mujoco model='mine'/>\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tiny_arm.xml"]
    forced = _urdf(tmp_path, "--force")
    assert forced.exit_code == 0, forced.output
    assert stamped_files(mine.read_bytes(), GENERATORS) is not None


def test_a_user_png_with_an_output_name_is_refused(tmp_path: Path) -> None:
    assert _urdf(tmp_path / "first").exit_code == 0
    png = next(p.name for p in (tmp_path / "first").iterdir() if p.suffix == ".png")
    out = tmp_path / "out"
    out.mkdir()
    (out / png).write_bytes(b"my own picture")
    result = _urdf(out)
    assert result.exit_code == 1 and png in _error_lines(result)[0]
    assert (out / png).read_bytes() == b"my own picture"
    assert sorted(p.name for p in out.iterdir()) == [png]


def test_a_user_file_where_a_mesh_goes_is_refused(tmp_path: Path) -> None:
    (tmp_path / "meshes").mkdir()
    (tmp_path / "meshes" / "base.mbin").write_bytes(b"notes, not a pack")
    result = _urdf(tmp_path)
    assert result.exit_code == 1 and "base.mbin" in _error_lines(result)[0]
    assert (tmp_path / "meshes" / "base.mbin").read_bytes() == b"notes, not a pack"


def test_a_previous_import_is_replaced_also_when_the_model_changes(tmp_path: Path) -> None:
    assert _urdf(tmp_path).exit_code == 0
    before = (tmp_path / "tiny_arm.xml").read_bytes()
    again = _urdf(tmp_path)
    assert again.exit_code == 0, again.output
    assert (tmp_path / "tiny_arm.xml").read_bytes() == before  # deterministic
    changed = _urdf(tmp_path, "--actuators")  # another XML: replaced because meshtool wrote the old one
    assert changed.exit_code == 0, changed.output
    assert (tmp_path / "tiny_arm.xml").read_bytes() != before
    assert mujoco.MjModel.from_xml_path(str(tmp_path / "tiny_arm.xml")).nu > 0


def test_an_output_file_the_user_edited_since_is_refused(tmp_path: Path) -> None:
    assert _urdf(tmp_path).exit_code == 0
    png = next(p for p in tmp_path.iterdir() if p.suffix == ".png")
    png.write_bytes(png.read_bytes() + b"edited")
    result = _urdf(tmp_path, "--actuators")
    assert result.exit_code == 1 and png.name in _error_lines(result)[0]
    assert png.read_bytes().endswith(b"edited")


def test_a_source_is_never_replaced_even_with_force(tmp_path: Path) -> None:
    assert _urdf(tmp_path / "first").exit_code == 0
    png = next(p.name for p in (tmp_path / "first").iterdir() if p.suffix == ".png")
    out = tmp_path / "out"
    out.mkdir()
    texture = PKG / "textures" / "base.jpg"
    original = texture.read_bytes()
    os.symlink(texture, out / png)  # the output name leads to the robot's own texture
    result = _urdf(out, "--force")
    assert result.exit_code == 1, result.output
    assert "is an input" in _error_lines(result)[0]
    assert texture.read_bytes() == original and (out / png).is_symlink()
