"""One reporting layer (issue 26 deliver 4): commands say what they did, and text and JSON are rendered from it.

Ground truth is outside the layer: the files on disk (their size, that MuJoCo or a JSON parser reads them) and
what the command printed in the other mode.
"""

import json
from pathlib import Path

import mujoco
import pytest
from click.testing import CliRunner

from meshtool.cli.main import main as meshtool_main
from meshtool.cli.mesh_commands import obj2bin
from meshtool.cli.output import EXIT_INPUT, EXIT_OK, Outcome, render_json
from simrun.cli.main import main as simrun_main

ROOT = Path(__file__).resolve().parent.parent
PACKED = ROOT / "fixtures" / "scenes" / "head.mbin"
HEAD = ROOT / "fixtures" / "head" / "Head 1.obj"
SCENE = ROOT / "fixtures" / "scenes" / "basic.toml"


def _run(main, args):
    result = CliRunner().invoke(main, [str(a) for a in args])
    return result


def test_a_file_written_is_in_json_with_its_kind_and_the_size_on_disk(tmp_path):
    glb, msh = tmp_path / "h.glb", tmp_path / "h.msh"
    result = _run(meshtool_main, ["export", PACKED, "--glb", glb, "--msh", msh, "--json"])
    assert result.exit_code == 0, result.output
    document = json.loads(result.stdout)
    assert [(o["kind"], o["path"], o["bytes"]) for o in document["outputs"]] == [
        ("glb", str(glb), glb.stat().st_size),
        ("msh", str(msh), msh.stat().st_size),
    ]
    assert document["status"] == "ok" and document["exit_code"] == EXIT_OK and "error" not in document


def test_text_and_json_say_the_same_things(tmp_path):
    text = _run(meshtool_main, ["export", PACKED, "--glb", tmp_path / "a.glb"])
    document = json.loads(_run(meshtool_main, ["export", PACKED, "--glb", tmp_path / "b.glb", "--json"]).stdout)
    assert text.stdout.splitlines() == [line.replace("b.glb", "a.glb") for line in document["output"]]
    assert f"({(tmp_path / 'a.glb').stat().st_size} bytes)" in text.stdout


def test_quiet_says_nothing_and_still_writes(tmp_path):
    result = _run(meshtool_main, ["export", PACKED, "--glb", tmp_path / "q.glb", "-q"])
    assert result.exit_code == 0 and result.stdout == "" and (tmp_path / "q.glb").stat().st_size > 0


def test_a_mesh_to_mjcf_lists_the_model_mujoco_loads(tmp_path):
    result = _run(meshtool_main, ["mjcf", HEAD, "-o", tmp_path, "--json"])
    assert result.exit_code == 0, result.output
    document = json.loads(result.stdout)
    (written,) = document["outputs"]
    assert written["kind"] == "mjcf"
    model = mujoco.MjModel.from_xml_path(written["path"])  # the consuming tool reads what the JSON names
    assert model.nmesh >= 1
    assert isinstance(document["findings"], list) and isinstance(document["stats"], dict)


def test_simrun_export_lists_each_output_and_its_notes(tmp_path):
    mjcf, usd = tmp_path / "m" / "scene.xml", tmp_path / "s.usda"
    result = _run(simrun_main, ["export", SCENE, "--mjcf", mjcf, "--usd", usd, "--json"])
    assert result.exit_code == 0, result.output
    document = json.loads(result.stdout)
    assert [(o["kind"], o["path"]) for o in document["outputs"]] == [("mjcf", str(mjcf)), ("usd", str(usd))]
    assert mujoco.MjModel.from_xml_path(str(mjcf)).nbody > 1 and usd.stat().st_size > 0
    assert all(note.startswith(f"{usd}: not in the USD: ") for note in document["notes"])


def test_a_folder_conversion_that_fails_is_json_with_the_failed_asset(tmp_path):
    source = tmp_path / "in"
    source.mkdir()
    (source / "good.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n")
    (source / "bad.obj").write_text("v 0 0 nan\nf 1 1 1\n")
    result = _run(obj2bin, [source, "-o", tmp_path / "out", "--json", "--no-check"])
    assert result.exit_code == EXIT_INPUT
    document = json.loads(result.stdout)
    statuses = {Path(a["source"]).name: a["status"] for a in document["assets"]}
    assert statuses == {"good.obj": "written", "bad.obj": "failed"}
    assert (tmp_path / "out" / "good.mbin").stat().st_size > 0 and not (tmp_path / "out" / "bad.mbin").exists()
    text = _run(obj2bin, [source, "-o", tmp_path / "out2", "--no-check"])
    assert text.exit_code == EXIT_INPUT and any(line.startswith("error: ") for line in text.stderr.splitlines())


@pytest.mark.parametrize(
    ("outcome", "code", "expected"),
    [
        (Outcome(command="x", lines=["wrote a"]), 0, {"status": "ok", "output": ["wrote a"]}),
        (Outcome(command="x", messages=["FAILED: 2 assets"]), 1, {"error": {"message": "FAILED: 2 assets"}}),
        (Outcome(command="x"), 1, {"error": {"message": "failed (exit code 1)"}}),
        (
            Outcome(command="x", error={"message": "m", "line": 3}),
            2,
            {"exit_code": 2, "error": {"message": "m", "line": 3}},
        ),
        (Outcome(command="x", document={"own": 1}, lines=["hidden"]), 0, {"own": 1}),
        (Outcome(command="x", document='{"own": 2}\n'), 1, {"own": 2}),
    ],
)
def test_the_json_document_is_rendered_from_the_outcome(outcome, code, expected):
    document = json.loads(render_json(outcome, code))
    assert expected.items() <= document.items()
    if outcome.document is None:
        assert {"status", "command", "exit_code", "output", "outputs", "findings", "notes", "stats"} <= set(document)
        assert ("error" in document) == (code != 0)


def test_an_entity_build_error_carries_its_location_as_fields(tmp_path):
    """A parameter refused when the world is built names its file, line, key and entity as JSON fields."""
    scene = tmp_path / "bad.toml"
    scene.write_text('[[entities]]\ntype = "Box"\nname = "b"\ndimensions = [0.1, 0.1, 0.1]\nmass = -2.0\n')
    result = _run(simrun_main, ["check", scene, "--json"])
    assert result.exit_code == EXIT_INPUT
    error = json.loads(result.stdout)["error"]
    assert (error["path"], error["line"], error["key"], error["entity"]) == (str(scene), 5, "entities[0]", "b")
    assert error["message"] == f"{scene}:5: entities[0] 'b': mass must be a positive number, got -2.0"
    assert result.stderr.strip() == f"error: {error['message']}"


def test_a_sensor_that_cannot_bind_carries_its_location_as_fields(tmp_path):
    """Wheel encoders on a box (no wheel joints) fail when bound: the error points at the [[sensors]] table."""
    scene = tmp_path / "sensor.toml"
    scene.write_text(
        '[[entities]]\ntype = "Box"\nname = "b"\ndimensions = [0.1, 0.1, 0.1]\n\n'
        '[[sensors]]\ntype = "Encoders"\nname = "enc"\nentity = "b"\nrate = 10\n'
    )
    result = _run(simrun_main, ["check", scene, "--json"])
    assert result.exit_code == EXIT_INPUT
    error = json.loads(result.stdout)["error"]
    assert (error["path"], error["line"], error["key"], error["entity"]) == (str(scene), 6, "sensors[0]", "enc")
    assert error["message"].startswith(f"{scene}:6: sensors[0] 'enc': cannot read 'b': ")
