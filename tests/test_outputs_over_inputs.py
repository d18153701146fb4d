"""Outputs never over inputs, in simrun too (issue 42 item 0).

Every simrun output command (``snapshot``, ``play --record/--video``, ``serve --record``, ``export``, the
``replay`` exports) is aimed at each kind of file a scene reads: its texture, its ``.mbin`` mesh, the MJCF
model of its ``MjcfRobot``, the OBJ mesh that model names (read for MuJoCo by the MJCF reader), its commands
file and the scene itself. Each must exit 1 with one ``error:`` line naming the output, the input and how the
output names it, before anything is written: the file keeps its bytes and the folder gains no file (no
partial output, no temporary file). Ground truth is the files on disk, hashed before and after.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from meshtool.files.outdir import how_same
from simrun.cli.main import main as simrun_main

FIXTURES = Path(__file__).resolve().parent.parent / "fixtures"
SIMRUN = str(Path(sys.executable).parent / "simrun")

SCENE = """\
[world]
timestep = 0.002

[assets]
head = "head.mbin"

[[entities]]
type = "Ground"
name = "ground"

[[entities]]
type = "Sphere"
name = "globe"
radius = 0.15
texture = "globe.png"
pose = { position = [0.6, 0.0, 0.5] }

[[entities]]
type = "MeshEntity"
name = "head"
asset = "head"
pose = { position = [1.0, 1.0, 0.2] }

[[entities]]
type = "MjcfRobot"
name = "arm"
file = "arm/arm.xml"

[[services]]
type = "JointService"
entity = "arm"

[test]
duration = 0.1
commands = "scene.commands.toml"
"""

COMMANDS = """\
[[commands]]
t = 0.02
service = "JointService"
entity = "arm"
call = "move_to"
args = [["shoulder"], [0.2], 0.05]
"""

#: Each kind of file the scene reads, by its path in the scene folder.
TARGETS = {
    "texture": "globe.png",
    "mbin-mesh": "head.mbin",
    "mjcf": "arm/arm.xml",
    "mjcf-mesh": "arm/meshes/gripper.obj",
    "commands": "scene.commands.toml",
    "scene": "scene.toml",
}

PLAY = ["play", "scene.toml", "--duration", "0.05", "--commands", "scene.commands.toml"]
#: Every output command, with ``{}`` where the output path goes (run in the scene folder).
OUTPUTS = {
    "snapshot": ["snapshot", "scene.toml", "-o", "{}"],
    "play --record": [*PLAY, "--record", "{}"],
    "play --video": [*PLAY, "--video", "{}"],
    "export --mjcf": ["export", "scene.toml", "--mjcf", "{}"],
    "export --mjz": ["export", "scene.toml", "--mjz", "{}"],
    "export --usd": ["export", "scene.toml", "--usd", "{}"],
    "export --glb": ["export", "scene.toml", "--glb", "{}"],
    "replay --glb": ["replay", "run.simlog", "--glb", "{}"],
    "replay --gltf": ["replay", "run.simlog", "--gltf", "{}"],
    "replay --usd": ["replay", "run.simlog", "--usd", "{}"],
    "replay --html": ["replay", "run.simlog", "--html", "{}"],
    "replay --mcap": ["replay", "run.simlog", "--mcap", "{}"],
    "replay --video": ["replay", "run.simlog", "--video", "{}"],
}


def _state(folder: Path) -> dict[str, str]:
    """Every file under ``folder`` (relative name) with the SHA-256 of its bytes."""
    return {
        p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file() and not p.is_symlink()
    }


@pytest.fixture(scope="module")
def scene_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A scene folder: texture, .mbin mesh, MJCF arm (with its OBJ mesh), commands file, and a recording of it."""
    folder = tmp_path_factory.mktemp("scene")
    shutil.copy(FIXTURES / "scenes" / "globe.png", folder)
    shutil.copy(FIXTURES / "scenes" / "head.mbin", folder)
    shutil.copytree(FIXTURES / "mjcf" / "arm", folder / "arm")
    (folder / "scene.toml").write_text(SCENE)
    (folder / "scene.commands.toml").write_text(COMMANDS)
    done = _simrun(folder, [*PLAY, "--record", "run.simlog"])
    assert done.exit_code == 0, done.output
    return folder


def _simrun(folder: Path, args: list[str]):  # type: ignore[no-untyped-def]
    here = Path.cwd()
    os.chdir(folder)
    try:
        return CliRunner().invoke(simrun_main, args)
    finally:
        os.chdir(here)


def _refused(result, output: str, source: Path, how: str) -> None:  # type: ignore[no-untyped-def]
    """Exit 1 and one ``error:`` line naming the output, the input it would replace and how."""
    lines = result.stderr.splitlines()
    assert result.exit_code == 1, result.output
    assert len(lines) == 1 and lines[0].startswith(f"error: {output}: is an input ("), lines
    assert str(source) in lines[0] and how in lines[0], lines
    assert "Traceback" not in result.output


@pytest.mark.parametrize("kind", list(TARGETS))
@pytest.mark.parametrize("command", list(OUTPUTS))
def test_output_aimed_at_an_input_is_refused(scene_dir: Path, command: str, kind: str) -> None:
    target = TARGETS[kind]
    before = _state(scene_dir)
    args = [a.replace("{}", target) for a in OUTPUTS[command]]
    result = _simrun(scene_dir, args)
    _refused(result, target, Path(target).name, "the same path")
    assert _state(scene_dir) == before  # the input untouched, nothing written beside it


@pytest.mark.parametrize("kind", list(TARGETS))
def test_serve_record_aimed_at_an_input_is_refused(scene_dir: Path, kind: str) -> None:
    """``simrun serve --record`` (a real server process) refuses at start, before the spool file is made."""
    target = TARGETS[kind]
    before = _state(scene_dir)
    done = subprocess.run(
        [SIMRUN, "serve", "scene.toml", "--port", "0", "--lockstep", "--record", target],
        cwd=scene_dir,
        capture_output=True,
        text=True,
        timeout=120,
    )
    lines = done.stderr.splitlines()
    assert done.returncode == 1, done.stderr
    assert len(lines) == 1 and lines[0].startswith("error: ") and "is an input (" in lines[0], lines
    assert Path(target).name in lines[0] and "the same path" in lines[0], lines
    assert _state(scene_dir) == before


@pytest.mark.parametrize(
    "command", ["snapshot", "play --record", "play --video", "export --mjcf", "export --glb", "replay --glb"]
)
@pytest.mark.parametrize("link", ["symbolic", "hard"])
def test_links_to_an_input_are_refused(scene_dir: Path, tmp_path: Path, command: str, link: str) -> None:
    """An output named by a link to the texture or to the MJCF's mesh: refused, the link and the file kept."""
    for source, name in ((scene_dir / "globe.png", "alias.png"), (scene_dir / "arm/meshes/gripper.obj", "alias.obj")):
        alias = tmp_path / f"{link}-{command.replace(' ', '')}-{name}"
        if link == "symbolic":
            alias.symlink_to(source)
        else:
            os.link(source, alias)
        before, linked = _state(scene_dir), os.lstat(alias)
        result = _simrun(scene_dir, [a.replace("{}", str(alias)) for a in OUTPUTS[command]])
        how = "a symbolic link to it" if link == "symbolic" else "a hard link to it"
        _refused(result, str(alias), source, how)
        assert _state(scene_dir) == before
        after = os.lstat(alias)
        assert (after.st_ino, after.st_mode, after.st_size) == (linked.st_ino, linked.st_mode, linked.st_size)


def test_case_alias_is_refused(scene_dir: Path, tmp_path: Path) -> None:
    """On a case-insensitive file system, ``GLOBE.PNG`` is the scene's ``globe.png``."""
    probe = tmp_path / "probe"
    probe.write_text("x")
    if not (tmp_path / "PROBE").exists():
        pytest.skip("this file system is case-sensitive: GLOBE.PNG is another file here")
    before = _state(scene_dir)
    _refused(_simrun(scene_dir, ["snapshot", "scene.toml", "-o", "GLOBE.PNG"]), "GLOBE.PNG", "globe.png", "")
    assert _state(scene_dir) == before


def test_nothing_is_written_when_a_later_output_is_an_input(scene_dir: Path) -> None:
    """With several outputs, one aimed at an input stops all of them before the first is written."""
    before = _state(scene_dir)
    result = _simrun(scene_dir, ["export", "scene.toml", "--mjcf", "out/ok.xml", "--glb", "globe.png"])
    _refused(result, "globe.png", "globe.png", "the same path")
    result = _simrun(scene_dir, ["replay", "run.simlog", "--mcap", "ok.mcap", "--glb", "ok.glb", "--usd", "globe.png"])
    _refused(result, "globe.png", "globe.png", "the same path")
    result = _simrun(scene_dir, [*PLAY, "--record", "ok.simlog", "--record-as", "glb", "--video", "arm/arm.xml"])
    _refused(result, "arm/arm.xml", "arm.xml", "the same path")
    assert _state(scene_dir) == before


def test_mjcf_export_beside_an_input_is_refused(tmp_path: Path) -> None:
    """``export --mjcf`` writes textures beside the XML (``0_texture_globe.png`` for ``globe.png``): one that is a
    texture the scene reads is refused, ``--force`` or not, before the XML or any other file is written."""
    shutil.copy(FIXTURES / "scenes" / "globe.png", tmp_path / "globe.png")
    shutil.copy(FIXTURES / "scenes" / "globe.png", tmp_path / "0_texture_globe.png")
    (tmp_path / "s.toml").write_text(
        '[[entities]]\ntype = "Sphere"\nname = "globe"\nradius = 0.15\ntexture = "globe.png"\n\n'
        '[[entities]]\ntype = "Sphere"\nname = "other"\nradius = 0.1\ntexture = "0_texture_globe.png"\n'
        "pose = { position = [1.0, 0.0, 0.5] }\n"
    )
    before = _state(tmp_path)
    for extra in ([], ["--force"]):
        result = _simrun(tmp_path, ["export", "s.toml", "--mjcf", "out.xml", *extra])
        _refused(result, "0_texture_globe.png", tmp_path / "0_texture_globe.png", "the same path")
        assert _state(tmp_path) == before


@pytest.mark.parametrize("command", ["play --record", "play --video", "export --mjcf", "export --mjz", "replay --glb"])
def test_force_never_replaces_an_input(scene_dir: Path, command: str) -> None:
    before = _state(scene_dir)
    for target in ("globe.png", "arm/arm.xml"):
        result = _simrun(scene_dir, [*(a.replace("{}", target) for a in OUTPUTS[command]), "--force"])
        _refused(result, target, Path(target).name, "the same path")
    assert _state(scene_dir) == before


def test_how_same_names_each_kind(tmp_path: Path) -> None:
    """meshtool's rule: the same path, a symbolic link, a hard link; different files are not the same."""
    a = tmp_path / "a.png"
    a.write_bytes(b"x")
    (tmp_path / "sym.png").symlink_to(a)
    os.link(a, tmp_path / "hard.png")
    (tmp_path / "other.png").write_bytes(b"x")
    assert how_same(a, tmp_path / "." / "a.png") == "the same path"
    assert how_same(tmp_path / "sym.png", a) == "a symbolic link to it"
    assert how_same(tmp_path / "hard.png", a) == "a hard link to it"
    assert how_same(tmp_path / "other.png", a) is None
    assert how_same(tmp_path / "missing.png", a) is None


def test_play_frames_over_an_input_are_refused(tmp_path: Path) -> None:
    """``play --frames DIR`` writes ``frame_00000.png``...: a texture of that name in DIR is refused before frame 0."""
    shutil.copy(FIXTURES / "scenes" / "globe.png", tmp_path / "frame_00001.png")
    (tmp_path / "s.toml").write_text(
        '[[entities]]\ntype = "Sphere"\nname = "globe"\nradius = 0.15\ntexture = "frame_00001.png"\n'
    )
    before = _state(tmp_path)
    result = _simrun(tmp_path, ["play", "s.toml", "--duration", "0.2", "--frames", ".", "--render-mode", "visual"])
    _refused(result, "frame_00001.png", tmp_path / "frame_00001.png", "the same path")
    assert _state(tmp_path) == before
