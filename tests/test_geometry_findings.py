"""Findings that change geometry are warnings shown by default; ``--up auto`` reaches a deep model root (issue 31).

The fixture is laid out like alex_description: ``package.xml`` four folders above the mesh, the URDF that
names it (scale 0.001) in the sibling ``urdf/`` folder. Ground truth: trimesh reading the same OBJ, and the
URDF's own scale.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh
from click.testing import CliRunner

from meshtool.cli.main import main
from meshtool.frame.modelroot import MAX_LEVELS, find_model_root
from meshtool.repair.normalise import NormaliseOptions, prepare
from meshtool.validate.config import Limits
from meshtool.validate.task import AssetTask, check_asset

PACKAGE = Path(__file__).resolve().parent.parent / "fixtures" / "realworld" / "ros_deep" / "alex_like_description"
LINK = PACKAGE / "meshes" / "robot" / "visual" / "high" / "link.obj"


def _bounds(positions: np.ndarray) -> np.ndarray:
    return np.array([positions.min(axis=0), positions.max(axis=0)])


def test_the_fixture_is_deeper_than_the_old_reach() -> None:
    """package.xml is four folders above the mesh's folder: the three-level search missed it."""
    assert len(LINK.parent.relative_to(PACKAGE).parts) == 4 > MAX_LEVELS
    root = find_model_root(LINK.parent)
    assert root is not None and root.folder == PACKAGE.resolve() and root.marker == "package.xml"


def test_up_auto_finds_the_urdf_in_the_sibling_folder_and_keeps_z_up() -> None:
    asset = prepare(LINK, NormaliseOptions(units="auto"))
    (up,) = [f for f in asset.findings if f.code == "up-axis"]
    assert up.severity.value == "info" and "kept as it is" in up.message and "alex_like.urdf" in up.message
    reference = trimesh.load(LINK, force="mesh")
    # not turned: the URDF uses the mesh as it is; millimetres from the URDF's scale 0.001
    np.testing.assert_allclose(_bounds(asset.mesh.positions), reference.bounds * 0.001, atol=1e-9)


def test_a_units_auto_scale_is_a_warning_shown_by_default(tmp_path: Path) -> None:
    result = CliRunner().invoke(main, ["normalize", str(LINK), "-o", str(tmp_path), "--units", "auto"])
    assert result.exit_code == 0, result.output
    (line,) = [x for x in result.stderr.splitlines() if "[units-evidence]" in x]
    assert line.startswith("warning: link.obj: --units auto: every vertex scaled as mm from ")
    assert "urdf/alex_like.urdf (URDF, scale 0.001 0.001 0.001)" in line
    assert "changed nothing" not in result.stderr
    strict = CliRunner().invoke(
        main, ["normalize", str(LINK), "-o", str(tmp_path / "s"), "--units", "auto", "--strict"]
    )
    assert strict.exit_code == 1 and "[units-evidence]" in strict.stderr
    said = CliRunner().invoke(main, ["normalize", str(LINK), "-o", str(tmp_path / "m"), "--units", "mm", "--strict"])
    assert said.exit_code == 0, said.stderr  # the unit said on the command line: nothing guessed


def test_an_up_axis_rotation_is_a_warning_shown_by_default(tmp_path: Path) -> None:
    """The same mesh (its header comment dropped) outside its package: no evidence, read as Y-up and turned."""
    alone = tmp_path / "alone" / "link.obj"
    alone.parent.mkdir()
    alone.write_text("".join(x for x in LINK.read_text().splitlines(keepends=True) if not x.startswith("#")))
    result = CliRunner().invoke(main, ["normalize", str(alone), "-o", str(tmp_path / "out"), "--units", "mm"])
    assert result.exit_code == 0
    lines = result.stderr.splitlines()
    assert "warning: link.obj: up axis y (rotated +90 degrees about X to Z-up): no evidence of the frame" in lines[0]
    asset = prepare(alone, NormaliseOptions(units="mm"))
    reference = trimesh.load(alone, force="mesh").bounds * 0.001
    turned = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])  # (x, y, z) -> (x, -z, y)
    corners = np.array([[x, y, z] for x in reference[:, 0] for y in reference[:, 1] for z in reference[:, 2]])
    np.testing.assert_allclose(_bounds(asset.mesh.positions), _bounds(corners @ turned.T), atol=1e-9)
    forced = CliRunner().invoke(
        main, ["normalize", str(alone), "-o", str(tmp_path / "f"), "--units", "mm", "--up", "y"]
    )
    assert forced.exit_code == 0 and "[up-axis]" not in forced.stderr  # said on the command line: not a guess


@pytest.fixture
def one_triangle(tmp_path: Path) -> Path:
    path = tmp_path / "tri.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    return path


def test_padding_is_a_warning_shown_by_default(one_triangle: Path, tmp_path: Path) -> None:
    result = CliRunner().invoke(main, ["normalize", str(one_triangle), "-o", str(tmp_path / "o"), "--up", "z"])
    assert result.exit_code == 0
    assert "warning: tri.obj: part 'default' (material 'default') has fewer than 4 distinct vertices: padded" in (
        result.stderr
    )


def test_geometry_findings_of_a_one_triangle_obj_explain_the_padding_edges(one_triangle: Path) -> None:
    """validate used to report the sliver's edges (G005, G007: 4 boundary edges) without saying why."""
    result = check_asset(AssetTask(one_triangle, "tri.obj", Limits()))
    codes = {f.code: f for f in result.findings}
    assert "G012" in codes and "padded with a sliver triangle" in codes["G012"].message
    assert codes["G012"].severity.value == "warning"
    # the triangle the user wrote has 3 boundary edges; the 4th and the winding clash are the sliver's
    assert "4 boundary edges" in codes["G007"].message
