"""``meshtool validate`` as CI runs it: several reports from one run, one cache for every format, each asset
named by its real format, and per-path settings in the configuration (issue 38, item 5).

Ground truth from outside the code under test: each asset's format is written here from its file name; the
JSON report is checked against the schema in docs/ (jsonschema), the JUnit report parsed by
``xml.etree``, the HTML page read by headless Chromium (Playwright, as ``tests/test_serve_dashboard.py``);
the lamp's height in centimetres is its vertex coordinates (24 units) divided by 100.
"""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path
from typing import Any
from xml.etree import ElementTree as ET

import jsonschema
import pytest
from click.testing import CliRunner
from conftest import FIXTURES, GL

from meshtool.cli.main import main
from meshtool.validate import ValidateOptions, load_config, render, validate

SCHEMA = json.loads((FIXTURES.parent / "docs" / "validate-report.schema.json").read_text())
#: What each file is, by its name (written here, not read from meshtool): registry name and label.
EXPECTED = {
    "box.obj": ("obj", "OBJ"),
    "bracket.stl": ("stl", "STL"),
    "crate.glb": ("glb", "GLB"),
    "link/link_cm_zup.dae": ("collada", "COLLADA"),
    "scan.ply": ("ply", "PLY"),
    "pack/box.mbin": ("mbin", "MBIN"),
}
ARGS = ["--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--hide-scrollbars", "--mute-audio"]


def _assets(folder: Path) -> Path:
    """The mixed-format fixture (OBJ, STL, GLB, COLLADA, PLY) and a pack, copied to ``folder``."""
    shutil.copytree(FIXTURES / "formats" / "mixed", folder)
    shutil.copytree(FIXTURES / "validate" / "clean", folder / "pack")
    (folder / "pack" / "box.obj").unlink()  # the pack alone (its source is checked as box.obj above)
    return folder


def _rel(path: str, root: Path) -> str:
    return path.split(f"{root.name}/", 1)[1]


def cli(*args: Any) -> Any:
    return CliRunner().invoke(main, ["validate", *map(str, args)])


def _run_line(output: str) -> str:
    """The summary line that says how the run went (``checked N ..., M from cache``)."""
    return next(line for line in output.splitlines() if line.startswith("checked "))


@pytest.fixture(scope="module")
def one_run(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """One ``meshtool validate`` writing JSON, JUnit and HTML (formats from the suffixes)."""
    root = tmp_path_factory.mktemp("ci")
    assets = _assets(root / "assets")
    out = root / "reports"
    result = cli(assets, "-o", out / "r.json", "-o", out / "r.xml", "-o", out / "r.html", "--cache-dir", root / "cache")
    return {"root": root, "assets": assets, "out": out, "result": result}


def test_one_run_writes_json_junit_and_html(one_run: dict[str, Any]) -> None:
    result, out, assets = one_run["result"], one_run["out"], one_run["assets"]
    assert result.exit_code == 0, result.output  # the STL, 40 m long read as metres, only warns (U001)
    assert sorted(p.name for p in out.iterdir()) == ["r.html", "r.json", "r.xml"]
    for name in ("r.json", "r.xml", "r.html"):
        assert f"wrote {out / name}" in result.output, result.output
    assert _run_line(result.output).startswith(f"checked {len(EXPECTED)} ")  # one run checked each asset once

    document = json.loads((out / "r.json").read_text())
    jsonschema.validate(document, SCHEMA)
    assert {_rel(a["path"], assets): a["format"] for a in document["assets"]} == {k: v[0] for k, v in EXPECTED.items()}
    suite = ET.parse(out / "r.xml").getroot().find("testsuite")
    assert suite is not None and int(suite.get("tests", "0")) == len(EXPECTED)
    labels = {}
    for case in suite.findall("testcase"):
        (prop,) = case.findall("properties/property")
        assert prop.get("name") == "format" and case.find("properties") is case[0]
        labels[_rel(case.get("name", ""), assets)] = prop.get("value")
    assert labels == {k: v[1] for k, v in EXPECTED.items()}


def test_the_reports_of_one_run_are_the_reports_of_single_format_runs(one_run: dict[str, Any], tmp_path: Path) -> None:
    """``--format json,junit,html`` with one -o each, and one format per run, write the same bytes."""
    out, assets, cache = one_run["out"], one_run["assets"], one_run["root"] / "cache"
    listed = cli(
        assets, "--format", "junit,json,html", "-o", tmp_path / "a", "-o", tmp_path / "b", "-o", tmp_path / "c",
        "--cache-dir", cache,
    )  # fmt: skip
    assert listed.exit_code == 0, listed.output
    assert (tmp_path / "a").read_bytes() == (out / "r.xml").read_bytes()
    assert (tmp_path / "b").read_bytes() == (out / "r.json").read_bytes()
    for fmt, name in (("json", "r.json"), ("junit", "r.xml")):
        single = cli(assets, "--format", fmt, "-o", tmp_path / name, "--cache-dir", cache)
        assert single.exit_code == 0 and (tmp_path / name).read_bytes() == (out / name).read_bytes()
        assert _run_line(single.output).startswith(f"checked 0, {len(EXPECTED)} from cache")


@pytest.fixture(scope="module")
def browser() -> Any:
    sync_api = pytest.importorskip("playwright.sync_api", reason="pip install playwright (no browser download needed)")
    chromium = next(
        (shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome") if shutil.which(n)), None
    )
    if chromium is None:
        pytest.skip("Chromium is not installed (apt-get install chromium)")
    with sync_api.sync_playwright() as playwright:
        launched = playwright.chromium.launch(executable_path=chromium, args=ARGS, headless=True)
        yield launched
        launched.close()


def test_the_html_page_names_each_assets_real_format(one_run: dict[str, Any], browser: Any) -> None:
    page = browser.new_page(viewport={"width": 1200, "height": 900})
    page.goto((one_run["out"] / "r.html").as_uri())
    cards = page.evaluate(
        """() => [...document.querySelectorAll('section.card')].map(card => ({
            path: card.querySelector('.path').innerText,
            stats: card.querySelector('.stats').innerText,
            format: card.dataset.format,
            image: card.querySelector('img').naturalWidth,
        }))"""
    )
    page.close()
    seen = {_rel(c["path"], one_run["assets"]): c for c in cards}
    assert set(seen) == set(EXPECTED)
    for name, (fmt, label) in EXPECTED.items():
        shown = seen[name]["stats"].split(" · ")[0]  # what a reader sees first under the asset's name
        assert shown == label and seen[name]["format"] == fmt, (name, seen[name])
        assert seen[name]["image"] == 404  # the thumbnail (or the placeholder) decoded in the browser
    assert sum(c["stats"].startswith("OBJ") for c in cards) == 1  # only the OBJ is called OBJ


def test_a_second_run_with_another_format_rechecks_no_unchanged_asset(tmp_path: Path) -> None:
    assets = _assets(tmp_path / "assets")
    cache = tmp_path / "cache"
    first = validate([assets], ValidateOptions(cache_dir=cache))  # as --format json: no thumbnails
    assert (first.checked, first.cache_hits, first.thumbnails_drawn) == (len(EXPECTED), 0, 0)
    second = validate([assets], ValidateOptions(cache_dir=cache, thumbnails=True))  # as --format html
    assert (second.checked, second.cache_hits) == (0, len(EXPECTED))
    assert render(second, "json") == render(first, "json")  # the findings of the first run, whatever the format
    drawable = sum(a.drawable for a in second.assets)
    assert second.thumbnails_drawn == drawable >= 5  # the pictures the first run had no reason to draw
    fresh = validate([assets], ValidateOptions(thumbnails=True))  # no cache: every rule judged again
    assert render(second, "json") == render(fresh, "json")
    if GL:
        assert sum(a.thumbnail is not None for a in second.assets) == drawable
        assert [a.thumbnail for a in second.assets] == [a.thumbnail for a in fresh.assets]
        assert render(second, "html") == render(fresh, "html")
    third = validate([assets], ValidateOptions(cache_dir=cache, thumbnails=True))
    assert (third.checked, third.thumbnails_drawn) == (0, 0 if GL else drawable)  # the drawn ones were kept
    with (assets / "scan.ply").open("ab") as ply:
        ply.write(b"\n")  # one asset's bytes change (a trailing newline after the PLY's data)
    fourth = validate([assets], ValidateOptions(cache_dir=cache))  # as --format junit
    assert (fourth.checked, fourth.cache_hits) == (1, len(EXPECTED) - 1)
    result = cli(assets, "--format", "junit", "-o", tmp_path / "r.xml", "--cache-dir", cache)
    assert _run_line(result.output).startswith(f"checked 0, {len(EXPECTED)} from cache"), result.output


LAMP = FIXTURES / "validate_paths" / "lamp.obj"
CONFIG = """\
[validate]
severity = { G007 = "error" }

[[validate.paths]]
glob = "props/cm/**"
units = "cm"

[[validate.paths]]
glob = "props/strict/**"
severity = { scale-implausible = "error" }
"""


def _lamps(root: Path) -> Path:
    for folder in ("props/cm", "props/cm/deep", "props/m", "props/strict", "elsewhere"):
        (root / folder).mkdir(parents=True, exist_ok=True)
        shutil.copy(LAMP, root / folder / "lamp.obj")
    (root / "meshtool.toml").write_text(CONFIG)
    return root


def _u001(report: Any, root: Path) -> dict[str, list[tuple[str, str]]]:
    return {
        _rel(a.path, root): [(f.severity.value, f.message) for f in a.findings if f.code == "U001"]
        for a in report.assets
    }


def test_a_config_glob_setting_units_silences_the_size_warning_on_exactly_those_assets(tmp_path: Path) -> None:
    root = _lamps(tmp_path / "project")
    config = load_config(root / "meshtool.toml")
    report = validate([root], ValidateOptions(config=config, cache_dir=tmp_path / "cache"))
    warned = [("warning", "24.0 m tall: if it was modelled in centimetres, pass --units cm (0.24 m)")]
    assert _u001(report, root) == {
        "elsewhere/lamp.obj": warned,
        "props/cm/deep/lamp.obj": [],
        "props/cm/lamp.obj": [],
        "props/m/lamp.obj": warned,
        "props/strict/lamp.obj": [("error", warned[0][1])],
    }
    extents = {_rel(a.path, root): a.stats["bbox"]["extent"] for a in report.assets}
    assert extents["props/cm/lamp.obj"] == pytest.approx([0.04, 0.04, 0.24])  # 4 x 24 x 4 cm, Z-up
    assert extents["props/m/lamp.obj"] == pytest.approx([4.0, 4.0, 24.0])
    # the cache knows the unit is part of the result: without the configuration the lamps are checked again
    plain = validate([root], ValidateOptions(cache_dir=tmp_path / "cache"))
    assert plain.checked == 2 and all(found == warned for found in _u001(plain, root).values())
    # the command line: the same configuration, named in the report
    result = cli(root, "--format", "json", "--config", root / "meshtool.toml", "--no-cache")
    document = json.loads(result.output)
    assert sum(bool(a["findings"]) for a in document["assets"]) == 3 and document["summary"]["errors"] == 1
    assert document["summary"]["config"] == str(root / "meshtool.toml")


@pytest.mark.parametrize(
    ("text", "line", "message"),
    [
        (
            '[validate]\nignore = ["S009"]\n\n[[validate.paths]]\nglob = "props/**"\nunit = "cm"\n',
            6,
            "[validate]: paths entry 1: unknown key 'unit' (use one of glob, ignore, limits, severity, units, up)",
        ),
        (
            '[validate]\n\n[[validate.paths]]\nglob = "a/**"\nunits = "cm"\n\n[[validate.paths]]\nglob = "b/**"\n'
            "limits = { max-vertexes = 3 }\n",
            9,
            "[validate]: paths entry 2: limits: unknown limit 'max-vertexes' (use one of max-vertices, ",
        ),
        (
            '# assets\n[validate]\ntimeout = 30\ncolour = "red"\n',
            4,
            "[validate]: unknown key 'colour' (use one of ignore, limits, paths, per-path-ignores, severity, "
            "source-roots, timeout)",
        ),
        (
            '[validate]\n[[validate.paths]]\nglob = "x/**"\nunits = "furlongs"\n',
            4,
            "[validate]: paths entry 1: unknown units 'furlongs' (use one of m, cm, mm, in, ft, auto)",
        ),
    ],
    ids=["paths-key", "paths-limit", "top-key", "paths-units"],
)
def test_unknown_keys_are_one_line_naming_the_key_the_file_and_the_line(
    tmp_path: Path, text: str, line: int, message: str
) -> None:
    config = tmp_path / "meshtool.toml"
    config.write_text(text)
    result = cli(LAMP, "--config", config, "--no-cache")
    assert result.exit_code == 2, result.output
    (error,) = result.output.strip().splitlines()
    assert error.startswith(f"usage error: {config}:{line}: {message}"), error


def test_the_same_keys_in_pyproject(tmp_path: Path) -> None:
    config = tmp_path / "pyproject.toml"
    config.write_text('[project]\nname = "x"\n\n[[tool.meshtool.validate.paths]]\nglob = "**"\nupaxis = "z"\n')
    result = cli(LAMP, "--config", config, "--no-cache")
    assert result.exit_code == 2 and f"{config}:6: [tool.meshtool.validate]: paths entry 1: unknown key 'upaxis'" in (
        result.output
    )
    config.write_text('[[tool.meshtool.validate.paths]]\nglob = "**"\nunits = "cm"\nup = "z"\n')
    assert load_config(config).settings_for(tmp_path / "lamp.obj").units == "cm"


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--format", "json,junit"], "--format json,junit writes 2 reports, stdout takes one"),
        (["--format", "json", "-o", "{t}/a.json", "-o", "{t}/b.json"], "--format names 1 format for 2 -o files"),
        (["--format", "json,html", "-o", "{t}/a.json"], "--format names 2 formats for 1 -o files"),
        (["-o", "{t}/a.json", "-o", "{t}/./a.json"], "named twice with -o"),
        (["--format", "json,json", "-o", "{t}/a", "-o", "{t}/b"], "json named twice"),
        (["--format", "json,yaml", "-o", "{t}/a", "-o", "{t}/b"], "'yaml' is not one of"),
    ],
)
def test_reports_that_do_not_pair_up_are_usage_errors(tmp_path: Path, args: list[str], message: str) -> None:
    args = [arg.replace("{t}", str(tmp_path)) for arg in args]
    result = CliRunner().invoke(main, ["validate", str(LAMP), "--no-cache", *args])
    assert result.exit_code == 2 and message in result.output, result.output
    assert "Traceback" not in result.output and not any(tmp_path.iterdir())


def test_a_file_of_another_suffix_gets_the_text_report_as_before(tmp_path: Path) -> None:
    result = cli(LAMP, "--no-cache", "--no-thumbnails", "-o", tmp_path / "notes.log", "-o", tmp_path / "r.txt")
    assert result.exit_code == 0, result.output
    for name in ("notes.log", "r.txt"):
        text = (tmp_path / name).read_text()
        assert re.search(r"^\S*/lamp\.obj \(OBJ\)  1 warning$", text, re.M) and "passed: 1 assets" in text


def test_annotations_on_stdout_and_reports_in_files_from_one_run(one_run: dict[str, Any], tmp_path: Path) -> None:
    """The CI step of docs/ci.md: ``-o -`` is stdout, so the annotations and the files come from one run."""
    out, assets, cache = one_run["out"], one_run["assets"], one_run["root"] / "cache"
    result = cli(
        assets, "--format", "github,junit,html", "-o", "-", "-o", tmp_path / "r.xml", "-o", tmp_path / "r.html",
        "--cache-dir", cache,
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    (annotation,) = result.stdout.splitlines()  # stdout holds the workflow commands only
    assert annotation.startswith("::warning file=") and "bracket.stl" in annotation and "U001" in annotation
    assert (tmp_path / "r.xml").read_bytes() == (out / "r.xml").read_bytes()
    assert "wrote" in result.stderr and _run_line(result.stderr).startswith(f"checked 0, {len(EXPECTED)} from cache")


def test_an_asset_mujoco_cannot_compile_has_no_picture_to_draw(tmp_path: Path) -> None:
    """P001: the plugin draws nothing for it, so an HTML run after a JSON run has nothing to draw."""
    asset = FIXTURES / "validate" / "P001_mujoco_compile"
    cache = tmp_path / "cache"
    first = validate([asset], ValidateOptions(cache_dir=cache))
    assert [f.code for a in first.assets for f in a.findings if f.code == "P001"] == ["P001"]
    second = validate([asset], ValidateOptions(cache_dir=cache, thumbnails=True))
    assert (second.checked, second.thumbnails_drawn) == (0, 0) and second.assets[0].thumbnail is None
