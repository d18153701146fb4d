"""The files an MJCF reads (simrun.robots.mjcf_files) and the ``simrun test`` bundle of a model with ``<include>``.

Ground truth is MuJoCo's own load: which of two candidate include files it used (the compiled option tells), and
that the listed files alone, copied into a fresh folder, compile to the same model while leaving any one out
makes MuJoCo refuse it. The fixture is fixtures/mjcf/included/ (scripts/make_include_fixtures.py): includes
found both ways, a mesh and a textured material named by an included file.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest

from simrun.robots.mjcf_files import include_files, model_files
from simrun.scenetest import TestOptions, run_tests
from simrun.scenetest.bundle import materialise
from simrun.scenetest.runner import _execute, plan
from simrun.scenetest.spec import load_case

ROOT = Path(__file__).parent.parent
INCLUDED = ROOT / "fixtures" / "mjcf" / "included"
SIMRUN = [str(Path(sys.executable).parent / "simrun")]


def _write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")
    return path


def _option(step: float) -> str:
    return f'<mujoco><option timestep="{step}"/></mujoco>\n'


@pytest.mark.parametrize("absolute", [True, False], ids=["absolute", "relative"])
def test_include_rule_is_mujocos(tmp_path: Path, absolute: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    """Main folder first, then the including file's folder: the file MuJoCo used is the one listed."""
    main = _write(tmp_path / "main.xml", '<mujoco><include file="sub/a.xml"/><worldbody/></mujoco>\n')
    _write(tmp_path / "sub" / "a.xml", '<mujoco><include file="deep/b.xml"/><include file="c.xml"/></mujoco>\n')
    _write(tmp_path / "sub" / "deep" / "b.xml", '<mujoco><include file="d.xml"/></mujoco>\n')  # beside a.xml only
    _write(tmp_path / "sub" / "deep" / "d.xml", _option(0.003))  # beside b.xml only
    _write(tmp_path / "sub" / "c.xml", '<mujoco><size njmax="7"/></mujoco>\n')
    _write(tmp_path / "c.xml", '<mujoco><size njmax="9"/></mujoco>\n')  # in the main folder: this one wins
    monkeypatch.chdir(tmp_path)
    path = main if absolute else Path("main.xml")
    model = mujoco.MjModel.from_xml_path(str(path))
    listed = [p.resolve().relative_to(tmp_path).as_posix() for p in include_files(path)]
    assert listed == ["sub/a.xml", "sub/deep/b.xml", "sub/deep/d.xml", "c.xml"]
    assert model.opt.timestep == 0.003 and model.njmax == 9


def _copy_listed(path: Path, target: Path) -> list[str]:
    """Copy the files model_files lists for ``path`` under ``target`` (relative to the model's folder)."""
    names = []
    for item in model_files(path):
        rel = Path(os.path.relpath(item.path, path.parent))
        (target / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(item.path, target / rel)
        names.append(rel.as_posix())
    return names


def _same(a: mujoco.MjModel, b: mujoco.MjModel) -> None:
    for field in ("body_mass", "body_inertia", "body_ipos", "mesh_vert", "mesh_face", "tex_data", "jnt_range"):
        assert np.array_equal(getattr(a, field), getattr(b, field)), field
    assert (a.dof_damping == b.dof_damping).all() and (a.geom_matid == b.geom_matid).all()


def test_listed_files_are_exactly_what_mujoco_reads(tmp_path: Path) -> None:
    """The list alone compiles to the same model in a fresh folder; without any one of them MuJoCo refuses."""
    path = INCLUDED / "robot.xml"
    reference = mujoco.MjModel.from_xml_path(str(path))
    names = _copy_listed(path, tmp_path / "all")
    assert sorted(names) == [
        "meshes/paddle.obj",
        "parts/assets.xml",
        "parts/defaults.xml",
        "parts/link.xml",
        "robot.xml",
        "textures/grid.png",
    ]
    _same(mujoco.MjModel.from_xml_path(str(tmp_path / "all" / "robot.xml")), reference)
    for k, name in enumerate(names[1:]):
        folder = tmp_path / f"without{k}"
        shutil.copytree(tmp_path / "all", folder)
        (folder / name).unlink()
        with pytest.raises(ValueError):
            mujoco.MjModel.from_xml_path(str(folder / "robot.xml"))


def test_compiler_dirs_and_cube_faces(tmp_path: Path) -> None:
    """``assetdir``, an absolute ``meshdir`` and a cube texture's six faces, as MuJoCo reads them."""
    shutil.copytree(INCLUDED, tmp_path / "src")
    shared = tmp_path / "elsewhere"
    shared.mkdir()
    shutil.copy(INCLUDED / "meshes" / "paddle.obj", shared / "paddle.obj")
    for k in range(6):
        shutil.copy(INCLUDED / "textures" / "grid.png", tmp_path / "src" / "textures" / f"face{k}.png")
    sides = ("right", "left", "up", "down", "front", "back")
    faces = " ".join(f'file{side}="face{k}.png"' for k, side in enumerate(sides))
    path = _write(
        tmp_path / "src" / "cube.xml",
        f"""<mujoco><compiler assetdir="textures" meshdir="{shared}"/>
  <asset><mesh name="m" file="paddle.obj"/><texture name="sky" type="cube" {faces}/>
    <material name="m" texture="sky"/></asset>
  <worldbody><geom type="mesh" mesh="m" material="m"/></worldbody></mujoco>
""",
    )
    listed = {(f.kind, f.path.resolve().as_posix()) for f in model_files(path)}
    assert ("mesh", (shared / "paddle.obj").as_posix()) in listed
    assert {p for kind, p in listed if kind == "texture"} == {
        (tmp_path / "src" / "textures" / f"face{k}.png").as_posix() for k in range(6)
    }
    mujoco.MjModel.from_xml_path(str(path))  # MuJoCo reads them from there


def test_bundle_holds_every_file_mujoco_reads(tmp_path: Path) -> None:
    """The scene's bundle, unpacked in a fresh folder after the original is gone, compiles the same model."""
    reference = mujoco.MjModel.from_xml_path(str(INCLUDED / "robot.xml"))
    shutil.copytree(INCLUDED, tmp_path / "src")
    case = load_case(tmp_path / "src" / "swing.toml")
    shutil.rmtree(tmp_path / "src")
    assert {"parts/assets.xml", "parts/defaults.xml", "parts/link.xml", "meshes/paddle.obj"} <= set(case.bundle.files)
    materialise(case.bundle, tmp_path / "unpacked")
    _same(mujoco.MjModel.from_xml_path(str(tmp_path / "unpacked" / "robot.xml")), reference)


@pytest.mark.parametrize(("executor", "jobs"), [("local", 1), ("local", 2), ("dask", 2)])
def test_runs_need_no_original_folder(tmp_path: Path, executor: str, jobs: int) -> None:
    """Every executor runs the included model from its bundle alone (the scene's folder removed first)."""
    if executor == "dask":
        pytest.importorskip("distributed")
    shutil.copytree(INCLUDED, tmp_path / "src")
    options = TestOptions(seeds=[0, 1], jobs=jobs, executor=executor)
    cases = [load_case(tmp_path / "src" / "swing.toml")]
    shutil.rmtree(tmp_path / "src")
    tasks, _ = plan(cases, options)
    results = [r for r, _ in _execute(tasks, {c.bundle.digest: c.bundle for c in cases}, options)]
    assert [r.status for r in results] == ["passed", "passed"], [r.error for r in results]


def _simrun(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
    return subprocess.run([*SIMRUN, *args], capture_output=True, text=True, cwd=cwd, env=env, timeout=600)


def test_simrun_test_and_record_failures(tmp_path: Path) -> None:
    """``simrun test`` passes with -j1 and -j2; a failing run's recording re-simulates from the recorded folder."""
    work = tmp_path / "moved" / "arm"
    shutil.copytree(INCLUDED, work)
    for jobs in ("1", "2"):
        done = _simrun("test", "swing.toml", "--seeds", "0:2", "-j", jobs, cwd=work)
        assert done.returncode == 0, done.stdout + done.stderr
        assert "2 passed" in done.stdout
    failing = work / "swing.toml"
    text = failing.read_text(encoding="utf-8").replace("min = 0.45\nmax = 0.55", "min = 0.9\nmax = 1.0")
    failing.write_text(text, encoding="utf-8")
    record = tmp_path / "rec"
    done = _simrun("test", "swing.toml", "-j", "1", "--record-failures", str(record), cwd=work)
    assert done.returncode == 1 and "1 failed" in done.stdout, done.stdout + done.stderr
    shutil.rmtree(tmp_path / "moved")
    logs = sorted(record.rglob("*.simlog"))
    assert len(logs) == 1 and (logs[0].parent / "parts" / "link.xml").is_file()
    resim = _simrun("resim", str(logs[0]), cwd=tmp_path)
    assert resim.returncode == 0 and "bit-identical" in resim.stdout, resim.stdout + resim.stderr


def test_in_process_report_matches(tmp_path: Path) -> None:
    """run_tests on the fixture itself: the included model passes (the report the CLI prints)."""
    report = run_tests([INCLUDED / "swing.toml"], TestOptions(seeds=[0]))
    assert report.counts() == {"passed": 1, "failed": 0, "error": 0}
