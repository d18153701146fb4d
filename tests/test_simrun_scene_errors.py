"""Issue 14 item 4: every mistake in a scene is one line `FILE:LINE: entities[k] 'name': what` from `simrun check`,
whether it is found while reading, building (an entity's own check) or binding (services and sensors)."""

from pathlib import Path

import pytest
from click.testing import CliRunner

from simrun.cli.main import main

SCENES = Path(__file__).resolve().parent.parent / "fixtures" / "scenes"
BASE = """[world]
timestep = 0.002

[[entities]]
type = "Ground"
name = "ground"

[[entities]]
type = "BoeBot"
name = "bot"
pose = { position = [0.0, 0.0, 0.001] }

[[entities]]
type = "Box"
name = "box"
free = true
mass = 1.0
pose = { position = [0.5, 0.0, 0.05] }
"""
# line 13 is the box's [[entities]], 15 `name = "box"`, 16 `free = true`, 17 `mass = 1.0`, 18 the pose; appended
# text starts with a blank line 19

MISTAKES = [
    # (kind, replace (old, new) in BASE or None, appended text, expected line, key and name, message)
    (
        "negative mass (found when built)",
        ("mass = 1.0", "mass = -100.0"),
        "",
        17,
        "entities[2] 'box'",
        "mass must be a positive number, got -100.0",
    ),
    (
        "unknown key",
        ("free = true", "colour = [1.0, 0.0, 0.0, 1.0]"),
        "",
        16,
        "entities[2] 'box'",
        "colour: unknown key (known: type, name, parent, pose, free, kinematic, mass, density, color, texture, "
        "material, dimensions)",
    ),
    (
        "wrong type",
        ("mass = 1.0", 'mass = "heavy"'),
        "",
        17,
        "entities[2] 'box'",
        "mass: expected a finite number, got 'heavy'",
    ),
    (
        "missing texture",
        ("mass = 1.0", 'texture = "missing.png"'),
        "",
        17,
        "entities[2] 'box'",
        "texture: 'missing.png' cannot be read: No such file or directory",
    ),
    (
        "missing mesh",
        None,
        '\n[[entities]]\ntype = "MeshEntity"\nname = "mug"\nasset = "mug.mbin"\n',
        23,
        "entities[3] 'mug'",
        "asset: 'mug.mbin' cannot be read: No such file or directory",
    ),
    (
        "misspelt entity type",
        ('type = "Box"', 'type = "Bocks"'),
        "",
        14,
        "entities[2] 'box'",
        "type: unknown entity type 'Bocks'",
    ),
    (
        "unknown parent",
        ("free = true", 'parent = "table"'),
        "",
        13,
        "entities[2] 'box'",
        "parent 'table' does not exist; insert the parent first",
    ),
    (
        "bad quaternion",
        ("pose = { position = [0.5, 0.0, 0.05] }", "pose = { orientation = [1.0, 1.0, 0.0, 0.0] }"),
        "",
        18,
        "entities[2] 'box'",
        "pose: orientation must be a unit quaternion",
    ),
    (
        "misspelt service type",
        None,
        '\n[[services]]\ntype = "DriveServce"\nentity = "bot"\n',
        21,
        "services[0] 'DriveServce'",
        "type: unknown service type 'DriveServce' (known: DriveService, ArmService, JointService)",
    ),
    (
        "service bound to the wrong entity",
        None,
        '\n[[services]]\ntype = "DriveService"\nentity = "box"\n',
        20,
        "services[0] 'DriveService'",
        "'box' is a Box, not a differential-drive robot",
    ),
    (
        "sensor bound to a missing entity",
        None,
        '\n[[sensors]]\ntype = "IMU"\nname = "imu"\nentity = "robot"\n',
        23,
        "sensors[0] 'imu'",
        "entity: no entity named 'robot'",
    ),
    (
        "sensor that cannot read its entity",
        None,
        '\n[[sensors]]\ntype = "Encoders"\nname = "enc"\nentity = "box"\n',
        20,
        "sensors[0] 'enc'",
        "cannot read 'box': Invalid name 'box/left_wheel'",
    ),
]


@pytest.mark.parametrize(("kind", "replace", "extra", "line", "key", "message"), MISTAKES, ids=[m[0] for m in MISTAKES])
def test_scene_mistake_is_one_line_with_file_line_and_entity(tmp_path, kind, replace, extra, line, key, message):
    text = BASE
    if replace:
        assert replace[0] in text
        text = text.replace(replace[0], replace[1])
    path = tmp_path / "scene.toml"
    path.write_text(text + extra)
    result = CliRunner().invoke(main, ["check", str(path)])
    assert result.exit_code == 1 and "Traceback" not in result.output, result.output
    lines = result.stderr.splitlines()
    assert len(lines) == 1, lines
    assert lines[0].startswith(f"error: {path}:{line}: {key}: {message}"), lines[0]


def test_the_base_scene_is_fine(tmp_path):
    path = tmp_path / "scene.toml"
    path.write_text(BASE + '\n[[services]]\ntype = "DriveService"\nentity = "bot"\n')
    result = CliRunner().invoke(main, ["check", str(path)])
    assert result.exit_code == 0, result.output


def test_fixture_scenes_all_check():
    for scene in ("basic.toml", "boebot.toml", "pioneer_room.toml", "head_on_table.toml"):
        result = CliRunner().invoke(main, ["check", str(SCENES / scene), "--seconds", "0.2"])
        assert result.exit_code == 0, (scene, result.output)


@pytest.mark.parametrize(
    ("table", "line", "expected"),
    [
        (
            'tpye = "Box"\nname = "b"\ndimensions = [0.1, 0.1, 0.1]\n',
            2,
            "tpye: unknown key (an entity needs 'type', one of: Box, ",
        ),
        ('type = "Box"\nname = "b"\ndimenssions = [0.1, 0.1, 0.1]\n', 4, "did you mean 'dimensions'?"),
        ('type = "Boxx"\nname = "b"\n', 2, "type: unknown entity type 'Boxx' (known: "),
        ('name = "b"\n', 1, "missing key 'type' (one of: Box, "),
    ],
    ids=["misspelt-type-key", "misspelt-key", "misspelt-type", "no-type"],
)
def test_a_misspelt_key_is_named_at_its_own_line_with_the_closest_known_key(
    tmp_path: Path, table: str, line: int, expected: str
) -> None:
    """``tpye = "MeshEntity"`` said ``type: unknown entity type None`` at the table header (issue 26)."""
    from simrun.errors import SceneError
    from simrun.scene.scene_file import load_scene

    scene = tmp_path / "s.toml"
    scene.write_text("[[entities]]\n" + table)
    with pytest.raises(SceneError) as info:
        load_scene(scene)
    assert info.value.line == line, str(info.value)
    assert expected in str(info.value)
    if "tpye" in table:
        assert str(info.value).endswith("did you mean 'type'?")


def test_an_integer_too_long_for_python_is_one_error_line(tmp_path: Path) -> None:
    """A 5,000-digit integer made tomllib raise a plain ValueError (exit 3; the fuzzer's commands crash)."""
    from bounded import run_bounded

    scene = tmp_path / "s.toml"
    scene.write_text('[[entities]]\ntype = "Box"\nname = "b"\n')
    commands = tmp_path / "c.commands.toml"
    commands.write_text(f'[[commands]]\nt = {"9" * 5000}\nentity = "b"\ncall = "all_stop"\n')
    out = run_bounded(["simrun", "play", str(scene), "--commands", str(commands), "--duration", "0.1"])
    assert out.code == 1 and "Traceback" not in out.err
    assert out.err.startswith(f"error: {commands}: a number in it is too long (exceeds the limit (4300 digits)")
    assert out.err.count("\n") == 1
