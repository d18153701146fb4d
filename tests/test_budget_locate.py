"""In-process contracts of the expansion budget and the URDF mesh locator (issue 27).

The hostile-file tests run the command line in a child process; these call the two modules directly, with
every message, hint, location and boundary spelled out, so that a change to either is seen (mutation testing,
docs/testing.md).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from meshtool.errors import FormatError
from meshtool.read import budget
from meshtool.read.budget import ExpansionBudget, limit_from_env
from meshtool.urdf.locate import MeshLocator, UrdfError

WHERE = {"path": "r.urdf", "line": 7}


# -- the budget -------------------------------------------------------------------------------------------


def test_charges_add_up_and_refuse_only_past_the_limit() -> None:
    spent = ExpansionBudget("m.gltf", max_triangles=10, max_vertices=30)
    spent.charge(4, 12, "node 0")
    spent.charge(6, 18, "node 1")  # exactly at both limits: still allowed
    assert (spent.triangles, spent.vertices) == (10, 30)
    spent.charge(-5, -7, "nothing")  # negative counts add nothing
    assert (spent.triangles, spent.vertices) == (10, 30)
    with pytest.raises(FormatError) as info:
        spent.charge(1, 0, "node 2", offset=96)
    error = info.value
    assert error.message == "expands to more than 10 triangles (at least 11 with node 2); not read"
    assert (error.path, error.offset, error.code) == ("m.gltf", 96, "expansion-limit")
    assert error.hint == "check the file; for a genuine mesh this large set MESHTOOL_MAX_TRIANGLES"


def test_vertices_are_refused_on_their_own() -> None:
    spent = ExpansionBudget("m.dae", max_triangles=100, max_vertices=5)
    with pytest.raises(FormatError) as info:
        spent.charge(1, 6, "node 'arm'")
    assert info.value.message == "expands to more than 5 vertices (at least 6 with node 'arm'); not read"
    assert info.value.hint == "check the file; for a genuine mesh this large set MESHTOOL_MAX_VERTICES"
    assert info.value.offset is None


def test_large_numbers_are_written_with_thousands_separators() -> None:
    with pytest.raises(FormatError, match=r"more than 1,000,000 triangles \(at least 2,000,000 with x\)"):
        ExpansionBudget("m", 1_000_000, 10**9).charge(2_000_000, 0, "x")


def test_limits_come_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(budget.TRIANGLES_ENV, raising=False)
    monkeypatch.delenv(budget.VERTICES_ENV, raising=False)
    fresh = ExpansionBudget.for_file("a.glb")
    assert (fresh.path, fresh.max_triangles, fresh.max_vertices) == ("a.glb", 1 << 24, 3 << 24)
    assert (fresh.triangles, fresh.vertices) == (0, 0)
    monkeypatch.setenv(budget.TRIANGLES_ENV, " 12 ")
    monkeypatch.setenv(budget.VERTICES_ENV, "34")
    assert (ExpansionBudget.for_file("a").max_triangles, ExpansionBudget.for_file("a").max_vertices) == (12, 34)


@pytest.mark.parametrize("text", ["0", "-3", "many", "1.5", "\u0663", "1e6"])
def test_a_limit_that_is_not_a_positive_whole_number_is_refused(monkeypatch: pytest.MonkeyPatch, text: str) -> None:
    monkeypatch.setenv("SOME_LIMIT", text)
    with pytest.raises(FormatError) as info:
        limit_from_env("SOME_LIMIT", 7)
    assert info.value.message == f"environment variable SOME_LIMIT={text!r} is not a positive whole number"
    assert info.value.hint == "unset SOME_LIMIT or fix it"


@pytest.mark.parametrize(("text", "value"), [(None, 7), ("", 7), ("   ", 7), ("1", 1), ("0042", 42)])
def test_an_unset_or_blank_limit_is_the_default(monkeypatch: pytest.MonkeyPatch, text: str | None, value: int) -> None:
    if text is None:
        monkeypatch.delenv("SOME_LIMIT", raising=False)
    else:
        monkeypatch.setenv("SOME_LIMIT", text)
    assert limit_from_env("SOME_LIMIT", 7) == value


# -- the locator ------------------------------------------------------------------------------------------


def _package(root: Path, name: str = "robot", xml_name: str | None = None) -> Path:
    """``root/NAME/urdf/r.urdf`` and ``meshes/part.stl`` (bytes b"part"); the URDF's path."""
    (root / name / "meshes").mkdir(parents=True)
    (root / name / "meshes" / "part.stl").write_bytes(b"part")
    (root / name / "urdf").mkdir()
    urdf = root / name / "urdf" / "r.urdf"
    urdf.write_text("<robot/>")
    if xml_name is not None:
        (root / name / "package.xml").write_text(f"<package><name>{xml_name}</name></package>")
    return urdf


def test_the_robots_own_package_answers_to_its_folder_name(tmp_path: Path) -> None:
    urdf = _package(tmp_path)
    found = MeshLocator(urdf, {}).read("package://robot/meshes/part.stl", WHERE)
    assert found.data == b"part"
    assert found.path == (tmp_path / "robot" / "meshes" / "part.stl").resolve()
    assert found.root == (tmp_path / "robot").resolve()
    same = MeshLocator(urdf, {}).read(" package://robot//meshes/./part.stl ", WHERE)  # spaces, empty and . parts
    assert same.path == found.path


def test_package_xml_names_the_package_too(tmp_path: Path) -> None:
    urdf = _package(tmp_path, "robot-main", xml_name="robot_description")
    locator = MeshLocator(urdf, {})
    assert locator.own_names == {"robot-main", "robot_description"}
    assert locator.read("package://robot_description/meshes/part.stl", WHERE).data == b"part"


def test_an_empty_package_name_is_the_own_package_unless_mapped(tmp_path: Path) -> None:
    urdf = _package(tmp_path)
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "part.stl").write_bytes(b"other")
    assert MeshLocator(urdf, {}).read("package:///meshes/part.stl", WHERE).data == b"part"
    mapped = MeshLocator(urdf, {"": tmp_path / "other"}).read("package:///part.stl", WHERE)
    assert mapped.data == b"other" and mapped.root == (tmp_path / "other").resolve()


def test_another_package_needs_a_mapping_or_the_wide_search(tmp_path: Path) -> None:
    urdf = _package(tmp_path)
    (tmp_path / "shared_meshes").mkdir()
    (tmp_path / "shared_meshes" / "m.stl").write_bytes(b"shared")
    with pytest.raises(UrdfError) as info:
        MeshLocator(urdf, {}).read("package://shared_meshes/m.stl", WHERE)
    own = (tmp_path / "robot").resolve()
    assert info.value.message == (
        f"package 'shared_meshes' of mesh 'package://shared_meshes/m.stl' not found: it is not the robot's own "
        f"package {own}"
    )
    assert (
        info.value.hint
        == "pass --package-dir shared_meshes=FOLDER (or --package-search to look above the robot's folder)"
    )
    assert (info.value.path, info.value.line) == ("r.urdf", 7)
    searched = MeshLocator(urdf, {}, package_search=True).read("package://shared_meshes/m.stl", WHERE)
    assert searched.data == b"shared"
    with pytest.raises(UrdfError) as again:
        MeshLocator(urdf, {}, package_search=True).read("package://nowhere/m.stl", WHERE)
    assert again.value.hint == "pass --package-dir nowhere=FOLDER"
    mapped = MeshLocator(urdf, {"shared_meshes": tmp_path / "shared_meshes"})
    assert mapped.read("package://shared_meshes/m.stl", WHERE).data == b"shared"


@pytest.mark.parametrize("name", [".", "..", "a\\b"])
def test_a_package_name_that_is_not_a_folder_name_is_refused(tmp_path: Path, name: str) -> None:
    urdf = _package(tmp_path)
    with pytest.raises(UrdfError) as info:
        MeshLocator(urdf, {}).read(f"package://{name}/part.stl", WHERE)
    ref = f"package://{name}/part.stl"
    assert info.value.message == f"mesh {ref!r}: {name!r} is not a package name"
    assert info.value.hint == "name a ROS package" and info.value.line == 7


def test_dotdot_in_a_package_path_is_refused(tmp_path: Path) -> None:
    urdf = _package(tmp_path)
    with pytest.raises(UrdfError) as info:
        MeshLocator(urdf, {}).read("package://robot/meshes/../meshes/part.stl", WHERE)
    assert info.value.message == "mesh 'package://robot/meshes/../meshes/part.stl' climbs out of its package with '..'"
    assert info.value.hint == ("name the file from the package's top folder, or map another package with --package-dir")


def test_relative_and_file_paths_stay_in_the_package_unless_allowed(tmp_path: Path) -> None:
    urdf = _package(tmp_path)
    (tmp_path / "outside.stl").write_bytes(b"outside")
    assert MeshLocator(urdf, {}).read("../meshes/part.stl", WHERE).data == b"part"
    absolute = str((tmp_path / "robot" / "meshes" / "part.stl").resolve())
    assert MeshLocator(urdf, {}).read(f"file://{absolute}", WHERE).data == b"part"
    with pytest.raises(UrdfError) as info:
        MeshLocator(urdf, {}).read("../../outside.stl", WHERE)
    assert (
        info.value.message == f"mesh '../../outside.stl' is outside the robot's folder {(tmp_path / 'robot').resolve()}"
    )
    assert info.value.hint == "move it into the package, or pass --allow-outside"
    allowed = MeshLocator(urdf, {}, allow_outside=True).read("../../outside.stl", WHERE)
    assert allowed.data == b"outside" and allowed.root == tmp_path.resolve()
    inside = MeshLocator(urdf, {}, allow_outside=True).read("../meshes/part.stl", WHERE)
    assert inside.root == (tmp_path / "robot").resolve()  # inside: the package stays the root


def test_missing_and_unsupported_meshes(tmp_path: Path) -> None:
    urdf = _package(tmp_path)
    with pytest.raises(UrdfError) as info:
        MeshLocator(urdf, {}).read("package://robot/meshes/gone.stl", WHERE)
    gone = (tmp_path / "robot" / "meshes" / "gone.stl").resolve()
    assert info.value.message == f"mesh 'package://robot/meshes/gone.stl' not found (looked for {gone})"
    (tmp_path / "robot" / "meshes" / "part.off").write_bytes(b"OFF")
    with pytest.raises(UrdfError, match=r"mesh 'package://robot/meshes/part.off': unsupported type '\.off'"):
        MeshLocator(urdf, {}).read("package://robot/meshes/part.off", WHERE)
    (tmp_path / "robot" / "meshes" / "dir.stl").mkdir()
    with pytest.raises(UrdfError) as folder:
        MeshLocator(urdf, {}).read("package://robot/meshes/dir.stl", WHERE)
    assert folder.value.message.startswith("mesh 'package://robot/meshes/dir.stl' ")
    assert "folder" in folder.value.message and folder.value.line == 7


def test_the_own_package_is_the_urdf_folders_parent_only_for_urdf_folders(tmp_path: Path) -> None:
    (tmp_path / "a" / "description").mkdir(parents=True)
    urdf = tmp_path / "a" / "description" / "r.urdf"
    urdf.write_text("<robot/>")
    locator = MeshLocator(urdf, {})
    assert locator.own == (tmp_path / "a" / "description").resolve() and locator.own_names == {"description"}
    for folder in ("urdf", "robots", "xacro"):
        (tmp_path / "b" / folder).mkdir(parents=True)
        inner = tmp_path / "b" / folder / "r.urdf"
        inner.write_text("<robot/>")
        assert MeshLocator(inner, {}).own == (tmp_path / "b").resolve()
