"""Never destroy what meshtool did not write: -o refuses inputs always, and foreign files unless --force."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import pytest
from click.testing import CliRunner

from meshtool.cli.main import main, obj2bin
from meshtool.errors import OutputError
from meshtool.files.outdir import MARKER_KEY, check_output, replaceable_folder, write_folder

HEAD = Path("head") / "Head 1.obj"


def run(cmd, *args):
    return CliRunner().invoke(cmd, [str(a) for a in args], catch_exceptions=False)


def refused(result, words):
    """Exit 1, one ``error:`` line containing ``words``, no traceback."""
    lines = result.stderr.splitlines()
    assert result.exit_code == 1, result.output
    assert len(lines) == 1 and lines[0].startswith("error: ") and words in lines[0], lines
    assert "Traceback" not in result.output
    return lines[0]


@pytest.fixture
def head(fixtures, tmp_path):
    """A copy of the seed head (OBJ, MTL, BMP) in a folder of its own."""
    folder = tmp_path / "src"
    shutil.copytree(fixtures / "head", folder)
    return folder / "Head 1.obj"


@pytest.fixture
def packed(head, tmp_path):
    out = tmp_path / "head.mbin"
    assert run(obj2bin, head, "--units", "cm", "-o", out).exit_code == 0
    return out


# ------------------------------------------------------------------------------------------------ inputs


def test_obj2bin_never_writes_over_its_source(head):
    before = head.read_bytes()
    for extra in ([], ["--force"]):
        line = refused(run(obj2bin, head, "-o", head, *extra), "is an input")
        assert str(head) in line
    assert head.read_bytes() == before


def test_an_input_is_refused_through_links_and_for_every_file_the_asset_uses(head, tmp_path):
    (tmp_path / "soft.mbin").symlink_to(head)
    os.link(head, tmp_path / "hard.mbin")
    mtl = head.with_suffix(".mtl")
    texture = head.with_suffix(".bmp")
    before = {p: p.read_bytes() for p in (head, mtl, texture)}
    for target in (tmp_path / "soft.mbin", tmp_path / "hard.mbin", mtl, texture):
        refused(run(obj2bin, head, "--units", "cm", "-o", target, "--force"), "is an input")
    assert {p: p.read_bytes() for p in before} == before


def test_case_insensitive_alias_is_the_same_file(head, tmp_path):
    """On a case-insensitive file system HEAD 1.OBJ is the same inode; samefile is what decides."""
    alias = head.with_name("HEAD 1.OBJ")
    if not alias.exists():
        os.link(head, alias)  # a case-sensitive file system: make the alias a hard link, same inode
    with pytest.raises(OutputError, match="is an input"):
        check_output(alias, "mbin", force=True, inputs=[head])


# ------------------------------------------------------------------------------------------------ files


def test_obj2bin_refuses_a_foreign_file_unless_forced(head, tmp_path):
    notes = tmp_path / "notes.mbin"
    notes.write_text("my notes\n")
    refused(run(obj2bin, head, "--units", "cm", "-o", notes), "is not a meshtool mbin output")
    assert notes.read_text() == "my notes\n"
    assert run(obj2bin, head, "--units", "cm", "-o", notes, "--force").exit_code == 0
    assert notes.read_bytes()[:4] == b"\x89MBN"


def test_obj2bin_replaces_its_own_output(packed, head):
    first = packed.read_bytes()
    result = run(obj2bin, head, "--units", "mm", "-o", packed)
    assert result.exit_code == 0, result.output
    assert packed.read_bytes() != first


def test_folder_mode_refuses_foreign_files_per_asset(fixtures, tmp_path):
    src = tmp_path / "tree"
    shutil.copytree(fixtures / "multi_material", src / "a")
    shutil.copytree(fixtures / "bowl", src / "b")
    out = tmp_path / "out"
    (out / "a").mkdir(parents=True)
    (out / "a" / "crate.mbin").write_text("precious")
    result = run(obj2bin, src, "-o", out, "-j", "1")
    assert result.exit_code == 1
    errors = [line for line in result.stderr.splitlines() if line.startswith("error: ")]
    assert len(errors) == 1 and "is not a meshtool mbin output" in errors[0]
    assert (out / "a" / "crate.mbin").read_text() == "precious"
    assert (out / "b" / "bowl.mbin").read_bytes()[:4] == b"\x89MBN"
    assert run(obj2bin, src, "-o", out, "--force").exit_code == 0
    assert (out / "a" / "crate.mbin").read_bytes()[:4] == b"\x89MBN"


@pytest.mark.parametrize(("flag", "name"), [("--glb", "x.glb"), ("--msh", "x.msh"), ("--usd", "x.usda")])
def test_export_refuses_foreign_files_and_replaces_its_own(packed, tmp_path, flag, name):
    target = tmp_path / name
    target.write_text("#usda 1.0\n(\n)\n" if flag == "--usd" else "mine")
    before = target.read_bytes()
    refused(run(main, "export", packed, flag, target), "not replacing it")
    assert target.read_bytes() == before
    assert run(main, "export", packed, flag, target, "--force").exit_code == 0
    assert run(main, "export", packed, flag, target).exit_code == 0  # its own output: replaced again
    for extra in ([], ["--force"]):
        refused(run(main, "export", packed, flag, packed, *extra), "is an input")
    assert packed.read_bytes()[:4] == b"\x89MBN"


def test_a_glb_from_another_tool_is_not_replaced(packed, tmp_path):
    import trimesh

    other = tmp_path / "other.glb"
    scene = trimesh.Scene()
    scene.add_geometry(trimesh.creation.box())
    other.write_bytes(scene.export(file_type="glb"))  # generator: trimesh's, not meshtool's
    refused(run(main, "export", packed, "--glb", other), "is not a meshtool glb output")


def test_usd_export_does_not_overwrite_a_users_texture_beside_it(packed, tmp_path):
    user_png = tmp_path / "head_1.png"
    user_png.write_bytes(b"\x89PNG\r\n\x1a\n my own picture")
    refused(run(main, "export", packed, "--usd", tmp_path / "x.usda"), "head_1.png")
    assert user_png.read_bytes().endswith(b"my own picture") and not (tmp_path / "x.usda").exists()
    user_png.unlink()
    assert run(main, "export", packed, "--usd", tmp_path / "x.usda").exit_code == 0
    assert run(main, "export", packed, "--usd", tmp_path / "x.usda").exit_code == 0  # same PNG bytes: fine


# ------------------------------------------------------------------------------------------------ folders


def test_normalize_never_deletes_a_folder_that_merely_holds_an_asset_json(head, tmp_path):
    mine = tmp_path / "out" / "head_1"
    mine.mkdir(parents=True)
    (mine / "asset.json").write_text("{}")
    (mine / "thesis.tex").write_text("years of work")
    refused(run(main, "normalize", head, "-o", tmp_path / "out"), "not replacing it")
    (mine / "thesis.tex").unlink()
    refused(run(main, "normalize", head, "-o", tmp_path / "out"), "no meshtool marker")
    assert (mine / "asset.json").read_text() == "{}"
    assert run(main, "normalize", head, "-o", tmp_path / "out", "--force").exit_code == 0
    assert json.loads((mine / "asset.json").read_text())[MARKER_KEY]["files"] == [
        "asset.json",
        "head_1.mtl",
        "head_1.obj",
        "head_1.png",
    ]


def test_a_meshtool_folder_is_replaced_only_while_it_holds_nothing_else(head, tmp_path):
    assert run(main, "normalize", head, "-o", tmp_path, "--units", "cm").exit_code == 0
    folder = tmp_path / "head_1"
    marker = json.loads((folder / "asset.json").read_text())[MARKER_KEY]
    assert marker["tool"] == "meshtool" and marker["version"]
    assert run(main, "normalize", head, "-o", tmp_path, "--units", "mm").exit_code == 0
    (folder / "notes.txt").write_text("mine")
    refused(run(main, "normalize", head, "-o", tmp_path), "holds files meshtool did not write (notes.txt)")
    assert (folder / "notes.txt").read_text() == "mine"


def test_an_older_normalize_folder_without_the_marker_is_replaced(head, tmp_path):
    assert run(main, "normalize", head, "-o", tmp_path).exit_code == 0
    manifest_path = tmp_path / "head_1" / "asset.json"
    manifest = json.loads(manifest_path.read_text())
    del manifest[MARKER_KEY]  # what meshtool 0.1 wrote before the marker: tool + files
    manifest_path.write_text(json.dumps(manifest))
    assert replaceable_folder(tmp_path / "head_1") is None
    assert run(main, "normalize", head, "-o", tmp_path, "--units", "cm").exit_code == 0
    manifest["tool"] = "someone else"
    manifest_path.write_text(json.dumps(manifest))
    assert replaceable_folder(tmp_path / "head_1") is not None


def test_unpack_and_mjcf_write_the_marker_and_never_replace_a_folder_holding_the_input(packed, tmp_path):
    assert run(main, "unpack", packed, "-o", tmp_path / "u").exit_code == 0
    assert run(main, "unpack", packed, "-o", tmp_path / "u").exit_code == 0  # its own folder: replaced
    assert MARKER_KEY in json.loads((tmp_path / "u" / "head" / "asset.json").read_text())
    inside = tmp_path / "u" / "head" / "head.mbin"
    shutil.copy(packed, inside)
    for extra in ([], ["--force"]):
        refused(run(main, "unpack", inside, "-o", tmp_path / "u", *extra), "holding an input")
    assert inside.is_file()
    assert run(main, "mjcf", packed, "-o", tmp_path / "m").exit_code == 0
    assert run(main, "mjcf", packed, "-o", tmp_path / "m").exit_code == 0
    refused(run(main, "mjcf", inside, "-o", tmp_path / "u", "--force"), "holding an input")


def test_write_folder_refuses_links_and_files_in_place_of_the_folder(tmp_path):
    (tmp_path / "real").mkdir()
    (tmp_path / "link").symlink_to(tmp_path / "real")
    (tmp_path / "file").write_text("x")
    for name in ("link", "file"):
        with pytest.raises(OutputError, match="not a folder"):
            write_folder(tmp_path, name, {"asset.json": b"{}"})
    assert (tmp_path / "file").read_text() == "x" and (tmp_path / "link").is_symlink()


# ------------------------------------------------------------------------------------------------ simrun


def test_simrun_writer_applies_the_same_rules(tmp_path):
    from simrun.errors import SimrunError
    from simrun.outfile import output_policy, write_bytes, write_text

    scene = tmp_path / "scene.toml"
    scene.write_text("[world]\n")
    user = tmp_path / "model.glb"
    user.write_text("not mine")
    with output_policy(force=True, inputs=[scene]), pytest.raises(SimrunError, match="is an input"):
        write_text(scene, "<mujoco/>")
    assert scene.read_text() == "[world]\n"
    with pytest.raises(SimrunError, match="not replacing it"):
        write_bytes(user, b"glTF")
    with output_policy(force=True):
        write_bytes(user, b"glTF")
    assert user.read_bytes() == b"glTF"
    notes = tmp_path / "notes.xml"
    notes.write_text("<notes>mine</notes>")
    with pytest.raises(SimrunError, match="not replacing it"):
        write_text(notes, "<mujoco/>")
    mjcf = tmp_path / "model.xml"
    write_text(mjcf, '<mujoco model="a"/>')
    write_text(mjcf, '<mujoco model="b"/>')  # an MJCF: the same kind, replaced
    assert "b" in mjcf.read_text()


def test_simrun_export_and_play_refuse_foreign_files_and_inputs(fixtures, tmp_path):
    from simrun.cli.main import main as simrun

    for name in ("basic.toml", "globe.png"):
        shutil.copy(fixtures / "scenes" / name, tmp_path / name)
    scene = tmp_path / "basic.toml"
    before = scene.read_bytes()
    user = tmp_path / "mine.glb"
    user.write_text("mine")
    refused(run(simrun, "export", scene, "--glb", user), "not replacing it")
    assert user.read_text() == "mine"
    assert run(simrun, "export", scene, "--glb", user, "--force").exit_code == 0
    assert run(simrun, "export", scene, "--glb", user).exit_code == 0  # simrun's own GLB now: replaced
    for extra in ([], ["--force"]):
        refused(run(simrun, "export", scene, "--usd", scene.with_suffix(".usda"), "--mjz", scene, *extra), "input")
    assert scene.read_bytes() == before
    log = tmp_path / "notes.simlog"
    log.write_text("field notes")
    refused(run(simrun, "play", scene, "--duration", "0.01", "--record", log), "not replacing it")
    assert log.read_text() == "field notes"
    assert run(simrun, "play", scene, "--duration", "0.01", "--record", log, "--force").exit_code == 0
    assert run(simrun, "play", scene, "--duration", "0.01", "--record", log).exit_code == 0  # a .simlog now


def test_a_meshtool_folder_with_a_file_edited_in_place_is_not_replaced(head, tmp_path):
    assert run(main, "normalize", head, "-o", tmp_path, "--units", "cm").exit_code == 0
    obj = tmp_path / "head_1" / "head_1.obj"
    obj.write_text(obj.read_text() + "# my hand edit\n")
    refused(run(main, "normalize", head, "-o", tmp_path), "changed since meshtool wrote them (head_1.obj)")
    assert obj.read_text().endswith("# my hand edit\n")
    assert run(main, "normalize", head, "-o", tmp_path, "--force").exit_code == 0
