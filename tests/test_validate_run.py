"""meshtool validate end to end: reports parsed back, cache, executors, exit codes."""

import json
import re
import shutil
from html.parser import HTMLParser
from pathlib import Path
from xml.etree import ElementTree as ET

import jsonschema
import mujoco
import numpy as np
import pytest
from click.testing import CliRunner
from conftest import FIXTURES, GL, needs_gl
from PIL import Image

from meshtool.cli.main import main
from meshtool.validate import ValidateOptions, render, validate
from meshtool.validate import task as task_module
from meshtool.validate.plugin_types import PhysicsOutcome
from meshtool.validate.rules import RULES
from simrun.asset_check import _drop

ROOT = FIXTURES / "validate"
SCHEMA = json.loads((Path(__file__).resolve().parent.parent / "docs" / "validate-report.schema.json").read_text())
PICK = ["clean", "S003_texture_missing", "G005_winding_inconsistent", "K001_pack_corrupt", "C004_no_hulls"]


@pytest.fixture
def assets(tmp_path):
    """A copy of a few rule fixtures (and the clean ones) to validate and modify."""
    for name in PICK:
        shutil.copytree(ROOT / name, tmp_path / "assets" / name)
    return tmp_path / "assets"


@pytest.fixture(scope="module")
def report():
    return validate([ROOT / name for name in PICK], ValidateOptions(thumbnails=GL))


def summary_of(rep):
    return [(a.path, [f.to_dict() for f in a.findings]) for a in rep.assets]


def test_report_counts(report):
    paths = [a.path.split("validate/")[1] for a in report.assets]
    assert paths == [
        "C004_no_hulls/box.mbin",
        "G005_winding_inconsistent/box.obj",
        "K001_pack_corrupt/box.mbin",
        "S003_texture_missing/box.obj",
        "clean/box.mbin",
        "clean/box.obj",
    ]
    assert report.counts() == {"error": 2, "warning": 2, "info": 0}
    assert report.failed(strict=False) and report.internal_errors() == 0


def test_json_report_matches_its_schema(report):
    document = json.loads(render(report, "json"))
    jsonschema.validate(document, SCHEMA)
    assert document["summary"]["errors"] == 2 and document["summary"]["passed"] is False
    assert document["summary"]["by_status"] == {"error": 2, "warning": 2, "info": 0, "clean": 2}
    s003 = next(a for a in document["assets"] if "S003" in a["path"])
    (finding,) = s003["findings"]
    assert finding["rule"] == "S003" and finding["name"] == "texture-missing" and finding["line"] == 3
    assert finding["file"].endswith("S003_texture_missing/box.mtl")
    assert finding["hint"] == RULES["S003"].hint


def test_junit_report_parses(report):
    root = ET.fromstring(render(report, "junit"))
    (suite,) = root.findall("testsuite")
    cases = suite.findall("testcase")
    assert len(cases) == 6 == int(suite.get("tests"))
    failures = {
        c.get("name").split("validate/")[1]: c.find("failure").get("type")
        for c in cases
        if c.find("failure") is not None
    }
    assert failures == {"K001_pack_corrupt/box.mbin": "K001", "S003_texture_missing/box.obj": "S003"}
    assert suite.get("failures") == "2" and suite.get("errors") == "0"
    strict = ET.fromstring(render(report, "junit", strict=True)).find("testsuite")
    assert strict.get("failures") == "4"  # the warnings fail too


def test_github_annotations(report):
    lines = render(report, "github").splitlines()
    assert len(lines) == sum(len(a.findings) for a in report.assets) == 4
    pattern = re.compile(r"^::(error|warning|notice) file=[^,:]+(,line=\d+)?,title=[A-Z]\d{3} [a-z-]+::.+ \(fix: .+\)$")
    assert all(pattern.match(line) for line in lines), lines
    assert any(line.startswith("::error ") and ",line=3," in line and "S003" in line for line in lines)


class ImgCounter(HTMLParser):
    def __init__(self):
        super().__init__()
        self.images, self.cards = [], 0

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if tag == "img":
            self.images.append(attrs["src"])
        if tag == "section" and "card" in attrs.get("class", ""):
            self.cards += 1


def test_html_has_one_image_per_asset(report):
    page = render(report, "html")
    parser = ImgCounter()
    parser.feed(page)
    assert parser.cards == len(parser.images) == len(report.assets) == 6
    assert all(src.startswith("data:image/") for src in parser.images)  # self-contained
    assert "http://" not in page.replace('xmlns="http://www.w3.org/2000/svg"', "")
    assert page.count("S003 texture-missing") == 1


@needs_gl
def test_thumbnails_show_visual_and_collision_views(report):
    import io

    from PIL import Image

    clean = next(a for a in report.assets if a.path.endswith("clean/box.obj"))
    image = Image.open(io.BytesIO(clean.thumbnail))
    assert image.size == (404, 150)
    left, right = image.crop((0, 0, 200, 150)), image.crop((204, 0, 404, 150))

    # the collision view draws the hull in blue; the visual view shows the textured box
    def blue(im):
        rgb = np.asarray(im, dtype=int)
        return int((rgb[..., 2] > rgb[..., 0] + 40).sum())

    assert blue(right) > 500 and blue(right) > 2 * blue(left)
    broken = next(a for a in report.assets if "K001" in a.path)
    assert broken.thumbnail is None  # nothing to draw: the HTML shows a placeholder instead


def test_text_report_groups_worst_first(report):
    text = render(report, "text")
    assert text.index("K001_pack_corrupt") < text.index("C004_no_hulls")  # errors before warnings
    assert "clean/box.obj" not in text  # clean assets only with --verbose
    assert "FAILED: 6 assets, 2 clean; 2 errors, 2 warnings, 0 infos" in text


def test_cache_serves_unchanged_assets_and_notices_changes(assets, tmp_path):
    cache = tmp_path / "cache"
    options = ValidateOptions(cache_dir=cache)
    first = validate([assets], options)
    assert (first.checked, first.cache_hits) == (6, 0)
    second = validate([assets], options)
    assert (second.checked, second.cache_hits) == (0, 6)
    assert summary_of(second) == summary_of(first)
    assert render(second, "json") == render(first, "json")  # byte-identical whether cached or not
    # a changed texture re-checks the OBJ that uses it and the pack made from it (now stale), only those
    Image.new("RGB", (4, 4), (200, 30, 30)).save(assets / "clean" / "box.png")  # another valid PNG
    third = validate([assets], options)
    assert (third.checked, third.cache_hits) == (2, 4)
    pack = next(a for a in third.assets if a.path.endswith("clean/box.mbin"))
    assert [f.code for f in pack.findings] == ["K003"] and "changed: box.png" in pack.findings[0].message
    # adding the missing texture fixes S003: the folder listing is part of the cache entry
    shutil.copy(assets / "clean" / "box.png", assets / "S003_texture_missing" / "missing.png")
    changed = validate([assets], ValidateOptions(cache_dir=cache, changed_only=True))
    assert [a.path.split("assets/")[1] for a in changed.assets] == ["S003_texture_missing/box.obj"]
    assert changed.assets[0].findings == [] and changed.unchanged_skipped == 5
    assert validate([assets], options).cache_hits == 6


def test_validation_never_writes_beside_the_sources(assets, tmp_path):
    before = sorted(p.relative_to(assets) for p in assets.rglob("*"))
    validate([assets], ValidateOptions(cache_dir=tmp_path / "cache", thumbnails=GL))
    assert sorted(p.relative_to(assets) for p in assets.rglob("*")) == before


def test_worker_processes_give_the_same_findings(assets):
    serial = validate([assets], ValidateOptions(jobs=1))
    parallel = validate([assets], ValidateOptions(jobs=2))
    assert summary_of(parallel) == summary_of(serial)


def test_dask_executor_gives_the_same_findings(assets):
    pytest.importorskip("distributed")
    local = validate([assets], ValidateOptions(jobs=1))
    dask = validate([assets], ValidateOptions(jobs=2, executor="dask"))
    assert dask.executor == "dask"
    assert summary_of(dask) == summary_of(local)
    assert render(dask, "json") == render(local, "json")


def test_dask_scheduler_address(assets):
    """--scheduler: a running cluster (here a LocalCluster started by the test) reached by its address."""
    distributed = pytest.importorskip("distributed")
    local = validate([assets], ValidateOptions(jobs=1))
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, dashboard_address=None) as cluster:
        remote = validate([assets], ValidateOptions(executor="dask", scheduler=cluster.scheduler_address))
    assert summary_of(remote) == summary_of(local)


def test_mujoco_warnings_become_p003(capfd):
    model = mujoco.MjModel.from_xml_string(
        '<mujoco><option gravity="0 0 -1e13"/><worldbody><body><freejoint/>'
        '<geom type="box" size=".1 .1 .1"/></body></worldbody></mujoco>'
    )
    outcome = PhysicsOutcome()
    _drop(model, "falling.obj", 0.3, 0.2, outcome)
    codes = {f.code for f in outcome.findings}
    assert "P003" in codes, [f.one_line() for f in outcome.findings]
    assert outcome.stats["warnings"]
    assert any("unstable" in m for m in outcome.stats["mujoco_messages"])
    assert capfd.readouterr().out == ""  # MuJoCo's own print would land in a report on stdout


def test_a_crashing_rule_is_x001_and_exit_3(assets, monkeypatch):
    def broken(*args, **kwargs):
        raise ZeroDivisionError("boom")

    monkeypatch.setattr(task_module, "geometry_findings", broken)
    report = validate([assets / "clean" / "box.obj"])
    (finding,) = [f for f in report.assets[0].findings if f.code == "X001"]
    assert "ZeroDivisionError: boom" in finding.message
    result = CliRunner().invoke(main, ["validate", str(assets / "clean" / "box.obj"), "--no-cache", "-j", "1"])
    assert result.exit_code == 3


def cli(*args):
    return CliRunner().invoke(main, ["validate", *map(str, args)])


def test_cli_exit_codes(assets, tmp_path):
    cache = ["--cache-dir", tmp_path / "cache"]
    assert cli(assets / "clean", *cache, "-j", 1).exit_code == 0
    assert cli(assets / "G005_winding_inconsistent", *cache).exit_code == 0  # warnings only
    assert cli(assets / "G005_winding_inconsistent", *cache, "--strict").exit_code == 1
    assert cli(assets / "S003_texture_missing", *cache).exit_code == 1
    missing = cli(tmp_path / "nope", *cache)
    assert missing.exit_code == 1 and "no such file or folder" in missing.output
    assert cli(assets, "--scheduler", "tcp://x:1").exit_code == 2
    (tmp_path / "meshtool.toml").write_text("[validate]\nseverity = { G005 = 'fatal' }\n")
    bad = cli(assets, "--config", tmp_path / "meshtool.toml")
    assert bad.exit_code == 2 and "meshtool.toml: [validate]: severity of G005: 'fatal'" in bad.output
    assert "Traceback" not in bad.output


def test_cli_config_turns_a_warning_into_an_error(assets, tmp_path):
    config = tmp_path / "pyproject.toml"
    config.write_text('[tool.meshtool.validate]\nseverity = { winding-inconsistent = "error" }\n')
    result = cli(assets / "G005_winding_inconsistent", "--config", config, "--no-cache", "--format", "json")
    assert result.exit_code == 1
    document = json.loads(result.output)
    assert document["summary"]["config"] == str(config)
    assert [f["severity"] for a in document["assets"] for f in a["findings"]] == ["error"]


def test_cli_writes_the_report_atomically(assets, tmp_path):
    out = tmp_path / "reports" / "report.xml"
    result = cli(assets, "--format", "junit", "-o", out, "--no-cache")
    assert result.exit_code == 1
    ET.parse(out)  # a whole, parseable file
    assert sorted(p.name for p in out.parent.iterdir()) == ["report.xml"]  # no temporary files left
    assert "wrote" in result.output and "FAILED: 6 assets" in result.output


def test_cli_html_report(assets, tmp_path):
    out = tmp_path / "report.html"
    result = cli(assets, "--format", "html", "-o", out, "--no-cache", "-j", 1)
    assert result.exit_code == 1
    parser = ImgCounter()
    parser.feed(out.read_text())
    assert len(parser.images) == 6
    if GL:
        assert sum(src.startswith("data:image/png") for src in parser.images) == 5  # all but the corrupt pack
