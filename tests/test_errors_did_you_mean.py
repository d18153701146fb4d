"""One "did you mean" (issue 37 item 2): simrun.errors.did_you_mean, used by scene keys and types, sensor
bodies and commands files' entities alike."""

import ast
from pathlib import Path

import pytest

from simrun.errors import SceneError, SimrunError, did_you_mean

SIMRUN = Path(__file__).resolve().parent.parent / "simrun"


@pytest.mark.parametrize(
    ("word", "known", "hint"),
    [
        ("ray", ["rate", "rays", "noise"], "; did you mean 'rays'?"),
        ("dimenssions", ("mass", "dimensions"), "; did you mean 'dimensions'?"),
        ("zzz", ["rays", "rate"], ""),
        ("lsaer", iter(["gps", "laser"]), "; did you mean 'laser'?"),  # any iterable
        (3, ["3", "4"], "; did you mean '3'?"),  # compared as text
        ("x", [], ""),
    ],
)
def test_the_closest_known_name_or_nothing(word, known, hint):
    assert did_you_mean(word, known) == hint


def test_no_other_module_matches_names_itself():
    """Only simrun/errors.py imports difflib: every other "did you mean" goes through did_you_mean."""
    importers = []
    for path in sorted(SIMRUN.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            names = (
                [a.name for a in node.names]
                if isinstance(node, ast.Import)
                else [node.module or ""]
                if isinstance(node, ast.ImportFrom)
                else []
            )
            if "difflib" in names:
                importers.append(str(path.relative_to(SIMRUN)))
    assert importers == ["errors.py"]


def test_a_commands_file_names_the_closest_entity(tmp_path):
    from simrun import load_scene
    from simrun.run.commands import check_commands, load_commands

    (tmp_path / "s.toml").write_text(
        '[[entities]]\ntype = "BoeBot"\nname = "bot"\n\n[[services]]\ntype = "DriveService"\nentity = "bot"\n'
    )
    (tmp_path / "c.toml").write_text('[[commands]]\nt = 0.0\nentity = "bto"\ncall = "all_stop"\n')
    world = load_scene(tmp_path / "s.toml")
    with pytest.raises(SimrunError) as info:
        check_commands(world, load_commands(tmp_path / "c.toml"))
    assert str(info.value).endswith("entity: no entity 'bto' in the scene (entities: bot); did you mean 'bot'?")
    assert ":3: commands[0]" in str(info.value)


def test_a_scene_type_and_key_name_the_closest(tmp_path):
    from simrun import load_scene

    path = tmp_path / "s.toml"
    path.write_text('[[entities]]\ntype = "BoeBot"\nname = "bot"\nwheel_radiu = 0.03\n')
    with pytest.raises(SceneError, match=r"s\.toml:4: entities\[0\] 'bot': wheel_radiu: unknown key \(known: .*\); "
                       r"did you mean 'wheel_radius'\?$"):  # fmt: skip
        load_scene(path)
    path.write_text('[[entities]]\ntype = "BoeBott"\nname = "bot"\n')
    with pytest.raises(SceneError, match=r"unknown entity type 'BoeBott' \(known: .*\); did you mean 'BoeBot'\?$"):
        load_scene(path)
