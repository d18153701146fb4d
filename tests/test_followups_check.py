"""obj2bin compiles what it packs in MuJoCo, refusing (exit 1, nothing written) what MuJoCo rejects (issue 16 #5).

The verdicts come from MuJoCo itself: the refused pack is also refused by ``meshtool mjcf`` (the builder
compiles the written folder), and accepted packs load from the MJCF folder with ``MjModel.from_xml_path``.
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

import mujoco
import pytest
from click.testing import CliRunner

import meshtool.plugins
from meshtool.cli.main import main, obj2bin
from meshtool.errors import MeshtoolError
from meshtool.mjcf.loadcheck import check_pack
from meshtool.mjcf.model_desc import ModelError
from meshtool.packfile import pack
from meshtool.pipeline import ConvertOptions, convert
from meshtool.repair.normalise import NormaliseOptions, prepare

ROOT = Path(__file__).resolve().parent.parent
MICRO = ROOT / "fixtures" / "followups" / "micro_cube" / "micro.obj"
TILE = ROOT / "fixtures" / "realworld" / "normal_maps" / "tile.obj"
ONE_TRIANGLE = ROOT / "fixtures" / "realworld" / "one_triangle"


def _obj2bin(*args: str) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if k != "MESHTOOL_DEBUG"}
    code = "import sys; from meshtool.cli.main import obj2bin; sys.exit(obj2bin())"
    return subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, env=env, timeout=300)


def test_a_pack_mujoco_refuses_is_exit_1_and_nothing_is_written(tmp_path: Path) -> None:
    out = tmp_path / "micro.mbin"
    run = _obj2bin(str(MICRO), "-o", str(out))
    assert run.returncode == 1, run.stderr
    errors = [line for line in run.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and "Traceback" not in run.stderr
    assert "MuJoCo refuses the converted asset: mesh volume is too small (collision hull 0)" in errors[0]
    assert "--no-check" in errors[0] and "micro.obj" in errors[0]
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_no_check_writes_it_and_meshtool_mjcf_then_refuses_it_too(tmp_path: Path) -> None:
    out = tmp_path / "micro.mbin"
    result = CliRunner().invoke(obj2bin, [str(MICRO), "-o", str(out), "--no-check", "--json"])
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout)["stats"]["mujoco_check"] == "off"
    assert out.is_file()
    mjcf = CliRunner().invoke(main, ["mjcf", str(out), "-o", str(tmp_path / "mjcf")])
    assert mjcf.exit_code == 1, mjcf.output
    assert "error: MuJoCo refuses the model: mesh volume is too small" in mjcf.output
    assert not (tmp_path / "mjcf").exists()


SOURCES = [TILE, ONE_TRIANGLE / "parts.obj", ONE_TRIANGLE / "triangle.obj"]


@pytest.mark.parametrize("source", SOURCES, ids=lambda p: p.stem)
def test_accepted_packs_are_compiled_and_load_in_mujoco(source: Path, tmp_path: Path) -> None:
    out = tmp_path / f"{source.stem}.mbin"
    result = CliRunner().invoke(obj2bin, [str(source), "-o", str(out), "--json"])
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout)["stats"]["mujoco_check"] == "compiled"
    mjcf = CliRunner().invoke(main, ["mjcf", str(out), "-o", str(tmp_path / "mjcf")])
    assert mjcf.exit_code == 0, mjcf.output
    model = mujoco.MjModel.from_xml_path(str(tmp_path / "mjcf" / source.stem / f"{source.stem}.xml"))
    assert model.nmesh >= 2


def test_a_part_under_4_vertices_is_refused_by_the_check() -> None:
    source = ONE_TRIANGLE / "triangle.obj"
    asset = prepare(source, NormaliseOptions())
    assert any(f.code == "part-padded" for f in asset.findings)
    mesh = asset.mesh  # undo the padding: the one-triangle part MuJoCo refuses
    for name in ("faces", "face_uv", "face_normal", "face_material", "face_part", "face_lines"):
        setattr(mesh, name, getattr(mesh, name)[:1])
    data = pack(asset, False, {}, [], None)
    with pytest.raises(ModelError) as caught:
        check_pack(data, "triangle.obj")
    assert "at least 4 vertices required (visual mesh 0: part 'default')" in caught.value.message
    assert check_pack(pack(prepare(source, NormaliseOptions()), False, {}, [], None), "triangle.obj") == (
        "compiled",
        [],
    )


def test_without_the_plugin_the_check_is_skipped_with_a_note(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(meshtool.plugins, "mjcf_checker", lambda: None)
    monkeypatch.setattr(meshtool.plugins, "mjcf_builder", lambda: None)
    result = convert(MICRO, tmp_path / "micro.mbin", ConvertOptions())
    assert result.stats["mujoco_check"] == "skipped"
    (note,) = [f for f in result.findings if f.code == "mujoco-check-skipped"]
    assert note.severity.value == "info" and "install simrun" in note.message
    assert (tmp_path / "micro.mbin").is_file()


def test_an_installation_with_only_the_builder_is_checked_through_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(meshtool.plugins, "mjcf_checker", lambda: None)
    with pytest.raises(MeshtoolError, match="mesh volume is too small"):
        convert(MICRO, tmp_path / "micro.mbin", ConvertOptions())
    assert not (tmp_path / "micro.mbin").exists()
    assert convert(TILE, tmp_path / "tile.mbin").stats["mujoco_check"] == "compiled"


def test_a_folder_run_reports_the_refused_asset_and_converts_the_rest(tmp_path: Path) -> None:
    src = tmp_path / "src"
    (src / "a").mkdir(parents=True)
    (src / "a" / "micro.obj").write_bytes(MICRO.read_bytes())
    (src / "parts.obj").write_bytes((ONE_TRIANGLE / "parts.obj").read_bytes())
    result = CliRunner().invoke(obj2bin, [str(src), "-o", str(tmp_path / "out")])
    assert result.exit_code == 1, result.output
    assert "1 written, 0 unchanged, 1 failed" in result.output
    assert (tmp_path / "out" / "parts.mbin").is_file() and not (tmp_path / "out" / "a" / "micro.mbin").exists()


def test_the_check_does_not_change_the_bytes(tmp_path: Path) -> None:
    checked = convert(TILE, tmp_path / "a.mbin", ConvertOptions(check=True))
    unchecked = convert(TILE, tmp_path / "b.mbin", ConvertOptions(check=False))
    assert (checked.stats["mujoco_check"], unchecked.stats["mujoco_check"]) == ("compiled", "off")
    assert (tmp_path / "a.mbin").read_bytes() == (tmp_path / "b.mbin").read_bytes()


# -- remembered checks (issue 17: a cached obj2bin does not pay for MuJoCo's import and compile) ----------------

_REPORT_MUJOCO = (
    "import sys; from meshtool.cli.main import obj2bin\n"
    "try: obj2bin()\n"
    "except SystemExit as exc: code = exc.code\n"
    "print('mujoco imported' if 'mujoco' in sys.modules else 'mujoco not imported', file=sys.stderr)\n"
    "sys.exit(code)"
)


def _obj2bin_reporting(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-c", _REPORT_MUJOCO, *args], capture_output=True, text=True, env=dict(os.environ), timeout=300
    )


def test_a_passing_check_is_remembered_and_the_next_run_does_not_import_mujoco(tmp_path: Path) -> None:
    cache = tmp_path / "cache"
    runs = [
        _obj2bin_reporting(str(TILE), "-o", str(tmp_path / f"{k}.mbin"), "--cache-dir", str(cache), "--json")
        for k in range(2)
    ]
    assert [r.returncode for r in runs] == [0, 0], runs[0].stderr
    assert [json.loads(r.stdout)["stats"]["mujoco_check"] for r in runs] == ["compiled", "cached"]
    assert "mujoco imported" in runs[0].stderr.splitlines() and "mujoco not imported" in runs[1].stderr.splitlines()
    assert (tmp_path / "0.mbin").read_bytes() == (tmp_path / "1.mbin").read_bytes()
    assert len(list((cache / "checks").rglob("*.ok"))) == 1
    # other bytes (another scale) are another question: compiled again, remembered apart
    other = _obj2bin_reporting(str(TILE), "-o", str(tmp_path / "s.mbin"), "--cache-dir", str(cache), "--scale", "2")
    assert other.returncode == 0 and "mujoco imported" in other.stderr.splitlines()
    assert len(list((cache / "checks").rglob("*.ok"))) == 2
    # --no-cache neither reads nor writes: MuJoCo compiles it, and nothing appears in the user cache either
    bare = _obj2bin_reporting(str(TILE), "-o", str(tmp_path / "n.mbin"), "--no-cache", "--json")
    assert json.loads(bare.stdout)["stats"]["mujoco_check"] == "compiled"
    assert not (Path(os.environ["XDG_CACHE_HOME"]) / "meshtool" / "checks").exists()


def test_the_default_cache_sits_beside_the_decomposition_cache(tmp_path: Path) -> None:
    run = _obj2bin_reporting(str(TILE), "-o", str(tmp_path / "t.mbin"))
    assert run.returncode == 0, run.stderr
    assert len(list((Path(os.environ["XDG_CACHE_HOME"]) / "meshtool" / "checks").rglob("*.ok"))) == 1


def test_a_refusal_is_never_remembered(tmp_path: Path) -> None:
    cache = tmp_path / "cache"
    for _ in range(2):
        run = _obj2bin(str(MICRO), "-o", str(tmp_path / "micro.mbin"), "--cache-dir", str(cache))
        assert run.returncode == 1 and "MuJoCo refuses the converted asset" in run.stderr
    assert not list(cache.rglob("*.ok"))


def test_the_remembered_check_names_the_plugin_files_and_mujoco_version() -> None:
    from meshtool.mjcf.loadcheck import plugin_identity

    identity = plugin_identity()
    assert identity is not None
    builder = ROOT / "simrun" / "export" / "mjcf_builder.py"
    # the content, not the size and modification time (issue 27: a cache keyed by what its result depends on)
    assert f"export/mjcf_builder.py {hashlib.sha256(builder.read_bytes()).hexdigest()}" in identity.splitlines()
    assert any(line.endswith(f" {mujoco.__version__}") and "mujoco" in line for line in identity.splitlines())
