"""The formats registry (meshtool/formats.py) is the one table of formats (issue 26, item 2).

- ``docs/formats.md`` ("Formats registry") is the registry's tables, row for row;
- every reader has the one signature and every writer and recogniser named in a row exists;
- every recogniser says yes to a file the project's own writer wrote and (where the format has room for a
  stamp) no to a foreign file of the same suffix;
- a new mesh format is one reader module plus one row: registered, it is read by ``normalize``, found in
  folders by ``obj2bin`` and ``validate``, and accepted as a URDF mesh, with no other edit;
- a new output is one row: ``check_output`` replaces our file of that kind and refuses a foreign one;
- no registry suffix is written as a literal anywhere else in the packages' code.
"""

from __future__ import annotations

import ast
import importlib
import inspect
import io
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from meshtool import formats
from meshtool.errors import OutputError
from meshtool.files.outdir import check_output
from meshtool.formats import MESH_FORMATS, OUTPUTS, MeshFormat, OutputFormat, mesh_suffixes, register_mesh_format

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "formats.md"
HEAD = ROOT / "fixtures" / "head" / "Head 1.obj"
BOX = ROOT / "fixtures" / "scenes" / "boebot.toml"
MESHES = ROOT / "fixtures" / "scenes" / "head_on_table.toml"


def mesh_table() -> str:
    lines = ["| format | suffixes | up axis | unit | reader |", "|---|---|---|---|---|"]
    for row in MESH_FORMATS:
        up = {"evidence": f"evidence, else {row.fallback_up.upper()}-up", "spec": "Y-up (specification)"}.get(
            row.up, f"declared, else {row.fallback_up.upper()}-up"
        )
        unit = {"evidence": "evidence", "spec": "metres (specification)", "declared": "declared"}[row.units]
        if row.suggested_unit:
            unit += f" ({row.suggested_unit} suggested)"
        suffixes = ", ".join(f"`{s}`" for s in row.suffixes)
        lines.append(f"| {row.label} | {suffixes} | {up} | {unit} | `{row.reader}` |")
    return "\n".join(lines)


def output_table() -> str:
    lines = ["| output | suffixes | what | recognised as ours by | written by |", "|---|---|---|---|---|"]
    for row in OUTPUTS:
        suffixes = ", ".join(f"`{s}`" for s in row.suffixes)
        lines.append(f"| {row.name} | {suffixes} | {row.what} | {row.stamp} | `{row.writer}` |")
    return "\n".join(lines)


def test_the_document_is_the_registry() -> None:
    text = DOC.read_text(encoding="utf-8")
    assert mesh_table() in text, "docs/formats.md: regenerate the mesh formats table from meshtool/formats.py"
    assert output_table() in text, "docs/formats.md: regenerate the outputs table from meshtool/formats.py"


def test_no_suffix_is_in_two_rows() -> None:
    inputs = [s for row in MESH_FORMATS for s in row.suffixes]
    outputs = [s for row in OUTPUTS for s in row.suffixes]
    assert len(inputs) == len(set(inputs)) and len(outputs) == len(set(outputs))
    assert all(s == s.lower() and s.startswith(".") for s in (*inputs, *outputs))
    assert len({row.name for row in MESH_FORMATS}) == len(MESH_FORMATS)
    assert len({row.name for row in OUTPUTS}) == len(OUTPUTS)


@pytest.mark.parametrize("row", MESH_FORMATS, ids=lambda r: r.name)
def test_every_reader_has_the_one_signature(row: MeshFormat) -> None:
    assert list(inspect.signature(row.read()).parameters) == ["data", "path", "src", "resolver"]


@pytest.mark.parametrize("row", OUTPUTS, ids=lambda r: r.name)
def test_every_writer_and_recogniser_exists(row: OutputFormat) -> None:
    module, _, name = row.writer.partition(":")
    assert callable(getattr(importlib.import_module(module), name))
    assert callable(row.recogniser())


def _written(kind: str, tmp: Path) -> Path:
    """A file of ``kind`` written by the project's own writer."""
    from meshtool.packfile.export import to_glb, to_msh
    from meshtool.packfile.read import load
    from meshtool.packfile.usd import export_usd
    from meshtool.pipeline import ConvertOptions, convert
    from meshtool.repair.normalise import NormaliseOptions

    pack = tmp / "head.mbin"
    if not pack.exists():
        convert(HEAD, pack, ConvertOptions(NormaliseOptions(units="cm"), check=False))
    if kind == "mbin":
        return pack
    with load(pack) as packed:
        if kind == "glb":
            (tmp / "head.glb").write_bytes(to_glb(packed))
            return tmp / "head.glb"
        if kind == "msh":
            (tmp / "head.msh").write_bytes(to_msh(packed))
            return tmp / "head.msh"
        if kind == "usd":
            export_usd(packed, tmp / "head.usda", "head")
            return tmp / "head.usda"
    return _simrun_written(kind, tmp)


def _simrun_written(kind: str, tmp: Path) -> Path:
    from simrun.export.mjcf_builder import export_world_mjcf
    from simrun.record.replay_export import export_recording
    from simrun.run.play import encode_gif, encode_mp4
    from simrun.run.session import PlayOptions, run_play
    from simrun.scene.scene_file import load_scene
    from simrun.world.archive import save_mjz

    frames = [np.full((16, 16, 3), 40 * k, np.uint8) for k in range(3)]
    target = tmp / f"out{formats.suffix(kind)}"
    if kind == "gif":
        target.write_bytes(encode_gif(frames, 10.0))
    elif kind == "mp4":
        encode_mp4(frames, 10.0, target)
    elif kind == "png":
        buffer = io.BytesIO()
        Image.fromarray(frames[1]).save(buffer, format="PNG")
        target.write_bytes(buffer.getvalue())
    elif kind in ("mjz", "mjcf", "obj"):
        world = load_scene(MESHES)
        world.compile()
        if kind == "mjz":
            save_mjz(world, target)
        else:
            written = export_world_mjcf(world, tmp / "model" / "scene.xml")
            return next(p for p in written if p.suffix == formats.suffix(kind))  # an OBJ the export wrote
    else:  # recording and what it is exported to
        log = tmp / "run.simlog"
        if not log.exists():
            run_play(BOX, PlayOptions(duration=0.05, record=log))
        if kind == "simlog":
            return log
        if kind == "mcap":
            from simrun.record.mcap_export import export_mcap

            export_mcap(log, target)
            return target
        export_recording(log, {kind: target})
    return target


@pytest.mark.parametrize("row", OUTPUTS, ids=lambda r: r.name)
def test_every_recogniser_knows_our_files_and_only_ours(row: OutputFormat, tmp_path: Path) -> None:
    if row.name == "html":
        from simrun.record.replay_html import viewer_bundle

        try:
            viewer_bundle()
        except Exception as exc:  # the three.js bundle is installed by scripts/install_test_tools.sh
            pytest.skip(f"no viewer bundle for the HTML player: {exc}")
    ours = _written(row.name, tmp_path)
    assert row.recogniser()(ours, ours.stat().st_size)
    foreign = tmp_path / f"foreign{ours.suffix}"
    foreign.write_bytes(b"something a user made\n" * 4)
    assert not row.recogniser()(foreign, foreign.stat().st_size)
    check_output(ours, any_of_kind=True)  # ours is replaced without --force
    with pytest.raises(OutputError, match="not replacing it"):
        check_output(foreign, any_of_kind=True)
    if row.marked:  # a stamp tells ours apart: meshtool's own commands replace it too
        check_output(ours)


OFF_READER = """
from meshtool.read.source_mesh import Piece, SourceFrame, SourceMesh, assemble
import numpy as np


def read(data, path, src, resolver):
    words = data.decode().split()
    nv, nf = int(words[1]), int(words[2])
    at = 4
    positions = np.array(words[at : at + 3 * nv], float).reshape(nv, 3)
    at += 3 * nv
    faces = []
    for _ in range(nf):
        n = int(words[at])
        faces.append([int(w) for w in words[at + 1 : at + 1 + n]])
        at += 1 + n
    faces = np.array(faces, np.int64)
    piece = Piece("off", -1, positions, faces, np.arange(1, len(faces) + 1))
    frame = SourceFrame(None, "OFF has no unit", None, "OFF has no up axis")
    return assemble([piece], path, "off", "face", [], frame, [])
"""
OFF = "OFF\n4 4 0\n0 0 0\n0.1 0 0\n0 0.1 0\n0 0 0.1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n"


@pytest.fixture
def off_format(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> MeshFormat:
    """Object File Format, added as a plug-in would add it: one reader module and one row."""
    (tmp_path / "off_reader.py").write_text(OFF_READER)
    monkeypatch.syspath_prepend(str(tmp_path))
    return MeshFormat(
        "off", "OFF", (".off",), "off_reader:read", "evidence", "z", "OFF has no up axis; Z-up assumed", "evidence"
    )


def test_a_new_mesh_format_is_one_module_and_one_row(off_format: MeshFormat, tmp_path: Path) -> None:
    from meshtool.pipeline import tree_jobs
    from meshtool.repair.normalise import NormaliseOptions, prepare
    from meshtool.urdf.import_robot import import_urdf
    from meshtool.urdf.locate import MeshLocator
    from meshtool.validate.runner import suffixes

    models = tmp_path / "models"
    models.mkdir()
    (models / "tet.off").write_text(OFF)
    assert ".off" not in mesh_suffixes()
    with register_mesh_format(off_format):
        assert ".off" in mesh_suffixes() and ".off" in suffixes()
        asset = prepare(models / "tet.off", NormaliseOptions())
        assert asset.mesh.positions.shape[0] >= 4 and asset.mesh.faces.shape[0] == 4
        assert asset.manifest["sources"][0]["role"] == "off"
        found = [src.name for src, _ in tree_jobs(models, tmp_path / "packs")]
        assert found == ["tet.off"]
        urdf = models / "tet.urdf"
        urdf.write_text(
            '<robot name="tet"><link name="base"><visual><geometry><mesh filename="tet.off"/></geometry></visual>'
            '<collision><geometry><mesh filename="tet.off"/></geometry></collision></link></robot>'
        )
        assert MeshLocator(urdf, {}).read("tet.off", {"path": str(urdf), "line": 1}).data == OFF.encode()
        robot = import_urdf(urdf)
        assert robot.mbins, "the URDF import packs the OFF mesh like any other format"
    assert ".off" not in mesh_suffixes()


def test_a_new_output_is_one_row(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "ply_out.py").write_text(
        "def ours(path, size):\n    return open(path, 'rb').read(40).startswith(b'ply\\ncomment meshtool')\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    row = OutputFormat("ply", (".ply",), "PLY mesh", "meshtool", "ply_out:ours", "comment line", "ply_out:ours")
    monkeypatch.setattr(formats, "OUTPUTS", [*OUTPUTS, row])
    mine, theirs = tmp_path / "a.ply", tmp_path / "b.ply"
    mine.write_bytes(b"ply\ncomment meshtool 0.1\n")
    theirs.write_bytes(b"ply\ncomment blender\n")
    check_output(mine)
    with pytest.raises(OutputError, match="is not a meshtool ply output"):
        check_output(theirs)


_LITERAL = re.compile(r"""["'](\.[a-z0-9]+)["']""")


def test_registry_suffixes_are_written_in_the_registry_only() -> None:
    listed = subprocess.run(
        ["git", "ls-files", "meshtool/*.py", "meshtool/**/*.py", "simrun/*.py", "simrun/**/*.py"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split()
    known = {s for row in MESH_FORMATS for s in row.suffixes} | {s for row in OUTPUTS for s in row.suffixes}
    known.discard(".png")  # also the texture format of every reader and writer (meshtool/repair/textures.py): an input
    offenders = []
    for name in listed:
        if name == "meshtool/formats.py":
            continue
        for number, line in enumerate((ROOT / name).read_text(encoding="utf-8").splitlines(), 1):
            if line.lstrip().startswith("#"):
                continue
            hits = [s for s in _LITERAL.findall(line) if s in known]
            if hits:
                offenders.append(f"{name}:{number}: {', '.join(hits)}")
    assert not offenders, "suffixes outside meshtool/formats.py:\n" + "\n".join(offenders)


def test_the_registry_imports_nothing_of_the_project() -> None:
    prefixes = "('meshtool.', 'simrun')"
    code = f"import sys, meshtool.formats; print(sorted(m for m in sys.modules if m.startswith({prefixes})))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "['meshtool.formats']"


def _registered_suffixes() -> set[str]:
    return {
        *(s for row in MESH_FORMATS for s in row.suffixes),
        *(s for row in OUTPUTS for s in row.suffixes),
        *formats.DESCRIPTION_SUFFIXES,
        *formats.COMPANION_SUFFIXES,
        *formats.IMAGE_SUFFIXES.values(),
    }


def test_every_suffix_is_written_in_the_registry_only() -> None:
    """No module of either package spells a registered suffix (``".glb"``...): it asks meshtool/formats.py.

    Issue 26: a file suffix is found in one registry row (tests and docs aside), so adding or renaming a
    format is one edit.
    """
    registered = _registered_suffixes()
    assert {".obj", ".glb", ".usda", ".mcap", ".urdf", ".mtl", ".jpg"} <= registered
    spelled = []
    for package in ("meshtool", "simrun"):
        for path in sorted((ROOT / package).rglob("*.py")):
            if path.name == "formats.py" and path.parent.name == "meshtool":
                continue
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value.lower() in registered:
                    spelled.append(f"{path.relative_to(ROOT)}:{node.lineno}: {node.value!r}")
    assert not spelled, "suffixes spelled outside meshtool/formats.py:\n" + "\n".join(spelled)
