"""Each rule of meshtool validate against its fixture: the fixture triggers exactly that rule."""

import re
from dataclasses import replace
from pathlib import Path

import pytest
from conftest import FIXTURES

from meshtool.findings import Severity
from meshtool.validate import Limits, check_asset
from meshtool.validate.config import ValidateConfig, parse_config
from meshtool.validate.rules import RULES, rule_id
from meshtool.validate.task import AssetTask

ROOT = FIXTURES / "validate"
DOCS = Path(__file__).resolve().parent.parent / "docs" / "validate-rules.md"

#: rule -> (fixture asset, limits changed for the test). Limits are changed only where a natural fixture
#: would be huge (G011: 200 000 vertices) or slow to tell (P002: a rocking egg settles at 1.3 s of 3).
FIXTURE = {
    "S001": ("S001_obj_unreadable/box.obj", {}),
    "S002": ("S002_mtl_missing/box.obj", {}),
    "S003": ("S003_texture_missing/box.obj", {}),
    "S004": ("S004_material_undefined/box.obj", {}),
    "S005": ("S005_texture_format/box.obj", {}),
    "S006": ("S006_path_absolute/box.obj", {}),
    "S007": ("S007_path_foreign/box.obj", {}),
    "S008": ("S008_path_outside/box.obj", {}),
    "S009": ("S009_name_unsafe/my box.obj", {}),
    "S010": ("S010_encoding/box.obj", {}),
    "S011": ("S011_syntax/box.obj", {}),
    "S012": ("../formats/validate/S012_facet_normals/flipped.stl", {}),
    "S013": ("../formats/validate/S013_buffer_missing/model.gltf", {}),
    "S014": ("S014_consumer_frames_differ/box.obj", {}),
    "G001": ("G001_non_finite/box.obj", {}),
    "G002": ("G002_no_faces/points.obj", {}),
    "G003": ("G003_degenerate_faces/box.obj", {}),
    "G004": ("G004_duplicate_faces/box.obj", {}),
    "G005": ("G005_winding_inconsistent/box.obj", {}),
    "G006": ("G006_inside_out/box.obj", {}),
    "G007": ("G007_open_mesh/box.obj", {}),
    "G008": ("G008_non_manifold/boxes.obj", {}),
    "G009": ("G009_coplanar/sheet.obj", {}),
    "G010": ("G010_tiny_volume/foil.obj", {}),
    "G011": ("G011_vertex_count/ball.obj", {"max_vertices": 100}),
    "U001": ("U001_scale_implausible/container.obj", {}),
    "C001": ("C001_hull_count/cubes.mbin", {}),
    "C002": ("C002_hull_vertices/ball.mbin", {}),
    "C003": ("C003_hull_fit/bracket.obj", {}),
    "C004": ("C004_no_hulls/box.mbin", {}),
    "P001": ("P001_mujoco_compile/box.mbin", {}),
    "P002": ("P002_drop_unsettled/egg.obj", {"settle_time": 1.0}),
    "P004": ("P004_mass_implausible/block.obj", {}),
    "P005": ("P005_inertia_implausible/wire.obj", {}),
    "K001": ("K001_pack_corrupt/box.mbin", {}),
    "K002": ("K002_pack_version/box.mbin", {}),
    "K003": ("K003_pack_stale/box.mbin", {}),
}
#: Rules without a single-rule fixture, and why (tested elsewhere).
NO_FIXTURE = {
    "P003": "MuJoCo warnings need a broken model; covered with an unstable model in test_validate_run",
    "X001": "a bug in a rule; covered by making a rule raise in test_validate_run",
    "X002": "a hanging check; covered by a deliberately slow physics plugin in test_validate_timeout",
    "S015": "an index past its limits needs thousands of files; covered with lowered limits in test_consumer_index",
    "G012": "a padded part is open too (G007); covered by the one-triangle OBJ in test_geometry_findings.py",
}
CLEAN = ["clean/box.obj", "clean/box.mbin", "K003_pack_stale/box.obj", "_sources/box.obj", "_sources/ball.obj"]


def run(rel, **limits):
    path = ROOT / rel
    return check_asset(AssetTask(path, rel, replace(Limits(), **limits)))


def test_every_rule_has_a_fixture_or_a_reason():
    assert set(FIXTURE) | set(NO_FIXTURE) == set(RULES)
    assert not set(FIXTURE) & set(NO_FIXTURE)


@pytest.mark.parametrize("rule", sorted(FIXTURE))
def test_fixture_triggers_exactly_its_rule(rule):
    rel, limits = FIXTURE[rule]
    result = run(rel, **limits)
    assert {f.code for f in result.findings} == {rule}, [f.one_line() for f in result.findings]
    assert all(f.severity is RULES[rule].severity for f in result.findings)
    assert all(f.message for f in result.findings)


@pytest.mark.parametrize("rel", CLEAN)
def test_clean_assets_trigger_nothing(rel):
    result = run(rel)
    assert result.findings == [], [f.one_line() for f in result.findings]
    assert result.kind == ("mbin" if rel.endswith(".mbin") else "obj")


def test_default_limits_do_not_flag_the_limit_fixtures():
    """The G011 and P002 fixtures are fine under the default limits: the rules fire on the limit alone."""
    for rule in ("G011", "P002"):
        assert run(FIXTURE[rule][0]).findings == []


def test_findings_name_file_and_line_where_known():
    s007 = run("S007_path_foreign/box.obj").findings
    assert [(f.path, f.line) for f in s007] == [("box.mtl", 3)]
    g001 = run("G001_non_finite/box.obj").findings
    assert [(f.path, f.line) for f in g001] == [("box.obj", 9)]  # the header comment is line 1, v lines 2..9


def test_geometry_numbers_are_exact():
    assert "1 of 13 triangles" in run("G004_duplicate_faces/box.obj").findings[0].message
    assert run("G007_open_mesh/box.obj").findings[0].message.startswith("4 boundary edges")
    assert run("G008_non_manifold/boxes.obj").findings[0].message.startswith("1 edges")
    assert run("C001_hull_count/cubes.mbin").findings[0].message == "40 hulls, budget 32"


def test_pack_stale_names_the_changed_source():
    (finding,) = run("K003_pack_stale/box.mbin").findings
    assert finding.message == "made from older sources (changed: box.obj)"


def test_physics_stats_of_the_clean_box():
    physics = run("clean/box.obj").stats["physics"]
    assert physics["mass_kg"] == pytest.approx(0.2 * 0.15 * 0.1 * 1000, rel=1e-6)
    assert 0 < physics["came_to_rest_s"] < 3
    assert physics["warnings"] == {}


def test_rules_are_documented_with_id_name_and_severity():
    docs = DOCS.read_text()
    for rule in RULES.values():
        row = re.search(rf"^\| `{rule.id}` \| `{rule.name}` \| (\w+) \|", docs, re.M)
        assert row, rule.id
        assert row.group(1) == rule.severity.value


def test_rule_lookup_by_id_or_name():
    assert rule_id("g005") == "G005"
    assert rule_id("winding-inconsistent") == "G005"
    assert rule_id("nope") is None


def test_config_overrides_and_ignores():
    config = parse_config(
        {
            "severity": {"G007": "error", "hull-fit": "off"},
            "ignore": ["S009"],
            "per-path-ignores": {"props/**": ["*"], "legacy/old.obj": ["G005"]},
            "limits": {"max-vertices": 10},
        },
        "meshtool.toml",
        "[validate]",
        Path("/repo"),
    )
    assert config.limits.max_vertices == 10
    from meshtool.validate.rules import hit

    found = [hit("G007", "open"), hit("C003", "fit"), hit("S009", "name"), hit("G005", "wind")]
    kept = config.apply(found, Path("/repo/a/b.obj"))
    assert [(f.code, f.severity) for f in kept] == [("G007", Severity.ERROR), ("G005", Severity.WARNING)]
    assert [f.code for f in config.apply(found, Path("/repo/legacy/old.obj"))] == ["G007"]
    assert config.apply(found, Path("/repo/props/x/y.obj")) == []
    assert config.apply([hit("X001", "bug")], Path("/repo/props/x.obj"))[0].code == "X001"  # never hidden


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ({"colour": 1}, "unknown key 'colour'"),
        ({"severity": {"Z999": "error"}}, "unknown rule 'Z999'"),
        ({"severity": {"G005": "fatal"}}, "severity of G005: 'fatal'"),
        ({"limits": {"max-things": 3}}, "unknown limit 'max-things'"),
        ({"limits": {"max-vertices": -3}}, "must be a positive number"),
        ({"ignore": "G005"}, "must be a list"),
    ],
)
def test_config_errors_are_one_line_with_the_file(table, message):
    from meshtool.validate import ConfigError

    with pytest.raises(ConfigError) as err:
        parse_config(table, "pyproject.toml", "[tool.meshtool.validate]", Path("."))
    assert message in str(err.value)
    assert str(err.value).startswith("pyproject.toml: [tool.meshtool.validate]")
    assert "\n" not in str(err.value)


def test_default_config_keeps_every_finding_as_it_is():
    from meshtool.validate.rules import hit

    found = [hit(rule, f"{rule} message", "x.obj", 3) for rule in RULES]
    assert ValidateConfig().apply(found, Path("x.obj")) == found


def test_config_is_found_from_the_working_folder_up(tmp_path):
    from meshtool.validate import find_config, load_config

    (tmp_path / "pyproject.toml").write_text('[tool.meshtool.validate]\nignore = ["S009"]\n')
    inner = tmp_path / "pkg" / "assets"
    inner.mkdir(parents=True)
    (tmp_path / "pkg" / "pyproject.toml").write_text("[project]\nname = 'x'\n")  # no table: keep looking
    found = find_config(inner)
    assert found == (tmp_path / "pyproject.toml").resolve()
    assert load_config(found).ignore == ("S009",)
    (inner / "meshtool.toml").write_text("[validate]\nlimits = { max-vertices = 5 }\n")
    nearest = find_config(inner)
    assert nearest == (inner / "meshtool.toml").resolve()
    config = load_config(nearest)
    assert config.limits.max_vertices == 5 and config.root == nearest.parent
