"""``meshtool validate -o``: the report never replaces an input, nor a file that is not an earlier report."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from click.testing import CliRunner

from meshtool.cli.main import main
from meshtool.validate.reports import FORMATS, is_report

SOURCE = Path(__file__).resolve().parent.parent / "fixtures" / "validate" / "_sources" / "box.obj"
WARNED = SOURCE.with_name("cubes.obj")  # a C003 warning: every report format has a line for it


@pytest.fixture
def assets(tmp_path: Path) -> Path:
    folder = tmp_path / "assets"
    folder.mkdir()
    shutil.copy(SOURCE, folder / "box.obj")
    shutil.copy(WARNED, folder / "cubes.obj")
    return folder


@pytest.fixture(scope="module")
def checked(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The assets (never changed by the tests using them) and a result cache they share."""
    folder = tmp_path_factory.mktemp("checked") / "assets"
    folder.mkdir()
    shutil.copy(SOURCE, folder / "box.obj")
    shutil.copy(WARNED, folder / "cubes.obj")
    return folder, folder.parent / "cache"


def validate(*args: str, cache: Path | None = None) -> tuple[int, str]:
    caching = ["--cache-dir", str(cache)] if cache is not None else ["--no-cache"]
    result = CliRunner().invoke(main, ["validate", *caching, "--no-thumbnails", *args])
    return result.exit_code, result.output


@pytest.mark.parametrize("force", [False, True], ids=["plain", "force"])
@pytest.mark.parametrize("how", ["file", "folder"])
def test_an_input_is_never_the_report(assets: Path, how: str, force: bool) -> None:
    obj = assets / "box.obj"
    before = obj.read_bytes()
    target = obj if how == "file" else assets
    code, output = validate(str(target), "-o", str(obj), *(["--force"] if force else []))
    assert code == 1 and "is an input (" in output and "refusing to overwrite it" in output, output
    assert "--force does not override this" in output
    assert "Traceback" not in output and obj.read_bytes() == before


def test_another_file_is_replaced_only_with_force(assets: Path, tmp_path: Path) -> None:
    notes = tmp_path / "notes.txt"
    notes.write_text("my notes\n")
    code, output = validate(str(assets), "-o", str(notes))
    assert code == 1 and "not an earlier meshtool validate report" in output and "--force" in output
    assert notes.read_text() == "my notes\n"
    code, output = validate(str(assets), "-o", str(notes), "--force")
    assert code in (0, 1) and "wrote" in output and is_report(notes.read_bytes())


@pytest.mark.parametrize("fmt", FORMATS)
def test_an_earlier_report_of_every_format_is_replaced(checked: tuple[Path, Path], tmp_path: Path, fmt: str) -> None:
    assets, cache = checked
    report = tmp_path / f"report.{fmt}"
    for _ in range(2):  # the findings come from a shared cache after the first check: what is tested is the file
        code, output = validate(str(assets), "--format", fmt, "-o", str(report), cache=cache)
        assert code in (0, 1) and "wrote" in output, output
    assert is_report(report.read_bytes())


def test_an_empty_file_may_be_replaced(assets: Path, tmp_path: Path) -> None:
    empty = tmp_path / "empty.txt"
    empty.write_bytes(b"")
    code, output = validate(str(assets / "box.obj"), "-o", str(empty))
    assert code == 0 and "wrote" in output, output


def test_what_is_not_a_report() -> None:
    assert not is_report(SOURCE.read_bytes())
    assert not is_report(b"")
    assert not is_report(b"PASSED is a word\nchecked the oil\n")
    assert not is_report(b"::a\nnot a command\n")
